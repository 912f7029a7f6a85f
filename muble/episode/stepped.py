"""An episode driven one decision at a time, for agents that are not Python objects in this process.

``run_episode`` pulls decisions from an ``Agent``; Gymnasium environments and the remote agent server are pushed
decisions instead (``env.step(action)``, an ``act`` message). ``SteppedEpisode`` joins the two without a second
copy of the action loop: the episode runs in ``EpisodeRunner.execute`` — settling and checking the scene, the
call checks, loop and failure limits, the judge, all as ``muble run`` and ``muble eval`` have them — on a worker
thread, with an agent whose ``act`` hands the observation over and waits for the next decision.

Only one of the two threads works at any time (they hand over through queues), so the simulation is as
deterministic as in-process. The worker makes and frees its own GL context (renderers are set up and closed
inside ``execute``), so a thread per episode is safe. An ``EpisodeThread`` passed as ``worker`` runs episode after
episode on one thread instead, so what a thread keeps (its GL contexts, a renderer kept across episodes) serves
them all: the Gymnasium environment's resets pay no new context.
"""
from __future__ import annotations

import logging
import queue
import threading
from dataclasses import dataclass
from typing import Any, Callable

from muble.core.errors import MubleError
from muble.core.interfaces import Agent, Instruction, Task
from muble.core.scene import SceneGraph
from muble.core.types import Answer, Observation, ObservationMode, Track

log = logging.getLogger(__name__)

# A decision as run_episode takes it: an ActionCall, an Answer, None (stop), or anything else (invalid_action).
Decision = Any


class EpisodeAbandoned(BaseException):
    """Raised inside the worker when an episode is closed before it ended (a BaseException, so that the action
    loop's ``except Exception`` for agent errors lets it through and the runner's ``finally`` cleans up)."""


class EpisodeStateError(MubleError):
    """A decision for an episode that has ended, or one not yet started."""


@dataclass
class Step:
    """What the agent gets back: the next observation, or the episode's end (``output`` then holds it)."""

    # None only where there is none to give: the step recorded (``last``) when the worker failed before the first
    # observation, or an end whose result holds no observation (``EpisodeResult.initial`` unset, no steps)
    observation: Observation | None
    done: bool = False
    output: Any = None  # muble.episode.runner.EpisodeOutput once done


class _Bridge(Agent):
    """The agent inside the worker: each ``act`` posts the observation and waits for the next decision."""

    def __init__(self, episode: "SteppedEpisode"):
        self.episode = episode
        self.stop_after_answer = False

    def reset(self, instruction: Instruction, observation: Observation, *, track: Track = Track.program,
              mode: ObservationMode = ObservationMode.graph) -> None:
        self.stop_after_answer = False

    def act(self, instruction: Instruction, observation: Observation) -> Decision:
        if self.stop_after_answer:  # an answer that ends the episode: the loop judges it next
            return None
        decision, stop = self.episode._exchange(observation)
        if isinstance(decision, Answer) and stop:
            self.stop_after_answer = True
        return decision


class EpisodeThread:
    """One worker thread that runs episodes one after another (``submit``), and anything that must run where their
    GL contexts are current (``call``: closing a renderer kept across episodes)."""

    def __init__(self, name: str = "muble-episodes") -> None:
        self.name = name
        self._jobs: queue.Queue = queue.Queue()
        self._thread: threading.Thread | None = None

    def submit(self, job: Callable[[], None]) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._loop, name=self.name, daemon=True)
            self._thread.start()
        self._jobs.put(job)

    def call(self, fn: Callable[[], Any], timeout: float = 60.0) -> Any:
        """``fn()`` run on the worker thread (after the jobs before it); its result, or what it raised."""
        done: queue.Queue = queue.Queue()

        def job() -> None:
            try:
                done.put((True, fn()))
            except BaseException as e:  # noqa: BLE001 - raised on the caller's side
                done.put((False, e))

        self.submit(job)
        ok, value = done.get(timeout=timeout)
        if not ok:
            raise value
        return value

    def interrupt(self) -> None:
        """Raise ``EpisodeAbandoned`` inside the worker thread at its next Python instruction, and end the thread
        after it: a job stuck in a Python loop stops, one blocked in a C call (``time.sleep``, a socket) when the
        call returns. For a job abandoned after its time limit (Python cannot stop a thread otherwise); the worker
        takes no job after it."""
        import ctypes

        thread = self._thread
        if thread is not None and thread.ident is not None and thread.is_alive():
            self._jobs.put(None)
            ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread.ident),
                                                       ctypes.py_object(EpisodeAbandoned))

    def close(self, timeout: float = 60.0) -> None:
        if self._thread is not None and self._thread.is_alive():
            self._jobs.put(None)
            self._thread.join(timeout=timeout)
        self._thread = None

    def _loop(self) -> None:
        try:
            while (job := self._jobs.get()) is not None:
                job()
        except EpisodeAbandoned:  # interrupted between two jobs: the thread just ends
            pass


class SteppedEpisode:
    """One episode of ``runner`` on ``scene`` and ``instruction``, judged by ``task``, one decision at a time.

    ``start()`` returns the first ``Step`` (already ``done`` when the scene is broken); each ``decide(decision)``
    returns the next. ``Answer`` decisions end the episode unless ``stop=False`` is passed with them (the action
    loop then keeps going, as with an in-process agent that answers and acts on). ``close()`` abandons an episode
    that has not ended. ``timeout`` (s) bounds how long one primitive may take before the episode is abandoned.
    ``worker``: an ``EpisodeThread`` to run on (default: a thread of its own).
    """

    def __init__(self, runner: Any, scene: SceneGraph, instruction: Instruction, task: Task,
                 timeout: float = 600.0, on_end: Callable[[Any], None] | None = None,
                 worker: EpisodeThread | None = None):
        self.runner = runner
        self.scene = scene
        self.instruction = instruction
        self.task = task
        self.timeout = timeout
        self.on_end = on_end
        self._to_worker: queue.Queue = queue.Queue()
        self._from_worker: queue.Queue = queue.Queue()
        self._thread: threading.Thread | None = None
        self.worker = worker
        self._started = False
        self._ended = threading.Event()
        self.last: Step | None = None
        self.output: Any = None
        self.error: BaseException | None = None

    # --------------------------------------------------------------------------------------------- agent side
    @property
    def done(self) -> bool:
        return self.last is not None and self.last.done

    def start(self) -> Step:
        if self._started:
            raise EpisodeStateError("the episode has started already")
        self._started = True
        self.runner.agent = _Bridge(self)
        if self.worker is not None:
            self.worker.submit(self._work)
        else:
            self._thread = threading.Thread(target=self._work, name="muble-episode", daemon=True)
            self._thread.start()
        return self._receive()

    def decide(self, decision: Decision, stop: bool = True) -> Step:
        """Hand the loop the next decision (an ``ActionCall``, an ``Answer``, None to stop, or anything the loop
        should judge as an invalid action); returns what follows."""
        if not self._started:
            raise EpisodeStateError("the episode has not started; call start() first")
        if self.done:
            raise EpisodeStateError("the episode has ended; start a new one")
        self._to_worker.put((decision, stop))
        return self._receive()

    def close(self) -> None:
        """Abandon the episode if it is still running and wait for the worker to clean up."""
        if self._started and not self._ended.is_set():
            self._to_worker.put(None)
            if not self._ended.wait(timeout=60.0):
                log.warning("episode worker did not stop within 60 s")

    def _receive(self) -> Step:
        try:
            kind, payload = self._from_worker.get(timeout=self.timeout)
        except queue.Empty:
            self.close()
            raise EpisodeStateError(f"the episode did not answer within {self.timeout:.0f} s; it was abandoned") from None
        if kind == "error":
            self.error = payload
            self.last = Step(self.last.observation if self.last else None, done=True)
            raise payload
        if kind == "done":
            self.output = payload
            result = payload.result
            final = result.steps[-1].observation if result.steps else result.initial
            self.last = Step(final, done=True, output=payload)
            if self.on_end is not None:
                self.on_end(payload)
        else:
            self.last = Step(payload)
        return self.last

    # -------------------------------------------------------------------------------------------- worker side
    def _exchange(self, observation: Observation) -> tuple[Decision, bool]:
        self._from_worker.put(("observe", observation))
        message = self._to_worker.get()
        if message is None:
            raise EpisodeAbandoned()
        return message

    def _work(self) -> None:
        try:
            output = self.runner.execute(self.scene, self.instruction, self.task)
        except EpisodeAbandoned:
            return
        except BaseException as e:  # noqa: BLE001 - handed to the agent side, which raises it there
            self._from_worker.put(("error", e))
            return
        finally:
            self._ended.set()
        self._from_worker.put(("done", output))
