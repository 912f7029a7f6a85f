"""The physical world: primitives executed with MuJoCo physics, keyframes from a renderer after each one."""
from __future__ import annotations

import logging
from typing import Any, Sequence

from muble.core.errors import PlanningError
from muble.core.interfaces import Renderer
from muble.core.types import ActionCall, ActionResult, Frame, Observation

log = logging.getLogger(__name__)


class PhysicalWorld:
    """Executes primitive actions (by registry name) in a ``TabletopEnv`` and renders a keyframe after each.

    A ``PlanningError`` from a primitive is a failed action (the environment is unchanged); a ``PhysicsError``
    propagates and ends the episode as a broken scene.
    """

    def __init__(self, env: Any, registry: Any, renderer: Renderer | None = None,
                 cameras: Sequence[str] = ("front",)):
        self.env = env
        self.registry = registry
        self.renderer = renderer
        self.cameras = tuple(cameras)

    def render(self) -> dict[str, Frame]:
        if self.renderer is None:
            return {}
        return {camera: self.renderer.render(self.env.data, self.env.names.cameras.get(camera, camera))
                for camera in self.cameras}

    def observe(self, result: ActionResult | None, step: int) -> Observation:
        scene = self.env.sync_scene_graph()
        return Observation(scene=scene, images=self.render(), measurements=self.env.observation(),
                           last_result=result, step=step)

    def apply(self, action: ActionCall) -> ActionResult:
        primitive = self.registry.create("primitive", action.name, action.params)
        try:
            return primitive.execute(self.env)
        except PlanningError as e:
            log.info("%s failed to plan: %s", action, e)
            return ActionResult(False, failure_reason=f"planning: {e}")
