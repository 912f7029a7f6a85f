"""``MuBlE/ShopVRB2-v0``: one SHOP-VRB2 episode per reset; actions are primitive calls, given as JSON text.

Why JSON text for actions: a primitive call is a name and a handful of typed parameters whose kinds differ per
primitive (an object id, a table part, numbers, vectors) and whose set grows with every primitive plugin. A
``Dict``/``OneOf`` space would have to enumerate them all and would still not say which ids exist in this scene;
language-model and VLA agents produce text anyway. The action is the same JSON object the remote protocol's
``act`` message carries, and the action loop checks it exactly as for an in-process agent:

    {"name": "approach", "params": {"target": 3}}      a primitive call
    {"answer": {"3": 234.5}}                           an answer (ends the episode; add "stop": false to go on)
    {"stop": true}                                     done: the episode is judged

Text that is not one of these shapes is an invalid action (the episode ends as ``invalid_action``), as is a call
no primitive accepts. Observations are a ``Dict``: the instruction text, the camera images, the agent-side scene
graph, the measurements and the last primitive's result as JSON text, and the step count. Reward is 1 at the end
of a successful episode, else 0; the loop's time limit (``episode.max_steps``) truncates.
"""
from __future__ import annotations

import copy
import json
import logging
from typing import Any, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from muble.core.errors import ConfigError, PhysicsError, SceneGenerationError, SceneValidationError
from muble.core.types import Outcome
from muble.dataset.shipped import check_plays_alone, episodes_root
from muble.episode.plain import MalformedDecision, decision_from_plain, observation_to_plain, plain
from muble.episode.components import benchmark_settings, image_size
from muble.episode.modes import track_instruction
from muble.episode.sources import EPISODE_FORMS, EpisodeFactory, EpisodeSpec, episode_kind
from muble.episode.stepped import EpisodeStateError, EpisodeThread, Step, SteppedEpisode
from muble.gym.config import environment_config, generation_size
from muble.gym.spaces import as_text, image_space, json_text, text_space
from muble.io.instructions_io import instruction_to_dict

log = logging.getLogger(__name__)

MAX_INSTRUCTION = 1024
MAX_ACTION = 4096
MAX_TEXT = 1 << 20  # the scene's JSON (with its masks) stays far below this
SCENE_TRIES = 50  # scene indices tried for one that the template mix and the physics accept
DEFAULT_OVERRIDES = ("renderer.width=320", "renderer.height=240")


class MalformedAction:
    """Action text that is not a decision: handed to the action loop, which judges it an invalid action."""

    def __init__(self, text: str, reason: str):
        self.text, self.reason = text, reason

    def __repr__(self) -> str:
        return f"{self.text!r:.60} ({self.reason})"


def parse_action(action: Any) -> tuple[Any, bool]:
    """(decision, stop) from action text; a ``MalformedAction`` if it is not one."""
    if not isinstance(action, str):
        return MalformedAction(repr(action)[:60], f"an action is JSON text, got {type(action).__name__}"), True
    try:
        return decision_from_plain(json.loads(action))
    except json.JSONDecodeError as e:
        return MalformedAction(action, f"not JSON: {e}"), True
    except MalformedDecision as e:
        return MalformedAction(action, str(e)), True


class ShopVRB2Env(gym.Env):
    """A SHOP-VRB2 episode through the same action loop as ``muble run``/``muble eval`` (``run_episode``).

    Configure with ``config`` (a Hydra-composed MuBlE config) and/or ``overrides`` (``["renderer.width=640",
    "robot=UR5e", "episode.max_steps=60"]``); ``templates`` and ``template_weights`` choose the instruction mix
    (default: the configured one, ``dataset.templates`` and ``dataset.template_weights``, read as ``muble generate``
    reads them; named templates without weights get equal shares); ``render=False`` leaves the images out (faster, no GL).

    ``reset(seed=s)`` draws the scene index from the seeded generator (same seed, same scene and instruction);
    ``reset(options=...)`` picks an episode: ``{"scene_index": i, "template": t}`` (a generated scene; with
    ``split=NAME`` among the overrides, ``{"scene_index": i}`` is index ``i`` of that split as ``muble generate``
    makes it, its template the split's),
    ``{"split": "val", "index": i}`` (a stored dataset episode under ``dataset.root``) or ``{"scene": {...},
    "instruction": {...}}`` (SHOP-VRB2 JSON data). ``info["instruction"]`` holds the instruction record an
    in-process agent receives (its program included, the stored ground-truth actions left out), ``info["track"]``
    and ``info["mode"]`` what the agent is told (``benchmark.track``, ``benchmark.mode``).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 2}

    def __init__(self, config: Any = None, overrides: Sequence[str] = (), templates: Sequence[str] | None = None,
                 template_weights: Sequence[float] | None = None, render: bool = True,
                 render_mode: str | None = None, max_text: int = MAX_TEXT):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"unknown render_mode {render_mode!r}; valid: {self.metadata['render_modes']}")
        if render_mode is not None and not render:
            raise ConfigError("render_mode='rgb_array' needs render=True (the images are what it shows)")
        self.cfg = environment_config(config, overrides, DEFAULT_OVERRIDES)
        # With split=NAME its scenes are made at the image size muble generate made them at, not at this one's.
        split_size = generation_size(config, overrides) if self.cfg.get("split") is not None else None
        self.factory = EpisodeFactory(self.cfg, render=render, split_size=split_size)
        if self.factory.split is not None and (templates is not None or template_weights is not None):
            raise ConfigError(f"with split={self.factory.split} an index's template is the one the split's "
                              "template mix gives it: pass no templates or template_weights, or set split=null")
        self.templates = list(templates) if templates else self.factory.mix
        for t in self.templates:
            self.factory.task(t)  # an unknown template fails here, listing the valid ones
        self.template_weights = list(template_weights) if template_weights else None
        self.mix_named = templates is not None or template_weights is not None
        self.render_mode = render_mode
        self.max_text = int(max_text)
        self.cameras = [str(c) for c in self.cfg.episode.cameras]
        entries: dict[str, spaces.Space] = {
            "instruction": text_space(MAX_INSTRUCTION),
            "scene": text_space(self.max_text),
            "measurements": text_space(self.max_text),
            "last_result": text_space(self.max_text),
            "step": spaces.Box(0, np.iinfo(np.int32).max, shape=(), dtype=np.int64),
        }
        self._image_spaces: dict[str, spaces.Box] = {}  # the observation space's images, by camera
        if render:
            width, height = image_size(self.cfg)
            self._image_spaces = {c: image_space(height, width) for c in self.cameras}
            entries["images"] = spaces.Dict(dict(self._image_spaces))
        self.observation_space = spaces.Dict(entries)
        self.action_space = text_space(MAX_ACTION)
        self.render_images = render
        self.episode: SteppedEpisode | None = None
        self.spec_now: EpisodeSpec | None = None
        self._last: Step | None = None
        self._scenes: dict[tuple, Any] = {}  # generated episodes by (index, templates): resets repeat them cheaply
        self._worker = EpisodeThread()

    # ----------------------------------------------------------------------------------------------- episode
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self._end_episode()
        spec: EpisodeSpec | None
        step: Step | None
        if options:
            spec = self._chosen(options)
            step = self._start(spec)
            if step.done:
                raise PhysicsError(f"the chosen episode {spec.source} does not start: {step.output.result.error}")
        else:
            step, spec = None, None
            for _ in range(SCENE_TRIES):
                index = int(self.np_random.integers(0, 2**31 - 1))
                try:
                    spec = self._generated(index, self.templates)
                except SceneGenerationError as e:  # with split=NAME: no scene of the index suits its template
                    log.info("scene %d: %s; drawing another", index, e)
                    continue
                if spec is None:
                    continue
                step = self._start(spec)
                if not step.done:
                    break
                log.info("scene %d does not start (%s); drawing another", index, step.output.result.error)
            else:
                raise ConfigError(f"no episode of templates {self.templates} starts in {SCENE_TRIES} drawn scenes")
            if step is None or spec is None:  # the loop above breaks only with an episode started
                raise RuntimeError("no episode was started, yet none of the drawn scenes was rejected")
        self.spec_now = spec
        track, mode = benchmark_settings(self.cfg)
        told = track_instruction(spec.instruction, track)
        info = {"instruction": instruction_to_dict(told), "source": spec.source,
                "template": spec.instruction.template_id, "track": track, "mode": mode}
        return self._observation(step), info

    def step(self, action: Any):
        if self.episode is None or self.episode.done:
            raise EpisodeStateError("the episode has ended (or none has started); call reset()")
        decision, stop = parse_action(action)
        step = self.episode.decide(decision, stop)
        info: dict[str, Any] = {"outcome": None}
        if isinstance(decision, MalformedAction):
            info["malformed_action"] = decision.reason
        reward, terminated, truncated = 0.0, False, False
        if step.done:
            result = step.output.result
            info.update(outcome=result.outcome.value, error=result.error,
                        answer=None if result.answer is None else plain(result.answer.value),
                        actions=[str(a) for a in result.actions])
            reward = 1.0 if result.outcome is Outcome.SUCCESS else 0.0
            truncated = result.outcome is Outcome.TIMEOUT
            terminated = not truncated
        return self._observation(step), reward, terminated, truncated, info

    def render(self):
        if self.render_mode != "rgb_array" or self._last is None or self._last.observation is None:
            return None
        frame = self._last.observation.images.get(self.cameras[0])
        return None if frame is None else frame.rgb.copy()

    def close(self) -> None:
        self._end_episode()
        try:
            self._worker.call(self.factory.close_renderer)  # where its GL context is current
        finally:
            self._worker.close()
            self.factory.close()

    # -------------------------------------------------------------------------------------------- internals
    def _chosen(self, options: dict[str, Any]) -> EpisodeSpec:
        kind = episode_kind(options)
        if kind == "generated":
            templates = [options["template"]] if "template" in options else self.templates
            spec = self._generated(int(options["scene_index"]), templates)
            if spec is None:
                raise ConfigError(f"no instruction of {templates} applies to scene {options['scene_index']} "
                                  f"(seed {self.cfg.seed}); choose another scene_index or template")
            return spec
        if kind == "stored":  # with protocol=NAME, a split of it that ships needs no dataset.root
            split = options["split"]
            check_plays_alone(self.cfg, split, "the Gymnasium environment")
            root = episodes_root(self.cfg, split) if isinstance(split, str) else None
            return self.factory.stored(split, options["index"], root)
        if kind == "data":
            return self.factory.from_data(options["scene"], options["instruction"])
        raise ConfigError(f"reset options {sorted(map(str, options))[:6]} name no episode; give {EPISODE_FORMS}")

    def _generated(self, index: int, templates: Sequence[str]) -> EpisodeSpec | None:
        key = (index, tuple(templates), tuple(self.template_weights or ()))
        if key not in self._scenes:
            if len(self._scenes) >= 8:
                self._scenes.pop(next(iter(self._scenes)))
            configured = not self.mix_named and list(templates) == self.templates
            self._scenes[key] = (self.factory.generated(index) if configured
                                 else self.factory.generated(index, templates, self.template_weights))
        return copy.deepcopy(self._scenes[key])

    def _start(self, spec: EpisodeSpec) -> Step:
        self._end_episode()
        # Every episode on the one worker thread, with the one renderer: its GL context, compiled shaders and
        # uploaded meshes serve every reset after the first.
        self.episode = SteppedEpisode(self.factory.runner(keep_renderer=True), spec.scene, spec.instruction,
                                      spec.task, worker=self._worker)
        try:
            return self.episode.start()
        except SceneValidationError:
            self.episode = None
            raise

    def _end_episode(self) -> None:
        if self.episode is not None:
            self.episode.close()
            self.episode = None
        self._last = None

    def _observation(self, step: Step) -> dict[str, Any]:
        self._last = step
        observation = step.observation
        if observation is None:
            raise EpisodeStateError("the episode ended without an observation to give; call reset()")
        data = observation_to_plain(observation)
        if self.episode is None:
            raise EpisodeStateError("the episode has ended (or none has started); call reset()")
        obs: dict[str, Any] = {
            "instruction": as_text(self.episode.instruction.instruction, MAX_INSTRUCTION, "the instruction"),
            "scene": json_text(data["scene"], self.max_text, "the scene"),
            "measurements": json_text(data["measurements"], self.max_text, "the measurements"),
            "last_result": json_text(data["last_result"], self.max_text, "the last result"),
            "step": np.array(data["step"], dtype=np.int64),
        }
        if self.render_images:
            obs["images"] = {}
            for camera in self.cameras:
                frame = observation.images.get(camera)
                obs["images"][camera] = (frame.rgb.copy() if frame is not None
                                         else np.zeros(self._image_spaces[camera].shape, dtype=np.uint8))
        return obs
