"""``MuBlE/Tabletop-v0``: continuous end-effector control of the arm with its gripper on a SHOP-VRB2 tabletop.

Action: ``Box(-1, 1, (7,))`` = (dx, dy, dz, rx, ry, rz, gripper) of the ``IK_JOINT_SERVO`` controller, one control
step (``robot.control_freq``) per ``step``; the pose part is scaled to at most 5 cm / 0.5 rad, gripper -1 opens and
1 closes (``TabletopEnv.step``). Observation: a camera image (``image``, the configured renderer at the configured
size; left out with ``render=False``) and the proprioception (end-effector pose, joint positions and velocities,
gripper command and opening, a held flag). The environment has no reward of its own (0): wrap it with the reward of the skill being learned. A
physics fault ends the episode (``terminated``, ``info["outcome"] == "broken_scene"``); the registered id truncates
after 400 steps.
"""
from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from muble.core.errors import ConfigError, InitialStateError, SceneGenerationError, SceneValidationError
from muble.gym.config import environment_config, generation_size
from muble.gym.spaces import image_space
from muble.sim.spaces import control_space, proprioception, proprioception_space

if TYPE_CHECKING:  # pragma: no cover
    from muble.sim.env import TabletopEnv

log = logging.getLogger(__name__)

SCENE_TRIES = 20
# Small RGB images drawn for speed: on a software rasteriser robosuite's shadow-casting lights and the robot's
# ~170k visual triangles cost ~0.9 s a frame as a keyframe is drawn. Without shadows, floor reflection and
# multisampling, and with the robot's meshes drawn from decimated copies within 5 mm of the modelled surface (under
# a third of a pixel of a 128x128 view of the table), the masks stay within IoU 0.98 of the detailed meshes'
# (benchmarks/gym_speed.py measures both).
DEFAULT_OVERRIDES = ("renderer.width=128", "renderer.height=128", "renderer.depth=false",
                     "renderer.segmentation=false")
FAST_MUJOCO_OVERRIDES = ("renderer.shadows=false", "renderer.reflection=false", "renderer.multisamples=0",
                         "renderer.mesh_tolerance=0.005")


def default_overrides(overrides: Sequence[str]) -> tuple[str, ...]:
    """The environment's defaults under ``overrides``: the fast MuJoCo settings unless another renderer is chosen."""
    chosen = [o.split("=", 1)[1] for o in overrides if o.split("=", 1)[0].lstrip("+~") == "renderer" and "=" in o]
    return DEFAULT_OVERRIDES + (FAST_MUJOCO_OVERRIDES if chosen in ([], ["mujoco"]) else ())


def arm_dof(robot: str) -> int:
    """Joints of a robosuite arm, read from its model (no world is built)."""
    from robosuite.models.robots import create_robot

    return len(create_robot(robot, idn=0).joints)


class TabletopGymEnv(gym.Env):
    """A generated SHOP-VRB2 scene per reset under end-effector control.

    Configure with ``config`` (a Hydra-composed MuBlE config) and/or ``overrides`` (``["robot=UR5e",
    "renderer.width=224", "renderer.height=224"]``); ``camera`` picks the view. ``reset(seed=s)`` draws the scene
    index from the seeded generator (same seed, same scene); ``reset(options={"scene_index": i})`` or
    ``{"scene": {...}}`` (SHOP-VRB2 JSON data) chooses it. With ``split=NAME`` among the overrides, scene ``i`` is
    the scene of index ``i`` of that split as ``muble generate`` makes it. ``render=False`` leaves the image out of
    the observation (proprioception only; no renderer and no GL context are made).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, config: Any = None, overrides: Sequence[str] = (), camera: str = "front",
                 render_mode: str | None = None, render: bool = True):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"unknown render_mode {render_mode!r}; valid: {self.metadata['render_modes']}")
        if render_mode is not None and not render:
            raise ConfigError("render_mode='rgb_array' needs render=True (the image is what it shows)")
        from omegaconf import OmegaConf

        from muble.episode.components import build_components, image_size, scene_generator
        from muble.plugins.registry import get_registry

        self.cfg = environment_config(config, overrides, default_overrides(overrides))
        # With split=NAME its scenes are made at the image size muble generate made them at, not at this one's.
        self.split_size = generation_size(config, overrides) if self.cfg.get("split") is not None else None
        self.render_mode = render_mode
        self.camera = camera
        robot = OmegaConf.to_container(self.cfg.robot, resolve=True)
        if not isinstance(robot, dict):
            raise ConfigError(f"the robot config is a mapping of settings, not {robot!r}")
        self.robot = robot
        self.render_images = bool(render)
        self.components = build_components(self.cfg, renderer=self.render_images, task=False)
        self.registry = get_registry()
        self.generator = scene_generator(self.cfg, self.components["object_set"])
        self.metadata = {**self.metadata, "render_fps": float(self.cfg.robot.control_freq)}
        width, height = image_size(self.cfg)
        image = {"image": image_space(height, width)} if self.render_images else {}
        self.observation_space = spaces.Dict({**image, **proprioception_space(arm_dof(self.robot["name"])).spaces})
        self.action_space = control_space()
        self.env: TabletopEnv | None = None
        self._image: np.ndarray | None = None
        self._scenes: dict[int, Any] = {}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self._close_env()
        options = dict(options or {})
        unknown = sorted(set(options) - {"scene_index", "scene"})
        if unknown:
            raise ConfigError(f"unknown reset option(s) {unknown}; valid: scene_index, scene")
        if "scene" in options:
            from muble.io.scene_io import scene_from_dict

            scene = scene_from_dict(options["scene"])
            self._build(scene)
            index = None
        else:
            fixed = options.get("scene_index")
            for _ in range(1 if fixed is not None else SCENE_TRIES):
                index = int(fixed) if fixed is not None else int(self.np_random.integers(0, 2**31 - 1))
                try:
                    self._build(self._scene(index))
                    break
                except (InitialStateError, SceneGenerationError) as e:
                    if fixed is not None:
                        raise
                    log.info("scene %d cannot be used (%s); drawing another", index, e)
            else:
                raise ConfigError(f"none of {SCENE_TRIES} drawn scenes starts at rest")
        return self._observation(), {"scene_index": index, "objects": len(self._live_env().scene.objects)}

    def step(self, action):
        env = self._live_env()
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        _, _, terminated, truncated, info = env.step(action)
        info = {"outcome": None if info.get("outcome") is None else info["outcome"].value,
                **({"error": info["error"]} if "error" in info else {})}
        return self._observation(), 0.0, bool(terminated), bool(truncated), info

    def render(self):
        if self.render_mode != "rgb_array" or self._image is None:
            return None
        return self._image.copy()

    def close(self) -> None:
        self._close_env()
        renderer = self.components.get("renderer")
        if renderer is not None:
            renderer.close()
        if self.generator is not None:
            self.generator.close()
            self.generator = None

    # -------------------------------------------------------------------------------------------- internals
    def _live_env(self) -> TabletopEnv:
        if self.env is None:
            raise ConfigError("call reset() before step()")
        return self.env

    def _scene(self, index: int):
        import copy

        if index not in self._scenes:
            if len(self._scenes) >= 8:
                self._scenes.pop(next(iter(self._scenes)))
            if self.cfg.get("split") is None:
                self._scenes[index] = self.generator.generate(index)
            else:  # index ``index`` of the split as muble generate makes it (its template's suited scene)
                from muble.episode.components import split_episode

                self._scenes[index] = split_episode(self.cfg, str(self.cfg.split), index,
                                                    self.components["object_set"], size=self.split_size).scene
        return copy.deepcopy(self._scenes[index])

    def _build(self, scene) -> None:
        from muble.sim.build import object_models
        from muble.sim.env import TabletopEnv
        from muble.sim.initial_state import settle_and_check

        try:
            models = object_models(scene, self.components["object_set"], self.cfg.objects.name)
            env = TabletopEnv(scene, models, self.robot, self.components["sensors"])
        except (KeyError, TypeError, ValueError) as e:
            raise SceneValidationError(f"the scene cannot be built: {type(e).__name__}: {e}") from e
        try:
            settle_and_check(env)
        except InitialStateError:
            env.close()
            raise
        self.env = env
        if self.render_images:
            self.components["renderer"].setup(env.sync_scene_graph(), env.model)

    def _observation(self) -> dict[str, Any]:
        env = self._live_env()
        if not self.render_images:
            return proprioception(env)
        camera = env.names.cameras.get(self.camera, self.camera)
        self._image = self.components["renderer"].render(env.data, camera).rgb
        return {"image": self._image.copy(), **proprioception(env)}

    def _close_env(self) -> None:
        if self.env is not None:
            self.env.close()
            self.env = None
        self._image = None
