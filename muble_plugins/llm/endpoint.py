"""One OpenAI-compatible chat-completions endpoint, asked with bounded time and bounded retries, every exchange
recorded.

``Endpoint.ask`` sends one request with the official ``openai`` client (its own retries off, so every retry is
decided and counted here). HTTP 429 and 5xx replies and dropped connections are transient: the request is sent
again after the wait the server's Retry-After asks for (capped at ``max_backoff``), or else 1, 2, 4 … s, at most
``http_retries`` times; then ``EndpointError``. A request that exceeds ``timeout`` raises ``EndpointTimeout`` at
once: a server that does not answer in time will not answer the next one either, and the episode must end. Other
HTTP errors (400, 401, 404) raise ``EndpointError`` with the server's message. Each of these ends the episode as
``agent_error`` (the action loop turns an agent's exception into that outcome), never the evaluation.

Every request body (images shortened to their size; the key is in a header and never written) and every reply or
error goes as one JSON line into the episode's log file, with its latency and token counts.

With a ledger (``muble_plugins.llm.ledger``) a request it has a reply to is not sent: the recorded reply is
replayed, with the tokens and seconds it cost when it was recorded, and counted as ``replayed``; a reply fetched
from the endpoint is recorded. Token counts carry OpenTelemetry GenAI's names (``muble.io.usage_fields``).
"""
from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import dataclass, field
from email.utils import parsedate_to_datetime
from pathlib import Path
from typing import Any

from muble.io.usage_fields import CACHED_INPUT_TOKENS, COST, INPUT_TOKENS, LATENCY, OUTPUT_TOKENS, PriceTable

from muble_plugins.llm.config import LedgerMode
from muble_plugins.llm.ledger import Ledger, request_key

log = logging.getLogger(__name__)

# The HTTP client logs a line per request at INFO; the episode's log has each request already, and eval's progress
# log would drown in them.
QUIET_LOGGERS = ("httpx", "httpx2", "openai")
NO_KEY = "no-key"  # sent when the key's variable is unset: local servers want none, the client wants something
FIRST_BACKOFF = 1.0  # s; doubled after each transient failure without Retry-After


class EndpointError(RuntimeError):
    """The endpoint could not give a reply (after the retries transient failures get)."""


class EndpointTimeout(EndpointError):
    """A request got no complete reply within the configured timeout."""


@dataclass
class Reply:
    """The text of one completion and what it cost: tokens (input ones include the cached ones) and the seconds
    waited for it, every try and back-off included (for a replayed reply, as recorded)."""

    text: str
    tokens_in: int
    tokens_out: int
    seconds: float
    tokens_cached: int = 0
    finish_reason: str | None = None
    replayed: bool = False  # read from the ledger: no request was sent

    def recorded(self) -> dict[str, Any]:
        """The reply as a ledger entry keeps it."""
        return {"text": self.text, "finish_reason": self.finish_reason, INPUT_TOKENS: self.tokens_in,
                OUTPUT_TOKENS: self.tokens_out, CACHED_INPUT_TOKENS: self.tokens_cached, "seconds": self.seconds}

    @classmethod
    def replay(cls, recorded: dict[str, Any]) -> "Reply":
        """The reply a ledger entry recorded (``recorded``), replayed."""
        return cls(recorded["text"], recorded[INPUT_TOKENS], recorded[OUTPUT_TOKENS], float(recorded["seconds"]),
                   recorded[CACHED_INPUT_TOKENS], recorded.get("finish_reason"), replayed=True)


@dataclass
class EpisodeStats:
    """Per-episode counters of the agent's exchanges with the endpoint (numbers only, summed in reports), and the
    seconds each reply took (the record's ``agent_samples``)."""

    requests: int = 0  # HTTP requests sent in this run, retries included (a replayed reply sends none)
    replayed: int = 0  # replies replayed from the ledger
    replies: int = 0  # completions used: received or replayed
    parse_failures: int = 0  # replies that were not one valid decision (each is re-asked or ends the episode)
    reasks: int = 0  # re-asks sent after such replies
    http_retries: int = 0  # requests sent again after 429, 5xx or a dropped connection
    timeouts: int = 0
    tokens_in: int = 0  # reported as INPUT_TOKENS, the cached ones included
    tokens_out: int = 0  # OUTPUT_TOKENS
    tokens_cached: int = 0  # CACHED_INPUT_TOKENS
    latency_s: float = 0.0  # seconds spent waiting for the endpoint, backoff and failed requests included
    decisions: int = 0
    invalid_end: int = 0  # 1 when the episode ended on a reply that could not be used after every re-ask
    latencies: list[float] = field(default_factory=list)  # seconds per reply, as ``Reply.seconds``

    def add(self, reply: Reply) -> None:
        """Count a reply used, received or replayed."""
        self.replies += 1
        self.replayed += reply.replayed
        self.tokens_in += reply.tokens_in
        self.tokens_out += reply.tokens_out
        self.tokens_cached += reply.tokens_cached
        self.latency_s += reply.seconds
        self.latencies.append(reply.seconds)

    def as_dict(self, prices: PriceTable) -> dict[str, float]:
        """The counters under the names reports read, with the tokens' cost at ``prices``."""
        counters = {k: v for k, v in self.__dict__.items()
                    if k not in ("tokens_in", "tokens_out", "tokens_cached", "latencies")}
        return {**counters, INPUT_TOKENS: self.tokens_in, OUTPUT_TOKENS: self.tokens_out,
                CACHED_INPUT_TOKENS: self.tokens_cached,
                COST: prices.cost_usd(self.tokens_in, self.tokens_out, self.tokens_cached)}

    def samples(self) -> dict[str, list[float]]:
        return {LATENCY: list(self.latencies)}


def retry_after(headers: Any) -> float | None:
    """Seconds a Retry-After (or retry-after-ms) header asks to wait, or None."""
    if headers is None:
        return None
    millis = headers.get("retry-after-ms")
    if millis:
        try:
            return float(millis) / 1000.0
        except ValueError:
            pass
    value = headers.get("retry-after")
    if not value:
        return None
    try:
        return float(value)
    except ValueError:
        try:
            return max(0.0, parsedate_to_datetime(value).timestamp() - time.time())
        except (TypeError, ValueError):
            return None


def response_format(schema: dict[str, Any], form: str) -> dict[str, Any]:
    """The ``response_format`` that constrains a reply to ``schema``, in the form the server accepts."""
    if form == "json_object":
        return {"type": "json_object", "schema": schema}
    return {"type": "json_schema", "json_schema": {"name": "decision", "schema": schema, "strict": False}}


def loggable(body: dict[str, Any]) -> dict[str, Any]:
    """The request body as logged: data URLs of images replaced by their length."""
    def shorten(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: shorten(v) for k, v in value.items()}
        if isinstance(value, list):
            return [shorten(v) for v in value]
        if isinstance(value, str) and value.startswith("data:image/"):
            return f"{value[:value.find(',') + 1]}<{len(value)} characters>"
        return value
    return shorten(body)


@dataclass
class ExchangeLog:
    """The JSONL file of one episode's requests and replies (no file when ``path`` is None)."""

    path: Path | None = None
    _file: Any = field(default=None, repr=False)

    def open(self, path: Path | None) -> None:
        self.close()
        self.path = path
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._file = path.open("w", encoding="utf-8")

    def write(self, kind: str, **entry: Any) -> None:
        if self._file is None:
            return
        self._file.write(json.dumps({"time": round(time.time(), 3), "kind": kind, **entry}, default=str) + "\n")
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
        self._file = None


class Endpoint:
    """The chat-completions endpoint of one agent (one client per worker process, made on first use)."""

    def __init__(self, base_url: str, model: str, api_key_env: str, temperature: float, max_tokens: int,
                 timeout: float, http_retries: int, max_backoff: float, schema_form: str,
                 seed: int | None = None) -> None:
        self.base_url, self.model, self.api_key_env = base_url, model, api_key_env
        self.temperature, self.max_tokens, self.timeout = temperature, max_tokens, timeout
        self.http_retries, self.max_backoff = http_retries, max_backoff
        self.schema_form, self.seed = schema_form, seed
        self.ledger: Ledger | None = None  # the agent sets it per episode
        self._client: Any = None

    def client(self) -> Any:
        if self._client is None:
            try:
                import openai
            except ImportError as e:
                from muble import ConfigError

                raise ConfigError('agent=llm needs the openai client: pip install "muble[llm]"') from e
            for name in QUIET_LOGGERS:
                logging.getLogger(name).setLevel(max(logging.WARNING, logging.getLogger(name).level))
            key = os.environ.get(self.api_key_env) if self.api_key_env else None
            self._client = openai.OpenAI(base_url=self.base_url, api_key=key or NO_KEY, timeout=self.timeout,
                                         max_retries=0)
        return self._client

    def body(self, messages: list[dict[str, Any]], schema: dict[str, Any] | None) -> dict[str, Any]:
        """The request body asking for a completion of ``messages`` (constrained to ``schema`` when given)."""
        body: dict[str, Any] = {"model": self.model, "messages": messages, "temperature": self.temperature,
                                "max_tokens": self.max_tokens}
        if self.seed is not None:
            body["seed"] = self.seed
        if schema is not None:
            body["response_format"] = response_format(schema, self.schema_form)
        return body

    def ask(self, messages: list[dict[str, Any]], schema: dict[str, Any] | None, stats: EpisodeStats,
            record: ExchangeLog, episode: str = "this episode") -> Reply:
        """One completion of ``messages`` (constrained to ``schema`` when given): replayed from the ledger when it
        has it, else asked of the endpoint (and recorded in a read-write ledger). Raises ``EndpointTimeout`` or
        ``EndpointError`` when none can be had, ``LedgerEntryDamaged`` for a damaged entry of the request and, in
        a read-only ledger, ``LedgerMissing`` naming ``episode`` for a request it lacks."""
        body = self.body(messages, schema)
        if self.ledger is None:
            return self.send(body, stats, record)
        key = request_key(body)
        recorded = self.ledger.read(key)
        if recorded is not None:
            record.write("request", attempt=0, base_url=self.base_url, body=loggable(body), ledger_key=key,
                         replayed=True)
            return self._used(Reply.replay(recorded), stats, record)
        if self.ledger.mode is LedgerMode.read_only:
            record.write("error", error="not in the LLM ledger (agent.ledger_mode=read_only)", ledger_key=key)
            raise self.ledger.missing(key, episode)
        reply = self.send(body, stats, record)
        self.ledger.write(key, body, loggable(body), reply.recorded())
        return reply

    def send(self, body: dict[str, Any], stats: EpisodeStats, record: ExchangeLog) -> Reply:
        """The endpoint's reply to ``body``, with the retries transient failures get."""
        import openai

        backoff = FIRST_BACKOFF
        start = time.monotonic()
        attempt = -1
        try:
            while True:
                attempt += 1
                stats.requests += 1
                record.write("request", attempt=attempt, base_url=self.base_url, body=loggable(body))
                sent = time.monotonic()
                try:
                    completion = self.client().chat.completions.create(**body)
                except openai.APITimeoutError as e:
                    stats.timeouts += 1
                    record.write("error", attempt=attempt, error="timeout", seconds=time.monotonic() - sent)
                    raise EndpointTimeout(f"no reply from {self.base_url} within {self.timeout:g} s "
                                          "(agent.timeout)") from e
                except (openai.APIConnectionError, openai.APIStatusError) as e:
                    status = getattr(e, "status_code", None)
                    transient = status is None or status == 429 or status >= 500
                    wait = retry_after(getattr(getattr(e, "response", None), "headers", None))
                    record.write("error", attempt=attempt, status=status, error=f"{type(e).__name__}: {e}"[:500],
                                 retry_after=wait, seconds=time.monotonic() - sent)
                    what = f"HTTP {status}" if status is not None else "connection failed"
                    if not transient:
                        hint = ("; if the server does not take this response_format, set agent.schema_form "
                                "(json_schema or json_object) or agent.schema=false") \
                            if "response_format" in body else ""
                        raise EndpointError(f"{self.base_url}: {what}: {e}{hint}") from e
                    if attempt == self.http_retries:
                        raise EndpointError(f"{self.base_url}: {what} after {attempt + 1} tries "
                                            f"(agent.http_retries={self.http_retries}): {e}") from e
                    delay = min(self.max_backoff, backoff if wait is None else wait)
                    log.info("%s: %s; trying again in %.1f s", self.base_url, what, delay)
                    stats.http_retries += 1
                    time.sleep(delay)
                    backoff *= 2
                    continue
                return self._used(received(completion, time.monotonic() - start), stats, record)
        except BaseException:
            stats.latency_s += time.monotonic() - start  # the wait that gave no reply counts too
            raise

    @staticmethod
    def _used(reply: Reply, stats: EpisodeStats, record: ExchangeLog) -> Reply:
        stats.add(reply)
        record.write("reply", text=reply.text, finish_reason=reply.finish_reason,
                     **{INPUT_TOKENS: reply.tokens_in, OUTPUT_TOKENS: reply.tokens_out,
                        CACHED_INPUT_TOKENS: reply.tokens_cached}, seconds=round(reply.seconds, 3),
                     replayed=reply.replayed)
        return reply


def received(completion: Any, seconds: float) -> Reply:
    """The reply in a chat completion: its text, finish reason and token counts (cached input tokens where the
    server reports them, as OpenAI's ``prompt_tokens_details.cached_tokens``)."""
    choice = completion.choices[0] if getattr(completion, "choices", None) else None
    text = (choice.message.content if choice is not None and choice.message is not None else None) or ""
    usage = getattr(completion, "usage", None)
    details = getattr(usage, "prompt_tokens_details", None)
    return Reply(text, int(getattr(usage, "prompt_tokens", 0) or 0), int(getattr(usage, "completion_tokens", 0) or 0),
                 seconds, int(getattr(details, "cached_tokens", 0) or 0), getattr(choice, "finish_reason", None))
