"""One SHOP-VRB2 episode from (seed, index): scene, instruction, physical execution, keyframes, sequence file.

``muble run``, ``muble generate`` and ``muble eval`` all go through ``EpisodeRunner`` so an episode is the same
whichever command produced it.
"""
from __future__ import annotations

import copy
import io
import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from muble.core import streams
from muble.core.errors import ConfigError, SceneValidationError
from muble.core.interfaces import Instruction, MotionPlanner, Renderer, Task
from muble.core.scene import SceneGraph
from muble.core.types import Frame
from muble.episode.loop import DEFAULT_MAX_STEPS, EpisodeResult, StepRecord, run_episode
from muble.episode.physical import PhysicalWorld
from muble.episode.sequence import sequence_dict
from muble.generation.ground_truth import apply_masks
from muble.io.atomic import write_bytes_atomic
from muble.io.scene_io import scene_to_dict

log = logging.getLogger(__name__)


def instruction_rng(seed: int, index: int) -> np.random.Generator:
    """The random stream for choosing an instruction (``episode.instruction``), distinct from every scene stream."""
    return streams.stream(streams.INSTRUCTION, seed, index)


class NoInstructionError(ConfigError):
    """The task has no valid instruction for the scene (its objects do not suit the template)."""


def no_instruction(name: str, index: int, seed: int,
                   hint: str = "choose another scene_index or seed, or another task") -> NoInstructionError:
    return NoInstructionError(f"task '{name}' has no valid instruction for scene {index} (seed {seed}); {hint}")


def choose_instruction(task: Task, scene: SceneGraph, seed: int, index: int, name: str | None = None) -> Instruction:
    """The task's first instruction for the scene; ``name`` is the task's registered name, for the error."""
    candidates = task.generate(scene, instruction_rng(seed, index))
    if not candidates:
        raise no_instruction(name or type(task).__name__, index, seed)
    return candidates[0]


# zlib level 1: a third of level 6's time for a file about 13 % larger, the same pixels (docs/rendering.md).
PNG_COMPRESS_LEVEL = 1


def png_bytes(rgb: np.ndarray, compress_level: int = PNG_COMPRESS_LEVEL) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG", optimize=False, compress_level=compress_level)
    return buf.getvalue()


def gif_bytes(frames: list[np.ndarray], seconds_per_frame: float = 0.8) -> bytes:
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:],
                   duration=int(seconds_per_frame * 1000), loop=0)
    return buf.getvalue()


@dataclass
class Timing:
    """Wall time of an episode split into physics (with primitives' planning inside), planning and rendering."""

    physics: float = 0.0
    planning: float = 0.0
    rendering: float = 0.0
    total: float = 0.0


@dataclass
class EpisodeOutput:
    """An executed episode and everything that gets written for it."""

    scene: SceneGraph
    instruction: Instruction
    result: EpisodeResult
    keyframes: list[np.ndarray] = field(default_factory=list)
    sequence: dict[str, Any] = field(default_factory=dict)
    timing: Timing = field(default_factory=Timing)
    # What the disturbances did (``DisturbanceEvent.to_dict``) and how many were planned: the record's alone.
    disturbances: list[dict[str, Any]] = field(default_factory=list)
    disturbances_planned: int = 0
    # The world at the start and after every primitive (muble.episode.fingerprint), for muble verify.
    fingerprints: list[dict[str, Any]] = field(default_factory=list)


class _TimedRenderer(Renderer):
    """Wraps a renderer to count its time (rendering is reported apart from physics)."""

    def __init__(self, inner: Renderer, timing: Timing):
        self.inner, self.timing = inner, timing

    def setup(self, scene, model):
        t = time.perf_counter()
        self.inner.setup(scene, model)
        self.timing.rendering += time.perf_counter() - t

    def render(self, data, camera) -> Frame:
        t = time.perf_counter()
        frame = self.inner.render(data, camera)
        self.timing.rendering += time.perf_counter() - t
        return frame


class _TimedPlanner(MotionPlanner):
    """Wraps a motion planner to count planning time (a MotionPlanner itself, so primitives accept it as the
    environment's configured planner)."""

    def __init__(self, inner, timing: Timing):
        self.inner, self.timing = inner, timing

    def plan(self, start_q, goal, world):
        t = time.perf_counter()
        try:
            return self.inner.plan(start_q, goal, world)
        finally:
            self.timing.planning += time.perf_counter() - t

    def __getattr__(self, name):
        return getattr(self.inner, name)


class KeyframeStateRecorder(Renderer):
    """Wraps the episode's renderer and keeps MuJoCo's ``qpos`` at every keyframe (each keyframe renders every
    configured camera in turn, so one state is kept per ``cameras`` calls): what ``muble render --keyframes``
    needs to draw the keyframes again with another renderer."""

    def __init__(self, inner: Renderer, cameras: int):
        self.inner, self.cameras = inner, max(1, cameras)
        self.states: list[np.ndarray] = []
        self._calls = 0

    def setup(self, scene: Any, model: Any) -> None:
        self.states, self._calls = [], 0
        self.inner.setup(scene, model)

    def render(self, data: Any, camera: str):
        if self._calls % self.cameras == 0:
            self.states.append(np.array(data.qpos, dtype=np.float64))
        self._calls += 1
        return self.inner.render(data, camera)

    def close(self) -> None:
        self.inner.close()

    def keyframe_states(self, output: "EpisodeOutput", robot: str, object_set: str, camera: str):
        """The recorded states as a ``KeyframeStates`` (one per keyframe of ``output``), or ``None`` with a
        warning when they do not match the keyframes one to one."""
        from muble.io.keyframe_states import KeyframeStates

        if not self.states or len(self.states) != len(output.keyframes):
            log.warning("keyframe states not written: %d states for %d keyframes", len(self.states),
                        len(output.keyframes))
            return None
        return KeyframeStates(np.stack(self.states), robot=robot, object_set=object_set, camera=camera)


@dataclass(eq=False)
class EpisodeRunner:
    """Executes instructions on scenes with the configured robot, planner, agent, sensors and renderer."""

    registry: Any
    robot: Any
    planner: Any
    agent: Any
    object_set: Any
    object_set_name: str
    sensors: dict[str, Any]
    renderer: Renderer | None
    cameras: tuple[str, ...] = ("front",)
    max_steps: int = DEFAULT_MAX_STEPS
    track: str = "program"  # what the agent is told (muble.episode.modes)
    mode: str = "graph"
    # Registry name -> disturbance (``muble.core.disturbances``), each drawing from its own stream for
    # (``seed``, the episode's key).
    disturbances: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    disturbances_per_episode: tuple[int, ...] = ()  # (low, high): how many of those that apply act; () all
    # The wrist sensor's error (``muble.sim.sensor_noise.WristNoise`` or a mapping of its fields; None: perfect),
    # drawn from its own stream for (``seed``, the episode's key).
    noise: Any = None
    decision_timeout: float = 0.0  # s one call of the agent's reset or act may take (0: no limit; run_episode)
    step_log_level: int = logging.INFO  # the per-primitive log line's level (muble eval: DEBUG, under --verbose)

    def _disturbances(self, scene: SceneGraph, instruction: Instruction, key: int) -> list[Any]:
        """The disturbances that act in this episode, each reset on its own stream: those that apply to the
        instruction, all of them or, with ``disturbances_per_episode``, a number of them drawn from
        ``episode.disturbance_mix``."""
        # By name: the draw must not depend on the order a config lists them in (a JSON round trip sorts it).
        applicable = [name for name, d in sorted(self.disturbances.items()) if d.applies(instruction)]
        if self.disturbances_per_episode and applicable:
            low, high = (list(self.disturbances_per_episode) * 2)[:2]
            rng = streams.stream(streams.DISTURBANCE_MIX, self.seed, key)
            count = int(rng.integers(min(low, len(applicable)), min(high, len(applicable)) + 1))
            chosen = set(rng.choice(len(applicable), size=count, replace=False).tolist())
            applicable = [name for i, name in enumerate(applicable) if i in chosen]
        out = []
        for name in applicable:
            disturbance = self.disturbances[name]
            disturbance.kind = name
            disturbance.reset(streams.disturbance_stream(name, self.seed, key), copy.deepcopy(scene))
            out.append(disturbance)
        return out

    def execute(self, scene: SceneGraph, instruction: Instruction, task: Task,
                key: int | None = None) -> EpisodeOutput:
        """Run ``instruction`` on ``scene``; ``key`` (default: the scene's index) keys the disturbances' and the
        sensor noise's streams."""
        from muble.core.errors import InitialStateError
        from muble.core.types import Outcome
        from muble.sim.build import object_models
        from muble.sim.env import TabletopEnv
        from muble.sim.initial_state import settle_and_check

        timing = Timing()
        start = time.perf_counter()
        hidden = getattr(self.object_set, "hidden_properties", ())
        # A scene the object set or MuJoCo's compiler refuses is the data's fault, whatever the builder raised.
        try:
            models = object_models(scene, self.object_set, self.object_set_name)
        except SceneValidationError:
            raise
        except (ConfigError, KeyError, TypeError, ValueError) as e:
            raise SceneValidationError(f"object set '{self.object_set_name}' cannot build the scene's objects: "
                                       f"{type(e).__name__}: {e}") from e
        try:
            env = TabletopEnv(scene, models, self.robot, self.sensors, noise=self.noise,
                              noise_stream=(self.seed, scene.image_index if key is None else key))
        except SceneValidationError:
            raise
        except ValueError as e:
            raise SceneValidationError(f"MuJoCo cannot compile the scene (element objN is the object with id N: check "
                                       f"its weight_gt, size and scale_factor): {e}") from e
        try:
            try:  # the scene must start at rest; if it does not, it is broken and the agent never acts
                settle_and_check(env)
            except InitialStateError as e:
                log.warning("broken scene: %s", e)
                world = PhysicalWorld(env, self.registry, None, self.cameras, hidden=hidden)
                initial = world.observe(None, 0)
                result = EpisodeResult(Outcome.BROKEN_SCENE, [], None, world.ground_truth(), initial=initial,
                                       error=str(e), initial_gt=world.ground_truth())
                return EpisodeOutput(scene, instruction, result, timing=timing)
            env.planner = _TimedPlanner(self.planner, timing)
            renderer = _TimedRenderer(self.renderer, timing) if self.renderer is not None else None
            if renderer is not None:
                renderer.setup(env.sync_scene_graph(), env.model)
            disturbances = self._disturbances(env.sync_scene_graph(), instruction,
                                              scene.image_index if key is None else key)
            world = PhysicalWorld(env, self.registry, renderer, self.cameras, hidden=hidden,
                                  disturbances=disturbances)
            keyframes: list[np.ndarray] = []

            def keep(step: StepRecord) -> None:
                frame = step.observation.images.get(self.cameras[0])
                if frame is not None:
                    keyframes.append(frame.rgb)
                log.log(self.step_log_level, "step %d: %s -> %s", step.observation.step, step.action,
                        "ok" if step.result.success else step.result.failure_reason)

            result = run_episode(instruction, world, self.agent, task, max_steps=self.max_steps, on_step=keep,
                                 track=self.track, mode=self.mode, decision_timeout=self.decision_timeout)
            first = result.initial.images.get(self.cameras[0]) if result.initial is not None else None
            if first is not None:
                keyframes.insert(0, first.rgb)
                if first.segmentation is not None:
                    # The scene file's masks as the camera sees the scene: robot and its occlusion included.
                    scene = copy.deepcopy(scene)
                    apply_masks(scene, first.segmentation)
        finally:
            env.close()
            if self.renderer is not None:
                self.renderer.close()
        timing.total = time.perf_counter() - start
        timing.physics = timing.total - timing.planning - timing.rendering
        return EpisodeOutput(scene, instruction, result, keyframes, timing=timing,
                             disturbances=[e.to_dict() for e in world.events],
                             disturbances_planned=sum(bool(d.planned) for d in disturbances),
                             fingerprints=world.fingerprints)


def write_episode(output: EpisodeOutput, directory: Path, stem: str, gif: bool = True,
                  action_names: str = "registry", states: Any = None) -> dict[str, str]:
    """Write keyframes, GIF and sequence file atomically; returns {relative path: sha256}.

    ``action_names``: ``registry`` or ``original`` primitive names in the sequence file. ``states``: the
    keyframes' MuJoCo states (``muble.io.keyframe_states.KeyframeStates``), written as
    ``keyframes/<stem>_states.npz`` for ``muble render --keyframes``."""
    written: dict[str, str] = {}
    paths = []
    for i, rgb in enumerate(output.keyframes):
        rel = f"keyframes/{stem}/frame_{i:04d}.png"
        written[rel] = write_bytes_atomic(directory / rel, png_bytes(rgb))
        paths.append(rel)
    if gif and output.keyframes:
        rel = f"keyframes/{stem}.gif"
        written[rel] = write_bytes_atomic(directory / rel, gif_bytes(output.keyframes))
    if states is not None:
        from muble.io.keyframe_states import keyframe_states_bytes

        rel = f"keyframes/{stem}_states.npz"
        written[rel] = write_bytes_atomic(directory / rel, keyframe_states_bytes(states))
    output.sequence = sequence_dict(output.instruction, output.result, paths, action_names=action_names)
    rel = f"sequences/{stem}.json"
    written[rel] = write_bytes_atomic(directory / rel, json.dumps(output.sequence).encode())
    rel = f"scenes/{stem}.json"
    written[rel] = write_bytes_atomic(directory / rel, json.dumps(scene_to_dict(output.scene)).encode())
    return written
