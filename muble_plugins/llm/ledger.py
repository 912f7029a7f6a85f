"""The LLM ledger: every reply the agent got from its endpoint, stored under the request that asked for it, so a run
that is resumed or run again replays the replies instead of asking again (docs/llm_agents.md, "The ledger").

An entry is keyed by the sha256 of the request's canonical JSON (``request_key``: the whole body the endpoint
gets, so the model, the sampling settings, the seed, the response format and every message, images included) and
lives in ``<ledger>/<key[:2]>/<key>.json``. It holds the request as the logs show it (images shortened), the
reply's text, its token counts under OpenTelemetry GenAI's names, the seconds it took and the seed it was sampled
with, and a sha256 of all of that (``checksum``). An entry is written once, atomically and never over another
(``write_bytes_atomic(..., replace=False)``); one that does not parse, is of another format, fails its checksum or
holds another request's reply is refused with ``LedgerEntryDamaged`` naming its file, never used and never
overwritten.

A replayed reply is the recorded one, whatever the sampling settings: with temperature > 0 the ledger replays the
sample it recorded, it does not draw again.
"""
from __future__ import annotations

import hashlib
import json
import logging
import time
from pathlib import Path
from typing import Any

from muble.core.errors import MubleError
from muble.io.usage_fields import CACHED_INPUT_TOKENS, INPUT_TOKENS, OUTPUT_TOKENS
from muble.io.atomic import write_bytes_atomic

from muble_plugins.llm.config import LedgerMode

log = logging.getLogger(__name__)

FOLDER = "llm_ledger"  # in the run's output folder, when agent.ledger is not set
FORMAT = "muble-llm-ledger-entry"
VERSION = 1
CHECKSUM = "sha256"  # the entry's field holding the checksum of the rest of it


class LedgerError(MubleError):
    """The ledger cannot give the reply a request needs (the episode ends as ``agent_error``)."""


class LedgerEntryDamaged(LedgerError):
    """An entry's file is not an intact entry of its request: refused, kept as it is."""


class LedgerMissing(LedgerError):
    """``agent.ledger_mode=read_only`` and the ledger has no reply to a request."""


def canonical_json(value: Any) -> bytes:
    """``value`` as canonical JSON: keys sorted, no whitespace, UTF-8, no NaN (so equal requests hash equally on
    every machine)."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode()


def request_key(body: dict[str, Any]) -> str:
    """The ledger's key of a request: the sha256 of its body's canonical JSON."""
    return hashlib.sha256(canonical_json(body)).hexdigest()


def checksum(entry: dict[str, Any]) -> str:
    """The sha256 of an entry's canonical JSON without its checksum field."""
    return hashlib.sha256(canonical_json({k: v for k, v in entry.items() if k != CHECKSUM})).hexdigest()


# A reply's fields in an entry and the types they must have.
REPLY_FIELDS = {"text": (str,), INPUT_TOKENS: (int,), OUTPUT_TOKENS: (int,), CACHED_INPUT_TOKENS: (int,),
                "seconds": (int, float)}


def lacking(reply: Any) -> list[str]:
    """The fields of ``REPLY_FIELDS`` a recorded reply lacks or has of another type."""
    if not isinstance(reply, dict):
        return list(REPLY_FIELDS)
    return [name for name, kinds in REPLY_FIELDS.items() if not isinstance(reply.get(name), kinds)]


class Ledger:
    """The ledger in folder ``root``, used in ``mode`` (read_write or read_only)."""

    def __init__(self, root: str | Path, mode: LedgerMode) -> None:
        self.root = Path(root)
        self.mode = LedgerMode(mode)

    def path(self, key: str) -> Path:
        return self.root / key[:2] / f"{key}.json"

    def read(self, key: str) -> dict[str, Any] | None:
        """The recorded reply to the request ``key`` (the entry's ``reply``, with ``seed``); None when there is
        none. Raises ``LedgerEntryDamaged`` for an entry that is not intact."""
        path = self.path(key)
        if not path.exists() and not path.is_symlink():
            return None
        try:
            entry = json.loads(path.read_bytes().decode("utf-8"))
        except (OSError, UnicodeDecodeError, ValueError) as e:
            raise self._damaged(path, f"it cannot be read as JSON ({type(e).__name__}: {e}): cut short or "
                                      "overwritten?") from e
        if not isinstance(entry, dict) or entry.get("format") != FORMAT or entry.get("version") != VERSION:
            found = (entry.get("format"), entry.get("version")) if isinstance(entry, dict) else type(entry).__name__
            raise self._damaged(path, f"it is not a version {VERSION} ledger entry (found {found!r})")
        if entry.get(CHECKSUM) != checksum(entry):
            raise self._damaged(path, "its content does not match its checksum: it was changed or damaged after "
                                      "it was written")
        if entry.get("key") != key:
            raise self._damaged(path, f"it holds the reply to another request ({str(entry.get('key'))[:16]}…)")
        wrong = lacking(entry.get("reply"))
        if wrong:
            raise self._damaged(path, f"its reply lacks {', '.join(wrong)}")
        return {**entry["reply"], "seed": entry.get("seed")}

    def write(self, key: str, body: dict[str, Any], logged_body: dict[str, Any], reply: dict[str, Any]) -> Path:
        """Record ``reply`` (``REPLY_FIELDS`` and ``finish_reason``) to the request ``body`` (``logged_body``: the
        body as the logs show it); an entry another worker recorded first is kept as it is. Returns its path."""
        path = self.path(key)
        entry = {"format": FORMAT, "version": VERSION, "key": key, "request": logged_body, "reply": reply,
                 "seed": body.get("seed"), "sampled": float(body.get("temperature") or 0.0) > 0,
                 "recorded": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        entry[CHECKSUM] = checksum(entry)
        try:
            write_bytes_atomic(path, json.dumps(entry, indent=1, sort_keys=True, ensure_ascii=False).encode(),
                               replace=False)
        except FileExistsError:
            log.debug("%s was recorded by another worker first; kept", path)
        return path

    def missing(self, key: str, episode: str) -> LedgerMissing:
        return LedgerMissing(
            f"agent.ledger_mode=read_only and the LLM ledger {self.root} has no reply to request {key[:16]}… of "
            f"{episode}; ask the endpoint for it with agent.ledger_mode=read_write, or set agent.ledger to the "
            "ledger of the run that recorded it")

    @staticmethod
    def _damaged(path: Path, why: str) -> LedgerEntryDamaged:
        log.error("LLM ledger entry %s refused: %s", path, why)
        return LedgerEntryDamaged(
            f"LLM ledger entry {path} is damaged: {why}. It was not used and is left as it is: delete it to ask the "
            "endpoint again (agent.ledger_mode=read_write), or restore it from the run that recorded it")
