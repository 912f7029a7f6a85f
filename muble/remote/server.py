"""``muble serve``: SHOP-VRB2 episodes driven by an agent in another process, over the protocol of
``muble.remote.wire`` on a ZeroMQ ROUTER socket.

Each ``reset`` opens a session (a token) bound to one episode, run by ``SteppedEpisode`` through the same action
loop as ``muble run``/``muble eval``.

Two processes. The server's process runs only the request loop: it reads every request, checks it (shape,
bounds, session state) and answers at once whatever needs no simulation: ``hello``, ``observe`` (the session's
last observation, kept), ``close``, every error, ``busy``. A ``reset`` or ``act`` becomes a job for the
simulation process (``muble.remote.simulation``), which holds every episode and runs jobs one at a time, in
order, as one process did before; its result comes back to the loop, which sends the reply. So a long reset
never delays another client's ``hello``, and a crash inside MuJoCo or OpenGL costs the episodes, not the server:
their requests are answered with an error and a fresh simulation process starts.

Work is bounded: a session holds at most one job (another request for it meanwhile gets ``busy``), at most
``max_sessions`` sessions exist, a scene holds at most ``max_objects`` objects, and a job that overruns
``step_timeout`` (plus the grace the episode needs to stop) gets the simulation process replaced.

A session is reclaimed when its client cannot be reached with the reset reply (it left before the token was
sent), when it has been idle for ``session_timeout`` seconds, or when it is closed.
"""
from __future__ import annotations

import collections
import errno
import ipaddress
import logging
import os
import secrets
import time
from dataclasses import dataclass, field
from typing import Any, Callable

from muble.core.errors import MubleError
from muble.episode.plain import MalformedDecision, decision_from_plain
from muble.episode.sources import dataset_root
from muble.remote.episodes import EpisodeRequest, public_text
from muble.remote.wire import (DEFAULT_HOST, DEFAULT_PORT, HARD_LIMIT_BYTES, IMAGE_FORMATS, MAX_REQUEST_BYTES,
                                   PROTOCOL, ProtocolError, decode_request, encode, error_header)
from muble.remote.schema import primitive_entries
from muble.remote.simulation import SimulationProcess, SimulationSetup

log = logging.getLogger(__name__)

DEFAULT_MAX_SESSIONS = 2
DEFAULT_SESSION_TIMEOUT = 120.0  # s without a request before a session is closed: a vanished client's slot
DEFAULT_MAX_OBJECTS = 64  # objects per scene; the generator's scenes have 3-7, SHOP-VRB2's at most 10
DEFAULT_STEP_TIMEOUT = 600.0  # s one reset or act may take before its episode is abandoned
# s beyond step_timeout before the simulation process is replaced: an abandoned episode's worker gets 60 s to
# stop (muble.episode.stepped), and the reset's scene generation is not under step_timeout.
OVERRUN_GRACE_S = 120.0
RESTART_BACKOFF_S = 30.0  # s before a simulation process that ended while starting is tried again


class ListenError(MubleError):
    """The server cannot listen where it was told to (address not of this machine, port in use)."""


@dataclass
class Session:
    token: str
    images: str
    last_used: float = field(default_factory=time.monotonic)
    working: bool = False  # a job of this session is queued or running
    closing: bool = False  # closed or expired: unknown to requests, its slot held until the episode is freed
    reply: tuple[dict[str, Any], list[bytes]] | None = None  # the last observation (header, image frames)

    @property
    def done(self) -> bool:
        return bool(self.reply and self.reply[0].get("done"))


@dataclass
class Job:
    """A request handed to the simulation process, and where its reply goes."""

    id: int
    session: Session
    message: dict[str, Any]
    envelope: list[bytes] | None  # None: nobody waits for a reply (close, expiry)
    rid: Any = None
    sent: float | None = None


def is_loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


class EpisodeServer:
    """Serves episodes on ``tcp://host:port`` (port 0: any free port, see ``endpoint``).

    ``cfg`` is the composed ``run`` config (templates, cameras, ``dataset.root``); ``build_factory`` builds the
    ``EpisodeFactory`` of that config inside the simulation process, so it must pickle (a module-level function
    or a ``functools.partial`` of one). ``render``: whether episodes render images.
    """

    def __init__(self, cfg: Any, build_factory: Callable[[], Any], render: bool = True, host: str = DEFAULT_HOST,
                 port: int = DEFAULT_PORT, max_sessions: int = DEFAULT_MAX_SESSIONS,
                 session_timeout: float = DEFAULT_SESSION_TIMEOUT, max_request_bytes: int = MAX_REQUEST_BYTES,
                 max_objects: int = DEFAULT_MAX_OBJECTS, step_timeout: float = DEFAULT_STEP_TIMEOUT):
        import zmq

        from muble.plugins.registry import get_registry

        self.cfg = cfg
        self.render = render
        self.registry = get_registry()
        self.templates = list(self.registry.names("task"))
        self.primitives = primitive_entries(self.registry)
        self.max_sessions = max_sessions
        self.session_timeout = session_timeout
        self.max_request_bytes = max_request_bytes
        self.max_objects = max_objects
        self.step_timeout = step_timeout
        self.dataset_root = dataset_root(cfg)
        self.sessions: dict[str, Session] = {}
        self.pending: collections.deque[Job] = collections.deque()  # not yet taken by the simulation process
        self.running: collections.OrderedDict[int, Job] = collections.OrderedDict()  # taken, in order
        self.last_result = time.monotonic()
        self._job_ids = 0
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
            self.socket.close(0)
            self.context.term()
            hint = ("another process listens on that port: choose another --port (0 picks a free one)"
                    if e.errno == errno.EADDRINUSE else
                    "--host must be an address of this machine (127.0.0.1: this machine only; 0.0.0.0: every "
                    "interface) and --port one you may open")
            why = os.strerror(e.errno) if e.errno is not None else str(e)
            raise ListenError(f"cannot listen on {address}: {why}; {hint}") from None
        self.endpoint = self.socket.getsockopt_string(zmq.LAST_ENDPOINT)
        setup = SimulationSetup(build_factory, step_timeout, max_objects,
                                None if self.dataset_root is None else str(self.dataset_root))
        self.simulation = SimulationProcess(self.context, setup)
        try:
            self.simulation.wait_ready()
        except BaseException:
            self.close()
            raise
        self.handlers: dict[str, Callable[..., Any]] = {
            "hello": self._hello, "reset": self._reset, "observe": self._observe, "act": self._act,
            "close": self._close}

    # ------------------------------------------------------------------------------------------------- loop
    def serve(self, idle_exit: float | None = None, max_requests: int | None = None) -> int:
        """Answer requests until ``idle_exit`` seconds pass without one (and no job is open) or ``max_requests``
        were received (forever when both are None). Returns the number of requests received."""
        import zmq

        received, last = 0, time.monotonic()
        while max_requests is None or received < max_requests:
            poller = zmq.Poller()  # made afresh: a replaced simulation process has a new socket and sentinel
            poller.register(self.socket, zmq.POLLIN)
            poller.register(self.simulation.socket, zmq.POLLIN)
            if self.simulation.alive():  # an ended one's sentinel stays readable: it would spin the loop
                poller.register(self.simulation.sentinel, zmq.POLLIN)
            events = dict(poller.poll(timeout=1000))
            if self._results():
                last = time.monotonic()
            self._watch()
            self._expire()
            self._flush()
            if events.get(self.socket):
                try:
                    frames = self.socket.recv_multipart(zmq.NOBLOCK)
                except zmq.Again:
                    continue
                envelope, body = self._split(frames)
                reply = self._reply(envelope, body)
                if reply is not None:
                    self._send(envelope, reply)
                self._flush()
                received += 1
                last = time.monotonic()
            elif idle_exit is not None and not (self.pending or self.running) \
                    and time.monotonic() - last > idle_exit:
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

    def _reply(self, envelope: list[bytes], body: list[bytes]) -> list[bytes] | None:
        """The reply to a request, or None when it became a job (the job's reply follows); never raises."""
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
        except MubleError as e:
            return [encode(error_header("episode_error", public_text(str(e), self.dataset_root)[:1000], rid))]
        except Exception as e:  # noqa: BLE001 - a request must never stop the server
            log.exception("unexpected error answering a request")
            return [encode(error_header("internal", f"an unexpected {type(e).__name__} (logged on the server); "
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
        """Stop: the simulation process closes every episode and ends; then the socket closes."""
        simulation = getattr(self, "simulation", None)
        if simulation is not None:
            simulation.close()
        self.sessions.clear()
        self.socket.close(0)
        self.context.term()

    # ------------------------------------------------------------------------------------------------- jobs
    def _job(self, session: Session, message: dict[str, Any], envelope: list[bytes] | None, rid: Any) -> None:
        self._job_ids += 1
        session.working = True
        self.pending.append(Job(self._job_ids, session, {**message, "job": self._job_ids, "token": session.token},
                                envelope, rid))

    def _flush(self) -> None:
        """Hand queued jobs to the simulation process, as far as it takes them now."""
        while self.pending and self.simulation.send(self.pending[0].message):
            job = self.pending.popleft()
            job.sent = time.monotonic()
            if not self.running:
                self.last_result = job.sent  # the process was idle: this job starts now
            self.running[job.id] = job

    def _results(self) -> bool:
        """Settle every result the simulation process has sent; True if any."""
        any_result = False
        while True:
            received = self.simulation.receive()
            if received is None:
                return any_result
            result, binary = received
            if result["kind"] in ("ready", "failed"):
                if result["kind"] == "failed":
                    log.error("the simulation process could not start: %s", result["message"])
                continue
            any_result = True
            self.last_result = time.monotonic()
            job = self.running.pop(result["job"], None)
            if job is not None:
                self._settle(job, result, binary)

    def _settle(self, job: Job, result: dict[str, Any], binary: list[bytes]) -> None:
        session, kind = job.session, job.message["kind"]
        session.working = False
        session.last_used = time.monotonic()
        if kind == "close":
            self.sessions.pop(session.token, None)
            return
        if result["ok"]:
            frames = [encode({"protocol": PROTOCOL, "id": job.rid, **result["header"]}), *binary]
            session.reply = (result["header"], binary)
        else:
            code, message = result["error"]
            frames = [encode(error_header(code, message, job.rid))]
            if kind == "reset" or result["ended"]:
                self.sessions.pop(session.token, None)  # no episode runs for it any more
        sent = job.envelope is None or self._send(job.envelope, frames)
        if kind == "reset" and result["ok"] and not sent:
            log.info("session %s…: its client left before the reset reply; closed", session.token[:8])
            self._free(session)
        elif session.closing and session.token in self.sessions:
            self._free(session)

    def _watch(self) -> None:
        """Replace the simulation process when it has ended or overrun its time; the requests it held are
        answered with an error and every session is lost. One that ended while starting is retried after
        ``RESTART_BACKOFF_S``, so a broken setup does not respawn in a loop."""
        overran = bool(self.running) and time.monotonic() - self.last_result > self.step_timeout + OVERRUN_GRACE_S
        if self.simulation.alive() and not overran:
            return
        reason = (f"ran over its time limit ({self.step_timeout:g} s)" if overran else
                  f"stopped (exit code {self.simulation.exitcode})")
        if self.running or self.pending or self.sessions:
            log.error("the simulation process %s; %d session(s) lost", reason, len(self.sessions))
            for job in [*self.running.values(), *self.pending]:
                if job.envelope is not None:
                    self._send(job.envelope, [encode(error_header(
                        "episode_error", f"the simulation {reason} while running this request; the episode is "
                        "lost: reset to start a new one", job.rid))])
            self.running.clear()
            self.pending.clear()
            self.sessions.clear()
        if not overran and not self.simulation.ready \
                and time.monotonic() - self.simulation.started < RESTART_BACKOFF_S:
            return
        log.info("starting a new simulation process")
        self.simulation.restart()

    def _free(self, session: Session) -> None:
        """Close a session: it is unknown to requests at once; its slot is freed when its episode is."""
        session.closing = True
        if not session.working:
            self._job(session, {"kind": "close"}, None, None)

    def _expire(self) -> None:
        now = time.monotonic()
        for session in list(self.sessions.values()):
            if not session.working and not session.closing and now - session.last_used > self.session_timeout:
                log.info("session %s… idle for %.0f s: closed", session.token[:8], now - session.last_used)
                self._free(session)

    # --------------------------------------------------------------------------------------------- requests
    def _hello(self, header: dict[str, Any], envelope: Any, rid: Any) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, set())
        return {"type": "hello", "templates": self.templates, "primitives": self.primitives,
                "cameras": [str(c) for c in self.cfg.episode.cameras] if self.render else [],
                "image_formats": list(IMAGE_FORMATS), "max_request_bytes": self.max_request_bytes,
                "max_objects": self.max_objects, "session_timeout": self.session_timeout,
                "step_timeout": self.step_timeout, "stored_episodes": self.dataset_root is not None,
                "open_sessions": len(self.sessions), "max_sessions": self.max_sessions}, []

    def _reset(self, header: dict[str, Any], envelope: list[bytes], rid: Any) -> None:
        _only(header, {"episode", "images"})
        images = header.get("images", "png")
        if images not in IMAGE_FORMATS:
            raise ProtocolError("bad_request", f"'images' must be one of {', '.join(IMAGE_FORMATS)}")
        request = EpisodeRequest.check(header.get("episode"), self.templates, self.dataset_root, self.max_objects)
        self._expire()
        if len(self.sessions) >= self.max_sessions:
            raise ProtocolError("busy", f"{len(self.sessions)} sessions are open (the maximum); close one first or "
                                "retry later")
        session = Session(secrets.token_hex(16), images)
        self.sessions[session.token] = session
        self._job(session, {"kind": "reset", "episode_kind": request.kind, "document": request.document,
                            "images": images}, envelope, rid)
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
        reply = self._session(header).reply
        if reply is None:  # set by the reset's result, before which the session is busy
            raise ProtocolError("busy", "the session has no observation yet; wait for its reset reply")
        return reply

    def _act(self, header: dict[str, Any], envelope: list[bytes], rid: Any) -> None:
        _only(header, {"session", "action"})
        session = self._session(header)
        if session.done:
            raise ProtocolError("out_of_order", "the session's episode has ended; send close, then reset for a "
                                "new episode")
        try:
            decision_from_plain(header.get("action"))
        except MalformedDecision as e:
            raise ProtocolError("bad_request", f"'action': {e}") from None
        self._job(session, {"kind": "act", "action": header.get("action")}, envelope, rid)
        return None

    def _close(self, header: dict[str, Any], envelope: Any, rid: Any) -> tuple[dict[str, Any], list[bytes]]:
        _only(header, {"session"})
        session = self._session(header)
        self._free(session)
        return {"type": "closed", "session": session.token}, []


def _only(header: dict[str, Any], allowed: set[str]) -> None:
    unknown = sorted(str(k) for k in header if k not in allowed | {"protocol", "type", "id"})
    if unknown:
        raise ProtocolError("bad_request", f"unknown field(s) {unknown[:6]} for '{header['type']}'; it takes "
                            f"{', '.join(sorted(allowed)) or 'no fields'}")
