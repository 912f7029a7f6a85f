"""The simulation process of ``muble serve``: every session's episode (MuJoCo world, renderer, action loop) lives
in one process of its own, which runs the server's jobs (``reset``, ``act``, ``close``) one at a time, in order.

Why a process and not a thread: MuJoCo's model compiler and OpenGL rendering hold Python's global interpreter
lock for whole calls, over a second each on a machine that renders without a GPU (measured: 1.0-1.7 s creating
the renderer's context and drawing the first frame). In a thread of the server's process they would stall the
request loop, and with it every other client's ``hello``. In a process of their own they stall nothing, and a
native crash or a runaway episode ends that process only: the server answers the requests it held with an error
and starts a fresh one.

The two processes speak over a ZeroMQ PAIR socket on an ``ipc://`` path in a private folder (mode 0700): a job is
a pickled dict, a result a pickled dict followed by the reply's binary frames (images). Both ends are this
package's code; nothing a client sends is unpickled, only JSON data the server checked is forwarded.
"""
from __future__ import annotations

import io
import logging
import multiprocessing
import os
import pickle
import shutil
import signal
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from muble.core.errors import MubleError

if TYPE_CHECKING:  # pragma: no cover
    import zmq

log = logging.getLogger(__name__)

READY_TIMEOUT_S = 600.0  # s the first simulation process may take to build the configured plugins
STOP_TIMEOUT_S = 10.0  # s a stopping simulation process gets to close its episodes before it is killed


@dataclass(frozen=True)
class SimulationSetup:
    """What the simulation process is started with. It crosses into a fresh interpreter, so it must pickle:
    ``build_factory`` is a module-level function (or a ``functools.partial`` of one) returning the
    ``EpisodeFactory``."""

    build_factory: Callable[[], Any]
    step_timeout: float
    max_objects: int
    dataset_root: str | None


def png(rgb: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG", compress_level=1)
    return buf.getvalue()


# ------------------------------------------------------------------------------------ the simulation process
def simulation_main(address: str, setup: SimulationSetup, parent_pid: int) -> None:
    """The simulation process: build the factory, say ``ready`` (or ``failed`` with the reason), then run jobs
    until told to stop or the server's process is gone."""
    import zmq

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C stops the server, which stops this process
    context = zmq.Context()
    socket = context.socket(zmq.PAIR)
    socket.setsockopt(zmq.LINGER, 0)
    socket.connect(address)
    sessions: dict[str, tuple[Any, str]] = {}
    factory = None
    try:
        try:
            factory = setup.build_factory()
        except Exception as e:  # noqa: BLE001 - reported to the server, which reports it to the user
            message = str(e) if isinstance(e, MubleError) else f"{type(e).__name__}: {e}"
            socket.send(pickle.dumps({"kind": "failed", "message": message}))
            return
        socket.send(pickle.dumps({"kind": "ready"}))
        while True:
            if not socket.poll(1000):
                if os.getppid() != parent_pid:
                    break  # the server is gone
                continue
            job = pickle.loads(socket.recv())
            if job["kind"] == "stop":
                break
            result, binary = run_job(job, factory, sessions, setup)
            socket.send_multipart([pickle.dumps(result), *binary], copy=False)
    finally:
        for episode, _ in sessions.values():
            episode.close()
        if factory is not None:
            factory.close()
        socket.close(0)
        context.term()


def run_job(job: dict[str, Any], factory: Any, sessions: dict[str, tuple[Any, str]],
            setup: SimulationSetup) -> tuple[dict[str, Any], list[bytes]]:
    """One job's result (``ok``, ``header`` or ``error`` (code, message), ``ended``: the session is gone) and
    binary frames; never raises."""
    from muble.episode.components import benchmark_settings
    from muble.episode.plain import decision_from_plain
    from muble.episode.modes import track_instruction
    from muble.episode.stepped import SteppedEpisode
    from muble.io.instructions_io import instruction_to_dict
    from muble.remote.episodes import EpisodeRequest, public_text
    from muble.remote.wire import ProtocolError

    token, kind = job["token"], job["kind"]
    root = Path(setup.dataset_root) if setup.dataset_root else None
    result: dict[str, Any] = {"kind": kind, "job": job["job"], "token": token, "ok": True, "header": None,
                              "error": None, "ended": False}
    binary: list[bytes] = []
    try:
        if kind == "reset":
            spec = EpisodeRequest(job["episode_kind"], job["document"]).build(factory, root, setup.max_objects)
            episode = SteppedEpisode(factory.runner(), spec.scene, spec.instruction, spec.task,
                                     timeout=setup.step_timeout)
            try:
                step = episode.start()
            except BaseException:
                episode.close()
                raise
            sessions[token] = (episode, job["images"])
            header, binary = observation_reply(token, job["images"], step, root)
            track, mode = benchmark_settings(factory.cfg)
            header.update(instruction=instruction_to_dict(track_instruction(spec.instruction, track)), track=track,
                          mode=mode, source=spec.source)
        elif kind == "act":
            episode, images = sessions[token]
            decision, stop = decision_from_plain(job["action"])
            try:
                step = episode.decide(decision, stop)
            except BaseException:
                # The episode failed inside (time limit, an error of the loop): it cannot go on.
                sessions.pop(token, None)
                episode.close()
                result["ended"] = True
                raise
            header, binary = observation_reply(token, images, step, root)
        else:  # close
            closing, _ = sessions.pop(token, (None, None))
            if closing is not None:
                closing.close()
            header = {}
        result["header"] = header
        return result, binary
    except ProtocolError as e:
        result.update(ok=False, error=(e.code, e.message))
    except MubleError as e:
        result.update(ok=False, error=("episode_error", public_text(str(e), root)[:1000]))
    except Exception as e:  # noqa: BLE001 - a job must never stop the simulation process
        log.exception("unexpected error in a %s job", kind)
        result.update(ok=False, error=("internal", f"an unexpected {type(e).__name__} (logged on the server); the "
                                       "server keeps serving"))
    return result, []


def observation_reply(token: str, images: str, step: Any, root: Path | None) -> tuple[dict[str, Any], list[bytes]]:
    """The observation reply's header (without ``protocol`` and ``id``) and its image frames, numbered from 1
    (frame 0 is the header)."""
    from muble.episode.plain import observation_to_plain, plain
    from muble.remote.episodes import public_text

    observation = step.observation
    plain_observation = observation_to_plain(observation)
    # Every object names its id first: the id, not the position in the list, is what a call's target gives.
    scene = plain_observation["scene"]
    scene["objects"] = [{"id": int(o.id), **d} for o, d in zip(observation.scene.objects, scene["objects"])]
    reply: dict[str, Any] = {"type": "observation", "session": token, "done": step.done,
                             "observation": plain_observation, "images": []}
    binary: list[bytes] = []
    if images != "none":
        for camera, frame in observation.images.items():
            rgb = np.ascontiguousarray(frame.rgb, dtype=np.uint8)
            binary.append(png(rgb) if images == "png" else rgb.tobytes())
            reply["images"].append({"camera": camera, "frame": len(binary), "format": images,
                                    "shape": list(rgb.shape), "dtype": "uint8"})
    if step.done:
        result = step.output.result
        reply.update(outcome=result.outcome.value,
                     error=None if result.error is None else public_text(result.error, root),
                     reward=float(result.outcome.value == "success"),
                     answer=None if result.answer is None else plain(result.answer.value),
                     actions=[{"name": a.name, "params": plain(a.params)} for a in result.actions])
    return reply, binary


# ----------------------------------------------------------------------------------- the server's handle on it
class SimulationProcess:
    """The server's side: starts the simulation process, hands it jobs without ever blocking, reads its
    results, and replaces it when it ends."""

    def __init__(self, context: Any, setup: SimulationSetup):
        self.context = context
        self.setup = setup
        self.folder = tempfile.mkdtemp(prefix="muble-serve-")  # mode 0700: no other user reaches the socket
        self.generation = 0
        self.socket: zmq.Socket[bytes] | None = None  # None while stopped
        self.process: multiprocessing.process.BaseProcess | None = None
        self.ready = False
        self.start()

    def start(self) -> None:
        import zmq

        self.generation += 1
        address = f"ipc://{self.folder}/simulation-{self.generation}"
        socket = self.context.socket(zmq.PAIR)
        socket.setsockopt(zmq.LINGER, 0)
        socket.bind(address)
        self.socket = socket
        spawn = multiprocessing.get_context("spawn")  # a fresh interpreter: no threads or GL state inherited
        process = spawn.Process(target=simulation_main, args=(address, self.setup, os.getpid()),
                                name="muble-simulation")
        self.process = process
        process.start()
        self.started = time.monotonic()
        self.ready = False

    def _live(self) -> tuple[zmq.Socket[bytes], multiprocessing.process.BaseProcess]:
        """The socket and process of the running simulation; ``MubleError`` once it is stopped."""
        if self.socket is None or self.process is None:
            raise MubleError("the simulation process is stopped: restart() it first")
        return self.socket, self.process

    @property
    def sentinel(self) -> int:
        return self._live()[1].sentinel

    def alive(self) -> bool:
        return self.process is not None and self.process.is_alive()

    @property
    def exitcode(self) -> int | None:
        """The process's exit code; None while it runs (or before it started)."""
        return None if self.process is None else self.process.exitcode

    def send(self, job: dict[str, Any]) -> bool:
        """Queue a job; False when the process cannot take it yet (not connected): send it again later."""
        import zmq

        if not self.ready or self.socket is None:  # stop() clears both
            return False
        try:
            self.socket.send(pickle.dumps(job), flags=zmq.NOBLOCK)
            return True
        except zmq.Again:
            return False

    def receive(self) -> tuple[dict[str, Any], list[bytes]] | None:
        """A message of the process (``ready``, ``failed`` or a job's result) and its frames, or None."""
        import zmq

        socket, _ = self._live()
        try:
            frames = socket.recv_multipart(zmq.NOBLOCK)
        except zmq.Again:
            return None
        message = pickle.loads(frames[0])
        if message.get("kind") == "ready":
            self.ready = True
        return message, frames[1:]

    def wait_ready(self, timeout: float = READY_TIMEOUT_S) -> None:
        """Wait until the process has built the configured plugins; ``MubleError`` with its reason if it could
        not."""
        import zmq

        socket, process = self._live()
        poller = zmq.Poller()
        poller.register(socket, zmq.POLLIN)
        poller.register(process.sentinel, zmq.POLLIN)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            poller.poll(timeout=1000)
            received = self.receive()
            if received is not None:
                message = received[0]
                if message["kind"] == "ready":
                    return
                if message["kind"] == "failed":
                    raise MubleError(message["message"])
            if not self.alive():
                raise MubleError(f"the simulation process stopped while starting (exit code {process.exitcode})")
        raise MubleError(f"the simulation process did not start within {timeout:.0f} s")

    def restart(self) -> None:
        """Replace the process (it ended or overran): a fresh one on a fresh socket."""
        self.stop()
        self.start()

    def stop(self) -> None:
        """Ask the process to close its episodes and end; kill it if it does not in time."""
        import zmq

        if self.process is not None and self.process.is_alive():
            try:
                if self.socket is not None:
                    self.socket.send(pickle.dumps({"kind": "stop"}), flags=zmq.NOBLOCK)
            except zmq.ZMQError:
                pass
            self.process.join(STOP_TIMEOUT_S)
            if self.process.is_alive():
                self.process.kill()
                self.process.join(STOP_TIMEOUT_S)
        if self.socket is not None:
            self.socket.close(0)
            self.socket = None
        self.ready = False

    def close(self) -> None:
        self.stop()
        shutil.rmtree(self.folder, ignore_errors=True)

