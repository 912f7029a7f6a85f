"""The remote agent wire protocol, version 1 (see docs/remote.md): JSON headers, images as binary frames, over ZeroMQ.

A request is one ZeroMQ message of exactly one frame: a UTF-8 JSON object with ``protocol`` ("muble.remote/1"),
``type`` and the type's fields. A reply is a JSON header frame followed by zero or more binary frames (images)
that the header refers to by position. Every malformed, oversized or out-of-order request gets an ``error``
reply with a ``code`` from ``ERROR_CODES`` and a message saying what to change.

Both directions are total: ``decode_request`` turns any bytes into a request or a ``ProtocolError``, and
``encode`` turns any header into bytes (at worst the fixed ``FALLBACK_REPLY``), so no request can make the
server fail while answering it.
"""
from __future__ import annotations

import json
import logging
import math
import re
from typing import Any

log = logging.getLogger(__name__)

PROTOCOL = "muble.remote/1"
PROTOCOL_FAMILY = "muble.remote/"
REQUEST_TYPES = ("hello", "reset", "observe", "act", "close")
IMAGE_FORMATS = ("png", "raw", "none")
DEFAULT_PORT = 5555
DEFAULT_HOST = "127.0.0.1"
MAX_REQUEST_BYTES = 4 << 20  # a request above this gets a too_large error reply
HARD_LIMIT_BYTES = 64 << 20  # above this ZeroMQ drops the peer's connection before the server reads anything
MAX_ID_CHARS = 64
# Bounds on a request's JSON document, checked right after parsing and before anything is built from it. A
# SHOP-VRB2 scene nests about 7 levels deep and a 64-object scene holds about 5,000 values, so these leave room
# for any real request while keeping the walk over one request well under a tenth of a second.
MAX_DEPTH = 32
MAX_VALUES = 250_000
# Integers beyond 64 bits are no id, index or count MuBlE uses; refusing them keeps float conversion of any
# number in a request from overflowing later.
MAX_INT = 2**63 - 1

ERROR_CODES = {
    "bad_request": "not a JSON object of the protocol's shape (the message says which field)",
    "unsupported_protocol": "the protocol field is missing or names a version this server does not speak",
    "too_large": "the request, or the scene in it, exceeds the server's bounds (bytes, nesting, values, objects)",
    "unknown_session": "no open session has this token (never opened, closed, or expired)",
    "out_of_order": "the session cannot take this request now (e.g. act after the episode ended)",
    "busy": "the server holds its maximum of open sessions, or the session is still working on its previous "
            "request; retry later",
    "not_found": "the episode named does not exist here: no dataset on this server, no such split, index or "
                 "template",
    "episode_error": "the episode could not start or run (bad scene or instruction data, broken physics, time "
                     "limit)",
    "internal": "an unexpected server error; the server keeps serving",
}

# The reply when even an error reply cannot be encoded: fixed bytes, so that one is always there to send.
FALLBACK_REPLY = (b'{"protocol":"muble.remote/1","type":"error","id":null,"error":{"code":"internal",'
                  b'"message":"the reply could not be encoded; the server keeps serving"}}')

# Lone UTF-16 surrogates: JSON's "\ud800" escapes decode to them, and no UTF-8 text can carry them back out.
_SURROGATE = re.compile("[\ud800-\udfff]")


class ProtocolError(Exception):
    """A request the server answers with an error reply (never raised out of the server loop)."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code = code
        self.message = message
        self.rid: Any = None  # the request's id, where it could be read and may be echoed


def encode(header: dict[str, Any]) -> bytes:
    """The header as ASCII JSON bytes; never raises.

    ``ensure_ascii`` writes every character, a lone surrogate included, as an escape, so no string can fail to
    encode. A header that still cannot be written (a non-finite number, an object JSON has no form for) becomes
    an ``internal`` error reply carrying the same ``id``, and failing that ``FALLBACK_REPLY``.
    """
    try:
        return _dumps(header)
    except Exception:  # noqa: BLE001 - whatever the header holds, a reply must go out
        log.exception("a reply could not be encoded; sending an internal error instead")
    rid = echoed_id(header) if isinstance(header, dict) else None
    try:
        return _dumps(error_header("internal", "the reply could not be encoded (logged on the server); the server "
                                   "keeps serving", rid))
    except Exception:  # noqa: BLE001 - see above
        return FALLBACK_REPLY


def _dumps(value: Any) -> bytes:
    return json.dumps(value, ensure_ascii=True, separators=(",", ":"), allow_nan=False).encode("ascii")


class _NonFinite(ValueError):
    pass


def _reject_constant(name: str) -> Any:
    raise _NonFinite(name)


def decode_request(frames: list[bytes], max_bytes: int = MAX_REQUEST_BYTES) -> dict[str, Any]:
    """The request's header; raises ``ProtocolError`` for anything but one JSON object frame of the protocol,
    within the bounds of ``check_document``."""
    size = sum(len(f) for f in frames)
    if size > max_bytes:
        raise ProtocolError("too_large", f"the request has {size} bytes; this server accepts at most {max_bytes}")
    if len(frames) != 1:
        raise ProtocolError("bad_request", f"a request is one frame (a JSON object), got {len(frames)} frames")
    try:
        header = json.loads(frames[0].decode("utf-8"), parse_constant=_reject_constant)
    except UnicodeDecodeError as e:
        raise ProtocolError("bad_request", f"the request is not UTF-8 text: {e}") from None
    except _NonFinite as e:
        raise ProtocolError("bad_request", f"the request holds {e}, which is not a JSON number; send finite "
                            "numbers only") from None
    except json.JSONDecodeError as e:
        raise ProtocolError("bad_request", f"the request is not JSON: {e}"[:300]) from None
    except RecursionError:
        raise ProtocolError("too_large", f"the request nests values too deeply; at most {MAX_DEPTH} levels are "
                            "accepted") from None
    except ValueError:  # an integer literal of more digits than Python converts (4,300)
        raise ProtocolError("bad_request", f"the request holds an integer of thousands of digits; integers must "
                            f"lie within +-{MAX_INT}") from None
    if not isinstance(header, dict):
        raise ProtocolError("bad_request", f"a request is a JSON object, got {type(header).__name__}")
    try:
        _check_header(header)
    except ProtocolError as e:
        e.rid = echoed_id(header)
        raise
    return header


def echoed_id(header: dict[str, Any]) -> Any:
    """The request's ``id`` when it may be echoed in the reply (a short string without lone surrogates, or an
    integer of 64 bits), else None."""
    rid = header.get("id")
    if isinstance(rid, str) and len(rid) <= MAX_ID_CHARS and not _SURROGATE.search(rid):
        return rid
    if isinstance(rid, int) and not isinstance(rid, bool) and abs(rid) <= MAX_INT:
        return rid
    return None


def _check_header(header: dict[str, Any]) -> None:
    check_document(header)
    protocol = header.get("protocol")
    if not isinstance(protocol, str) or not protocol.startswith(PROTOCOL_FAMILY):
        raise ProtocolError("unsupported_protocol", f"set \"protocol\": \"{PROTOCOL}\" in every request")
    if protocol != PROTOCOL:
        raise ProtocolError("unsupported_protocol", f"this server speaks {PROTOCOL}, not {protocol[:40]!r}")
    kind = header.get("type")
    if kind not in REQUEST_TYPES:
        raise ProtocolError("bad_request", f"unknown request type {str(kind)[:40]!r}; valid: "
                            f"{', '.join(REQUEST_TYPES)}")
    rid = header.get("id")
    if rid is not None and echoed_id(header) is None:
        raise ProtocolError("bad_request", f"'id' must be a string or integer of at most {MAX_ID_CHARS} characters")


def check_document(document: Any) -> None:
    """Raise ``ProtocolError`` if a parsed request nests deeper than ``MAX_DEPTH``, holds more than ``MAX_VALUES``
    values, an integer beyond 64 bits, a non-finite number or a string (or key) with a lone surrogate.

    The walk uses its own stack, so a document at the limit of Python's parser cannot exhaust the interpreter's.
    """
    stack: list[tuple[Any, int]] = [(document, 1)]
    count = 0
    while stack:
        value, depth = stack.pop()
        count += 1
        if count > MAX_VALUES:
            raise ProtocolError("too_large", f"the request holds more than {MAX_VALUES} JSON values; send smaller "
                                "scenes")
        if isinstance(value, dict):
            if depth > MAX_DEPTH:
                raise ProtocolError("too_large", f"the request nests more than {MAX_DEPTH} levels deep")
            for key, item in value.items():
                _check_string(key)
                stack.append((item, depth + 1))
        elif isinstance(value, list):
            if depth > MAX_DEPTH:
                raise ProtocolError("too_large", f"the request nests more than {MAX_DEPTH} levels deep")
            stack.extend((item, depth + 1) for item in value)
        elif isinstance(value, str):
            _check_string(value)
        elif isinstance(value, bool) or value is None:
            continue
        elif isinstance(value, int):
            if not -MAX_INT <= value <= MAX_INT:
                raise ProtocolError("bad_request", f"an integer of {len(str(abs(value)))} digits is beyond what the "
                                    f"protocol carries; integers must lie within +-{MAX_INT}")
        elif isinstance(value, float) and not math.isfinite(value):
            raise ProtocolError("bad_request", "a number in the request is too large to be finite (e.g. 1e400); "
                                "send finite numbers only")


def _check_string(text: str) -> None:
    match = _SURROGATE.search(text)
    if match:
        raise ProtocolError("bad_request", f"a string in the request holds the lone UTF-16 surrogate "
                            f"\\u{ord(match.group()):04x} at character {match.start()}, which is no Unicode "
                            "character; escape text as UTF-16 pairs or send it as UTF-8")


def error_header(code: str, message: str, rid: Any = None) -> dict[str, Any]:
    return {"protocol": PROTOCOL, "type": "error", "id": rid, "error": {"code": code, "message": message}}
