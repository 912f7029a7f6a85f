"""A scripted OpenAI-compatible chat-completions server on 127.0.0.1, for the ``llm`` agent's tests.

A real HTTP server (``http.server`` in a thread): ``POST /v1/chat/completions`` takes the next step of its script
and plays it: a completion with a given text, an HTTP error status with headers, a hang (no reply for a while) or
a dropped connection (closed without a byte). When the script is empty it plays ``fallback``. Every request body
is kept in ``requests`` (and its Authorization header in ``authorizations``) so tests can read what the agent
sent.
"""
from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

HANG_LIMIT = 30.0  # s: a hanging reply gives up by itself, so the server always stops


@dataclass
class Reply:
    """A completion whose message content is ``text``."""

    text: str


@dataclass
class Status:
    """An HTTP error reply."""

    code: int
    headers: dict[str, str] = field(default_factory=dict)
    message: str = "scripted failure"


@dataclass
class Hang:
    """No reply for ``seconds`` (then the connection is closed)."""

    seconds: float = HANG_LIMIT


@dataclass
class Drop:
    """The connection closed before any reply."""


Step = Reply | Status | Hang | Drop


def completion(text: str, body: dict[str, Any]) -> dict[str, Any]:
    """A chat.completion object with ``text``; token counts estimated from the request's size (4 characters a
    token), as a server would report them."""
    prompt_tokens = max(1, len(json.dumps(body.get("messages", []))) // 4)
    completion_tokens = max(1, len(text) // 4)
    return {"id": "chatcmpl-scripted", "object": "chat.completion", "created": int(time.time()),
            "model": body.get("model", "scripted"),
            "choices": [{"index": 0, "message": {"role": "assistant", "content": text}, "finish_reason": "stop"}],
            "usage": {"prompt_tokens": prompt_tokens, "completion_tokens": completion_tokens,
                      "total_tokens": prompt_tokens + completion_tokens}}


class ScriptedChatServer:
    """The server; use as a context manager (``with ScriptedChatServer() as server: server.base_url``)."""

    def __init__(self) -> None:
        self.script: list[Step] = []
        self.fallback: Step = Reply('{"stop": true}')
        self.requests: list[dict[str, Any]] = []
        self.authorizations: list[str | None] = []  # the Authorization header of each request
        self.lock = threading.Lock()
        self.stopping = threading.Event()
        outer = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.0"

            def log_message(self, *args: Any) -> None:  # quiet: the tests read the requests instead
                pass

            def do_POST(self) -> None:  # noqa: N802 - http.server's name
                length = int(self.headers.get("Content-Length", 0))
                body = json.loads(self.rfile.read(length) or b"{}")
                if not self.path.rstrip("/").endswith("/chat/completions"):
                    self._send(404, {"error": {"message": f"no route {self.path}"}})
                    return
                step = outer.next_step(body, self.headers.get("Authorization"))
                if isinstance(step, Reply):
                    self._send(200, completion(step.text, body))
                elif isinstance(step, Status):
                    self._send(step.code, {"error": {"message": step.message, "type": "scripted"}}, step.headers)
                elif isinstance(step, Hang):
                    outer.stopping.wait(min(step.seconds, HANG_LIMIT))
                    self.close_connection = True
                else:  # Drop: close the socket without a status line
                    self.close_connection = True
                    self.connection.close()

            def _send(self, code: int, payload: dict[str, Any], headers: dict[str, str] | None = None) -> None:
                data = json.dumps(payload).encode()
                self.send_response(code)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                for key, value in (headers or {}).items():
                    self.send_header(key, value)
                self.end_headers()
                self.wfile.write(data)

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.thread = threading.Thread(target=self.httpd.serve_forever, name="scripted-chat-server", daemon=True)

    @property
    def base_url(self) -> str:
        return f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"

    def next_step(self, body: dict[str, Any], authorization: str | None) -> Step:
        with self.lock:
            self.requests.append(body)
            self.authorizations.append(authorization)
            return self.script.pop(0) if self.script else self.fallback

    def play(self, *steps: Step, fallback: Step | None = None) -> None:
        """Replace the script (and the fallback) and forget earlier requests."""
        with self.lock:
            self.script = list(steps)
            self.requests = []
            self.authorizations = []
            if fallback is not None:
                self.fallback = fallback

    def __enter__(self) -> "ScriptedChatServer":
        self.thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stopping.set()
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join(timeout=5)
