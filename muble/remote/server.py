"""``muble serve``: SHOP-VRB2 episodes driven by an agent in another process, over the protocol of
``muble.remote.protocol`` on a ZeroMQ ROUTER socket.

Each ``reset`` opens a session (a token) bound to one episode, run by ``SteppedEpisode`` through the same action
loop as ``muble run``/``muble eval``. The server answers one request at a time (an ``act`` returns when the
primitive has been executed); run one server per parallel worker. Whatever a request holds, the server replies
— with an error for a malformed, oversized or out-of-order one — and keeps serving.
"""
from __future__ import annotations

import io
import ipaddress
import logging
import secrets
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from muble.core.errors import MubleError
from muble.core.instructions_io import instruction_to_dict
from muble.core.params import specs
from muble.episode.plain import MalformedDecision, decision_from_plain, observation_to_plain, plain
from muble.episode.sources import EpisodeFactory, EpisodeSpec, agent_instruction
from muble.episode.stepped import Step, SteppedEpisode
from muble.remote.protocol import (DEFAULT_HOST, DEFAULT_PORT, HARD_LIMIT_BYTES, IMAGE_FORMATS, MAX_REQUEST_BYTES,
                                   PROTOCOL, ProtocolError, decode_request, encode, error_header)

log = logging.getLogger(__name__)


@dataclass
class Session:
    token: str
    episode: SteppedEpisode
    spec: EpisodeSpec
    images: str
    last_used: float = field(default_factory=time.monotonic)


def is_loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


def png(rgb: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG", compress_level=1)
    return buf.getvalue()


class EpisodeServer:
    """Serves episodes of ``factory`` on ``tcp://host:port`` (port 0: any free port, see ``endpoint``)."""

    def __init__(self, factory: EpisodeFactory, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT,
                 max_sessions: int = 2, session_timeout: float = 900.0, max_request_bytes: int = MAX_REQUEST_BYTES):
        import zmq

        self.factory = factory
        self.max_sessions = max_sessions
        self.session_timeout = session_timeout
        self.max_request_bytes = max_request_bytes
        self.sessions: dict[str, Session] = {}
        self.context = zmq.Context()
        self.socket = self.context.socket(zmq.ROUTER)
        self.socket.setsockopt(zmq.LINGER, 0)
        # A message over the hard limit drops its sender's connection inside ZeroMQ, before it is buffered.
        self.socket.setsockopt(zmq.MAXMSGSIZE, max(HARD_LIMIT_BYTES, max_request_bytes + 1024))
        self.socket.setsockopt(zmq.ROUTER_HANDOVER, 1)
        if not is_loopback(host):
            log.warning("listening on %s: agents from other machines can connect (the protocol has no "
                        "authentication; use a trusted network)", host)
        address = f"tcp://{host}:{port}" if port else f"tcp://{host}:*"
        self.socket.bind(address)
        self.endpoint = self.socket.getsockopt_string(zmq.LAST_ENDPOINT)
        self.handlers = {"hello": self._hello, "reset": self._reset, "observe": self._observe, "act": self._act,
                         "close": self._close}

    # ------------------------------------------------------------------------------------------------- loop
    def serve(self, idle_exit: float | None = None, max_requests: int | None = None) -> int:
        """Answer requests until ``idle_exit`` seconds pass without one or ``max_requests`` were answered
        (forever when both are None). Returns the number of requests answered."""
        import zmq

        poller = zmq.Poller()
        poller.register(self.socket, zmq.POLLIN)
        answered, last = 0, time.monotonic()
        while max_requests is None or answered < max_requests:
            if not poller.poll(timeout=1000):
                self._expire()
                if idle_exit is not None and time.monotonic() - last > idle_exit:
                    log.info("no request for %.0f s; stopping", idle_exit)
                    break
                continue
            frames = self.socket.recv_multipart(copy=True)
            envelope, body = self._split(frames)
            reply = self.answer(body)
            self.socket.send_multipart([*envelope, *reply], copy=False)
            answered += 1
            last = time.monotonic()
        return answered

    @staticmethod
    def _split(frames: list[bytes]) -> tuple[list[bytes], list[bytes]]:
        """(routing envelope, request frames): REQ clients put an empty delimiter after the routing id; DEALER
        clients may not."""
        for i in range(1, len(frames)):
            if frames[i] == b"":
                return frames[:i + 1], frames[i + 1:]
        return frames[:1], frames[1:]

    def answer(self, frames: list[bytes]) -> list[bytes]:
        """The reply frames to one request's frames; never raises."""
        rid = None
        try:
            header = decode_request(frames, self.max_request_bytes)
            rid = header.get("id")
            reply_header, binary = self.handlers[header["type"]](header)
            reply_header = {"protocol": PROTOCOL, "id": rid, **reply_header}
            return [encode(reply_header), *binary]
        except ProtocolError as e:
            return [encode(error_header(e.code, e.message, rid))]
        except MubleError as e:
            return [encode(error_header("episode_error", str(e), rid))]
        except Exception as e:  # noqa: BLE001 - a request must never stop the server
            log.exception("unexpected error answering a request")
            return [encode(error_header("internal", f"{type(e).__name__}: {e}"[:500], rid))]

    def close(self) -> None:
        for session in list(self.sessions.values()):
            session.episode.close()
        self.sessions.clear()
        self.socket.close(0)
        self.context.term()
        self.factory.close()

    # --------------------------------------------------------------------------------------------- requests
    def _hello(self, header: dict[str, Any]) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, set())
        registry = self.factory.registry
        primitives = [{"name": name, "params": [p.describe() for p in specs(
            registry.get("primitive", name).record.factory.params)]} for name in registry.names("primitive")]
        return {"type": "hello", "templates": self.factory.templates, "primitives": primitives,
                "cameras": [str(c) for c in self.factory.cfg.episode.cameras] if self.factory.render else [],
                "image_formats": list(IMAGE_FORMATS), "max_request_bytes": self.max_request_bytes,
                "open_sessions": len(self.sessions), "max_sessions": self.max_sessions}, []

    def _reset(self, header: dict[str, Any]) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, {"episode", "images"})
        images = header.get("images", "png")
        if images not in IMAGE_FORMATS:
            raise ProtocolError("bad_request", f"'images' must be one of {', '.join(IMAGE_FORMATS)}")
        self._expire()
        if len(self.sessions) >= self.max_sessions:
            raise ProtocolError("busy", f"{len(self.sessions)} sessions are open (the maximum); close one first")
        spec = self._episode(header.get("episode"))
        episode = SteppedEpisode(self.factory.runner(), spec.scene, spec.instruction, spec.task)
        step = episode.start()
        token = secrets.token_hex(16)
        session = Session(token, episode, spec, images)
        self.sessions[token] = session
        reply, binary = self._observation(session, step)
        reply.update(instruction=instruction_to_dict(agent_instruction(spec.instruction)), source=spec.source)
        return reply, binary

    def _episode(self, episode: Any) -> EpisodeSpec:
        if not isinstance(episode, dict):
            raise ProtocolError("bad_request", "'episode' must be an object: {scene_index, template}, "
                                "{split, index} or {scene, instruction}")
        keys = set(episode)
        if keys == {"scene_index", "template"} or keys == {"scene_index"}:
            index, template = episode["scene_index"], episode.get("template")
            if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < 2**31:
                raise ProtocolError("bad_request", "'scene_index' must be an integer in [0, 2**31)")
            if template is not None and not isinstance(template, str):
                raise ProtocolError("bad_request", "'template' must be a template name")
            templates = [template] if template is not None else None
            spec = self.factory.generated(index, templates)
            if spec is None:
                raise ProtocolError("episode_error", f"no instruction of {templates or 'any template'} applies to "
                                    f"scene {index}; choose another scene_index or template")
            return spec
        if keys == {"split", "index"}:
            return self.factory.stored(episode["split"], episode["index"])
        if keys == {"scene", "instruction"}:
            return self.factory.from_data(episode["scene"], episode["instruction"])
        raise ProtocolError("bad_request", f"'episode' keys {sorted(map(str, keys))[:6]} name no episode; give "
                            "{scene_index[, template]}, {split, index} or {scene, instruction}")

    def _session(self, header: dict[str, Any]) -> Session:
        token = header.get("session")
        if not isinstance(token, str):
            raise ProtocolError("bad_request", "'session' must be the token a reset reply gave")
        session = self.sessions.get(token)
        if session is None:
            raise ProtocolError("unknown_session", "no open session has this token; send reset to open one")
        session.last_used = time.monotonic()
        return session

    def _observe(self, header: dict[str, Any]) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, {"session"})
        session = self._session(header)
        return self._observation(session, session.episode.last)

    def _act(self, header: dict[str, Any]) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, {"session", "action"})
        session = self._session(header)
        if session.episode.done:
            raise ProtocolError("out_of_order", "the session's episode has ended; send close, then reset for a "
                                "new episode")
        try:
            decision, stop = decision_from_plain(header.get("action"))
        except MalformedDecision as e:
            raise ProtocolError("bad_request", f"'action': {e}") from None
        step = session.episode.decide(decision, stop)
        return self._observation(session, step)

    def _close(self, header: dict[str, Any]) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, {"session"})
        session = self._session(header)
        session.episode.close()
        del self.sessions[session.token]
        return {"type": "closed", "session": session.token}, []

    # ------------------------------------------------------------------------------------------- internals
    def _observation(self, session: Session, step: Step) -> tuple[dict[str, Any], list[bytes]]:
        observation = step.observation
        reply: dict[str, Any] = {"type": "observation", "session": session.token, "done": step.done,
                                 "observation": observation_to_plain(observation), "images": []}
        binary: list[bytes] = []
        if session.images != "none":
            for camera, frame in observation.images.items():
                rgb = np.ascontiguousarray(frame.rgb, dtype=np.uint8)
                binary.append(png(rgb) if session.images == "png" else rgb.tobytes())
                reply["images"].append({"camera": camera, "frame": len(binary), "format": session.images,
                                        "shape": list(rgb.shape), "dtype": "uint8"})
        if step.done:
            result = step.output.result
            reply.update(outcome=result.outcome.value, error=result.error, reward=float(
                result.outcome.value == "success"), answer=None if result.answer is None else plain(
                result.answer.value), actions=[{"name": a.name, "params": plain(a.params)} for a in result.actions])
        return reply, binary

    def _expire(self) -> None:
        now = time.monotonic()
        for token, session in list(self.sessions.items()):
            if now - session.last_used > self.session_timeout:
                log.info("session %s… idle for %.0f s: closed", token[:8], now - session.last_used)
                session.episode.close()
                del self.sessions[token]


def _only(header: dict[str, Any], allowed: set[str]) -> None:
    unknown = sorted(str(k) for k in header if k not in allowed | {"protocol", "type", "id"})
    if unknown:
        raise ProtocolError("bad_request", f"unknown field(s) {unknown[:6]} for '{header['type']}'; it takes "
                            f"{', '.join(sorted(allowed)) or 'no fields'}")
