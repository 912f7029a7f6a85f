"""The remote agent protocol, version 1 (see docs/remote.md): JSON headers, images as binary frames, over ZeroMQ.

A request is one ZeroMQ message of exactly one frame: a UTF-8 JSON object with ``protocol`` ("muble.remote/1"),
``type`` and the type's fields. A reply is a JSON header frame followed by zero or more binary frames (images)
that the header refers to by position. Every malformed, oversized or out-of-order request gets an ``error``
reply with a ``code`` from ``ERROR_CODES`` and a message saying what to change.
"""
from __future__ import annotations

import json
from typing import Any

PROTOCOL = "muble.remote/1"
PROTOCOL_FAMILY = "muble.remote/"
REQUEST_TYPES = ("hello", "reset", "observe", "act", "close")
IMAGE_FORMATS = ("png", "raw", "none")
DEFAULT_PORT = 5555
DEFAULT_HOST = "127.0.0.1"
MAX_REQUEST_BYTES = 4 << 20  # a request above this gets a too_large error reply
HARD_LIMIT_BYTES = 64 << 20  # above this ZeroMQ drops the peer's connection before the server reads anything
MAX_ID_CHARS = 64

ERROR_CODES = {
    "bad_request": "not a JSON object of the protocol's shape (the message says which field)",
    "unsupported_protocol": "the protocol field is missing or names a version this server does not speak",
    "too_large": f"the request is larger than the server accepts ({MAX_REQUEST_BYTES} bytes by default)",
    "unknown_session": "no open session has this token (never opened, closed, or expired)",
    "out_of_order": "the session cannot take this request now (e.g. act after the episode ended)",
    "busy": "the server holds its maximum of open sessions; close one or retry later",
    "episode_error": "the episode could not start or run (bad scene or instruction data, broken physics)",
    "internal": "an unexpected server error; the server keeps serving",
}


class ProtocolError(Exception):
    """A request the server answers with an error reply (never raised out of the server loop)."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code = code
        self.message = message


def encode(header: dict[str, Any]) -> bytes:
    return json.dumps(header, ensure_ascii=False, separators=(",", ":"), allow_nan=False).encode("utf-8")


def decode_request(frames: list[bytes], max_bytes: int = MAX_REQUEST_BYTES) -> dict[str, Any]:
    """The request's header; raises ``ProtocolError`` for anything but one JSON object frame of the protocol."""
    size = sum(len(f) for f in frames)
    if size > max_bytes:
        raise ProtocolError("too_large", f"the request has {size} bytes; this server accepts at most {max_bytes}")
    if len(frames) != 1:
        raise ProtocolError("bad_request", f"a request is one frame (a JSON object), got {len(frames)} frames")
    try:
        header = json.loads(frames[0].decode("utf-8"))
    except UnicodeDecodeError as e:
        raise ProtocolError("bad_request", f"the request is not UTF-8 text: {e}") from None
    except (json.JSONDecodeError, RecursionError) as e:
        raise ProtocolError("bad_request", f"the request is not JSON: {e}"[:300]) from None
    if not isinstance(header, dict):
        raise ProtocolError("bad_request", f"a request is a JSON object, got {type(header).__name__}")
    protocol = header.get("protocol")
    if not isinstance(protocol, str) or not protocol.startswith(PROTOCOL_FAMILY):
        raise ProtocolError("unsupported_protocol", f"set \"protocol\": \"{PROTOCOL}\" in every request")
    if protocol != PROTOCOL:
        raise ProtocolError("unsupported_protocol", f"this server speaks {PROTOCOL}, not {protocol[:40]!r}")
    kind = header.get("type")
    if kind not in REQUEST_TYPES:
        raise ProtocolError("bad_request", f"unknown request type {str(kind)[:40]!r}; valid: {', '.join(REQUEST_TYPES)}")
    rid = header.get("id")
    if rid is not None and not (isinstance(rid, (int, str)) and not isinstance(rid, bool)
                                and len(str(rid)) <= MAX_ID_CHARS):
        raise ProtocolError("bad_request", f"'id' must be a string or integer of at most {MAX_ID_CHARS} characters")
    return header


def error_header(code: str, message: str, rid: Any = None) -> dict[str, Any]:
    return {"protocol": PROTOCOL, "type": "error", "id": rid, "error": {"code": code, "message": message}}
