"""``muble serve``: SHOP-VRB2 episodes driven by an agent in another process, over the protocol of
``muble.remote.protocol`` on a ZeroMQ ROUTER socket.

Each ``reset`` opens a session (a token) bound to one episode, run by ``SteppedEpisode`` through the same action
loop as ``muble run``/``muble eval``.

One request loop, many worker threads. The loop alone touches the socket: it reads every request, checks it
(shape, bounds, session state) and answers at once whatever is cheap (``hello``, ``observe``, ``close``, every
error, ``busy``). A ``reset`` or ``act`` becomes a job on a thread of its own; the job's reply comes back to the
loop through a queue (a byte on a pipe wakes the loop) and the loop sends it. So a long reset never delays
another client's ``hello``. Jobs take one lock, ``simulation``, around their episode work, so that episodes step
one at a time, as in one process before: shared plugin instances, the scene generator and Blender are never used
by two threads at once. A session holds at most one job (another request for it meanwhile gets ``busy``), and at
most ``max_sessions`` sessions exist, so the work queued is bounded.

A session is reclaimed when its client cannot be reached with the reset reply (it left before the token was
sent), when it has been idle for ``session_timeout`` seconds, or when it is closed.
"""
from __future__ import annotations

import errno
import io
import ipaddress
import logging
import os
import queue
import secrets
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from muble.core.errors import MubleError
from muble.core.instructions_io import instruction_to_dict
from muble.episode.plain import MalformedDecision, decision_from_plain, observation_to_plain, plain
from muble.episode.sources import EpisodeFactory, agent_instruction
from muble.episode.stepped import Step, SteppedEpisode
from muble.remote.episodes import EpisodeRequest, dataset_root, public_text
from muble.remote.protocol import (DEFAULT_HOST, DEFAULT_PORT, HARD_LIMIT_BYTES, IMAGE_FORMATS, MAX_REQUEST_BYTES,
                                   PROTOCOL, ProtocolError, decode_request, encode, error_header)
from muble.remote.schema import primitive_entries

log = logging.getLogger(__name__)

DEFAULT_MAX_SESSIONS = 2
DEFAULT_SESSION_TIMEOUT = 120.0  # s without a request before a session is closed: a vanished client's slot
DEFAULT_MAX_OBJECTS = 64  # objects per scene; the generator's scenes have 3-7, SHOP-VRB2's at most 10
DEFAULT_STEP_TIMEOUT = 600.0  # s one reset or act may take before its episode is abandoned
SHUTDOWN_JOIN_S = 5.0  # s the server waits for running jobs when it stops


class ListenError(MubleError):
    """The server cannot listen where it was told to (address not of this machine, port in use)."""


@dataclass
class Session:
    token: str
    images: str
    episode: SteppedEpisode | None = None  # None while its reset runs
    last_used: float = field(default_factory=time.monotonic)
    working: bool = False  # a job of this session is running
    closing: bool = False  # closed or expired: unknown to requests, its slot held until the episode is freed


@dataclass
class Finished:
    """A job's outcome, handed from its thread to the request loop."""

    session: Session
    kind: str  # "reset", "act" or "close"
    envelope: list[bytes] | None  # where the reply goes (None: nobody waits for one)
    frames: list[bytes]
    episode: SteppedEpisode | None = None  # reset: the started episode, None when it did not start
    failed: bool = False  # the job raised: its reply is an error


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
                 max_sessions: int = DEFAULT_MAX_SESSIONS, session_timeout: float = DEFAULT_SESSION_TIMEOUT,
                 max_request_bytes: int = MAX_REQUEST_BYTES, max_objects: int = DEFAULT_MAX_OBJECTS,
                 step_timeout: float = DEFAULT_STEP_TIMEOUT):
        import zmq

        self.factory = factory
        self.max_sessions = max_sessions
        self.session_timeout = session_timeout
        self.max_request_bytes = max_request_bytes
        self.max_objects = max_objects
        self.step_timeout = step_timeout
        self.dataset_root = dataset_root(factory.cfg)
        self.sessions: dict[str, Session] = {}
        self.simulation = threading.Lock()
        self.finished: queue.Queue[Finished] = queue.Queue()
        self.jobs: set[threading.Thread] = set()
        self._wake_read, self._wake_write = os.pipe()
        os.set_blocking(self._wake_read, False)
        os.set_blocking(self._wake_write, False)
        self.primitives = primitive_entries(factory.registry)
        self.context = zmq.Context()
        self.socket = self.context.socket(zmq.ROUTER)
        self.socket.setsockopt(zmq.LINGER, 0)
        # A message over the hard limit drops its sender's connection inside ZeroMQ, before it is buffered.
        self.socket.setsockopt(zmq.MAXMSGSIZE, max(HARD_LIMIT_BYTES, max_request_bytes + 1024))
        self.socket.setsockopt(zmq.ROUTER_HANDOVER, 1)
        # A reply to a peer that has gone raises instead of vanishing: the server learns that the client left.
        self.socket.setsockopt(zmq.ROUTER_MANDATORY, 1)
        if not is_loopback(host):
            log.warning("listening on %s: agents from other machines can connect (the protocol has no "
                        "authentication; use a trusted network)", host)
        address = f"tcp://{host}:{port}" if port else f"tcp://{host}:*"
        try:
            self.socket.bind(address)
        except zmq.ZMQError as e:
            self._close_transport()
            hint = ("another process listens on that port: choose another --port (0 picks a free one)"
                    if e.errno == errno.EADDRINUSE else
                    "--host must be an address of this machine (127.0.0.1: this machine only; 0.0.0.0: every "
                    "interface) and --port one you may open")
            raise ListenError(f"cannot listen on {address}: {os.strerror(e.errno)}; {hint}") from None
        self.endpoint = self.socket.getsockopt_string(zmq.LAST_ENDPOINT)
        self.handlers: dict[str, Callable[..., Any]] = {
            "hello": self._hello, "reset": self._reset, "observe": self._observe, "act": self._act,
            "close": self._close}

    # ------------------------------------------------------------------------------------------------- loop
    def serve(self, idle_exit: float | None = None, max_requests: int | None = None) -> int:
        """Answer requests until ``idle_exit`` seconds pass without one (and no job runs) or ``max_requests``
        were received (forever when both are None). Returns the number of requests received."""
        import zmq

        poller = zmq.Poller()
        poller.register(self.socket, zmq.POLLIN)
        poller.register(self._wake_read, zmq.POLLIN)
        received, last = 0, time.monotonic()
        while max_requests is None or received < max_requests:
            events = dict(poller.poll(timeout=1000))
            if self._wake_read in events:
                self._drain_wake()
            if self._deliver():
                last = time.monotonic()
            self._expire()
            if events.get(self.socket):
                try:
                    frames = self.socket.recv_multipart(zmq.NOBLOCK)
                except zmq.Again:
                    continue
                envelope, body = self._split(frames)
                self._handle(envelope, body)
                received += 1
                last = time.monotonic()
            elif idle_exit is not None and not self._running() and time.monotonic() - last > idle_exit:
                log.info("no request for %.0f s; stopping", idle_exit)
                break
        return received

    @staticmethod
    def _split(frames: list[bytes]) -> tuple[list[bytes], list[bytes]]:
        """(routing envelope, request frames): REQ clients put an empty delimiter after the routing id; DEALER
        clients may not."""
        for i in range(1, len(frames)):
            if frames[i] == b"":
                return frames[:i + 1], frames[i + 1:]
        return frames[:1], frames[1:]

    def answer(self, frames: list[bytes]) -> list[bytes]:
        """The reply frames to one request that needs no job (an error, ``hello``, ``observe``, ``close``);
        never raises. A request that would start a job is refused here: use ``serve``."""
        reply = self._reply(None, frames)
        return reply if reply is not None else [encode(error_header(
            "bad_request", "this request runs an episode; send it over the socket"))]

    def _handle(self, envelope: list[bytes], body: list[bytes]) -> None:
        reply = self._reply(envelope, body)
        if reply is not None:
            self._send(envelope, reply)

    def _reply(self, envelope: list[bytes] | None, body: list[bytes]) -> list[bytes] | None:
        """The reply to a request, or None when a job took it (the job's reply follows); never raises."""
        rid = None
        try:
            header = decode_request(body, self.max_request_bytes)
            rid = header.get("id")
            result = self.handlers[header["type"]](header, envelope, rid)
            if result is None:
                return None
            reply_header, binary = result
            return [encode({"protocol": PROTOCOL, "id": rid, **reply_header}), *binary]
        except ProtocolError as e:
            return [encode(error_header(e.code, e.message, rid if rid is not None else e.rid))]
        except Exception as e:  # noqa: BLE001 - a request must never stop the server
            return self._error_frames(e, rid)

    def _error_frames(self, error: Exception, rid: Any) -> list[bytes]:
        if isinstance(error, ProtocolError):
            return [encode(error_header(error.code, error.message, rid))]
        if isinstance(error, MubleError):
            message = public_text(str(error), self.dataset_root)[:1000]
            return [encode(error_header("episode_error", message, rid))]
        log.error("unexpected error answering a request", exc_info=error)
        return [encode(error_header("internal", f"an unexpected {type(error).__name__} (logged on the server); "
                                    "the server keeps serving", rid))]

    def _send(self, envelope: list[bytes], frames: list[bytes]) -> bool:
        """Send a reply; False when its client has gone (or cannot take it now), which drops the reply."""
        import zmq

        try:
            self.socket.send_multipart([*envelope, *frames], flags=zmq.NOBLOCK, copy=False)
            return True
        except zmq.ZMQError as e:
            log.info("reply not delivered (%s): the client has gone", e.strerror)
            return False

    def close(self) -> None:
        """Stop: wait briefly for running jobs, free every episode, close the socket and the factory."""
        deadline = time.monotonic() + SHUTDOWN_JOIN_S
        for job in list(self.jobs):
            job.join(timeout=max(0.0, deadline - time.monotonic()))
        self._deliver()
        for session in list(self.sessions.values()):
            if session.episode is not None and not session.working:
                session.episode.close()
        self.sessions.clear()
        self._close_transport()
        self.factory.close()

    def _close_transport(self) -> None:
        self.socket.close(0)
        self.context.term()
        for fd in (self._wake_read, self._wake_write):
            try:
                os.close(fd)
            except OSError:
                pass

    # ------------------------------------------------------------------------------------------------- jobs
    def _start_job(self, session: Session, kind: str, envelope: list[bytes] | None, rid: Any,
                   work: Callable[[], tuple[dict[str, Any], list[bytes], SteppedEpisode | None]]) -> None:
        """Run ``work`` (returning reply header, binary frames and, for a reset, the started episode) on a
        thread of its own; its reply reaches the loop through ``finished``."""
        session.working = True

        def run() -> None:
            frames: list[bytes] = []
            episode, failed = None, True
            try:
                reply_header, binary, episode = work()
                frames = [encode({"protocol": PROTOCOL, "id": rid, **reply_header}), *binary]
                failed = False
            except Exception as e:  # noqa: BLE001 - the job's error is its reply
                frames = self._error_frames(e, rid)
            finally:
                self.finished.put(Finished(session, kind, envelope, frames or self._error_frames(
                    RuntimeError("the job stopped"), rid), episode, failed))
                try:
                    os.write(self._wake_write, b"!")
                except OSError:  # the pipe is full (the loop wakes anyway) or closed (stopping)
                    pass

        thread = threading.Thread(target=run, name=f"muble-serve-{kind}", daemon=True)
        self.jobs.add(thread)
        thread.start()

    def _running(self) -> bool:
        self.jobs = {job for job in self.jobs if job.is_alive()}
        return bool(self.jobs) or not self.finished.empty()

    def _drain_wake(self) -> None:
        try:
            while os.read(self._wake_read, 4096):
                pass
        except BlockingIOError:
            pass

    def _deliver(self) -> bool:
        """Send the replies of finished jobs and settle their sessions; True if any finished."""
        delivered = False
        while True:
            try:
                done = self.finished.get_nowait()
            except queue.Empty:
                break
            delivered = True
            session = done.session
            session.working = False
            session.last_used = time.monotonic()
            if done.kind == "close":
                self.sessions.pop(session.token, None)
                continue
            if done.kind == "reset":
                if done.episode is None:
                    self.sessions.pop(session.token, None)
                else:
                    session.episode = done.episode
            sent = done.envelope is None or self._send(done.envelope, done.frames)
            if done.kind == "reset" and not sent and done.episode is not None:
                log.info("session %s…: its client left before the reset reply; closed", session.token[:8])
                self._free(session)
            elif done.kind == "act" and done.failed:
                # The episode failed inside (time limit, an error of the loop): it cannot go on.
                log.info("session %s…: its episode failed; closed", session.token[:8])
                self._free(session)
            elif session.closing and session.token in self.sessions:
                self._free(session)  # closed while working: freed now that the job is over
        return delivered

    def _free(self, session: Session) -> None:
        """Close a session: it is unknown to requests at once; its slot is freed when its episode is."""
        session.closing = True
        if session.working:
            return  # freed when its job finishes (see _deliver)
        episode = session.episode

        def work() -> tuple[dict[str, Any], list[bytes], None]:
            if episode is not None:
                with self.simulation:
                    episode.close()
            return {}, [], None

        self._start_job(session, "close", None, None, work)

    def _expire(self) -> None:
        now = time.monotonic()
        for session in list(self.sessions.values()):
            if not session.working and not session.closing and now - session.last_used > self.session_timeout:
                log.info("session %s… idle for %.0f s: closed", session.token[:8], now - session.last_used)
                self._free(session)

    # --------------------------------------------------------------------------------------------- requests
    def _hello(self, header: dict[str, Any], envelope: Any, rid: Any) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, set())
        return {"type": "hello", "templates": self.factory.templates, "primitives": self.primitives,
                "cameras": [str(c) for c in self.factory.cfg.episode.cameras] if self.factory.render else [],
                "image_formats": list(IMAGE_FORMATS), "max_request_bytes": self.max_request_bytes,
                "max_objects": self.max_objects, "session_timeout": self.session_timeout,
                "step_timeout": self.step_timeout, "stored_episodes": self.dataset_root is not None,
                "open_sessions": len(self.sessions), "max_sessions": self.max_sessions}, []

    def _reset(self, header: dict[str, Any], envelope: list[bytes] | None, rid: Any) -> None:
        _only(header, {"episode", "images"})
        images = header.get("images", "png")
        if images not in IMAGE_FORMATS:
            raise ProtocolError("bad_request", f"'images' must be one of {', '.join(IMAGE_FORMATS)}")
        request = EpisodeRequest.check(header.get("episode"), self.factory, self.dataset_root, self.max_objects)
        self._expire()
        if len(self.sessions) >= self.max_sessions:
            raise ProtocolError("busy", f"{len(self.sessions)} sessions are open (the maximum); close one first or "
                                "retry later")
        if envelope is None:
            return None
        session = Session(secrets.token_hex(16), images)
        self.sessions[session.token] = session

        def work() -> tuple[dict[str, Any], list[bytes], SteppedEpisode]:
            with self.simulation:
                spec = request.build(self.factory, self.dataset_root, self.max_objects)
                episode = SteppedEpisode(self.factory.runner(), spec.scene, spec.instruction, spec.task,
                                         timeout=self.step_timeout)
                try:
                    step = episode.start()
                except BaseException:
                    episode.close()
                    raise
            reply, binary = self._observation(session, step)
            reply.update(instruction=instruction_to_dict(agent_instruction(spec.instruction)), source=spec.source)
            return reply, binary, episode

        self._start_job(session, "reset", envelope, rid, work)
        return None

    def _session(self, header: dict[str, Any]) -> Session:
        token = header.get("session")
        if not isinstance(token, str):
            raise ProtocolError("bad_request", "'session' must be the token a reset reply gave")
        session = self.sessions.get(token)
        if session is None or session.closing:
            raise ProtocolError("unknown_session", "no open session has this token (closed, expired after "
                                f"{self.session_timeout:g} s idle, or never opened); send reset to open one")
        if session.working:
            raise ProtocolError("busy", "the session is still working on its previous request; wait for its reply")
        session.last_used = time.monotonic()
        return session

    def _observe(self, header: dict[str, Any], envelope: Any, rid: Any) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, {"session"})
        session = self._session(header)
        return self._observation(session, session.episode.last)

    def _act(self, header: dict[str, Any], envelope: list[bytes] | None, rid: Any) -> None:
        _only(header, {"session", "action"})
        session = self._session(header)
        if session.episode.done:
            raise ProtocolError("out_of_order", "the session's episode has ended; send close, then reset for a "
                                "new episode")
        try:
            decision, stop = decision_from_plain(header.get("action"))
        except MalformedDecision as e:
            raise ProtocolError("bad_request", f"'action': {e}") from None
        if envelope is None:
            return None
        episode = session.episode

        def work() -> tuple[dict[str, Any], list[bytes], None]:
            with self.simulation:
                step = episode.decide(decision, stop)
            return (*self._observation(session, step), None)

        self._start_job(session, "act", envelope, rid, work)
        return None

    def _close(self, header: dict[str, Any], envelope: Any, rid: Any) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, {"session"})
        session = self._session(header)
        self._free(session)
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
            error = None if result.error is None else public_text(result.error, self.dataset_root)
            reply.update(outcome=result.outcome.value, error=error, reward=float(
                result.outcome.value == "success"), answer=None if result.answer is None else plain(
                result.answer.value), actions=[{"name": a.name, "params": plain(a.params)} for a in result.actions])
        return reply, binary


def _only(header: dict[str, Any], allowed: set[str]) -> None:
    unknown = sorted(str(k) for k in header if k not in allowed | {"protocol", "type", "id"})
    if unknown:
        raise ProtocolError("bad_request", f"unknown field(s) {unknown[:6]} for '{header['type']}'; it takes "
                            f"{', '.join(sorted(allowed)) or 'no fields'}")
