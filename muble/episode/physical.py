"""The physical world: primitives executed with MuJoCo physics, keyframes from a renderer after each one.

Besides poses, the observed scene graph carries the gripper flags of the symbolic world, so an agent plans the
same way in both: ``in_hand`` (welded to the hand), ``raised`` (held and touching neither the table nor another
object, read from the contacts), ``approached`` (the hand is in the grasp pose of that object: the last
primitive succeeded and declares ``PrimitiveAction.hand_at_target = "grasp"``) and ``gripper_over`` (the hand
hovers over that object: a successful primitive that declares ``"over"`` for it, or the object just let go of,
which the hand retreats straight up from).
"""
from __future__ import annotations

import logging
from typing import Any, Sequence

from muble.core.errors import PlanningError
from muble.core.interfaces import Disturbance, DisturbanceEvent, Renderer
from muble.core.observation import agent_view
from muble.core.scene import SceneGraph
from muble.core.types import ActionCall, ActionResult, Frame, Observation
from muble.episode.fingerprint import fingerprint
from muble.sim.sync import is_lifted

log = logging.getLogger(__name__)


class PhysicalWorld:
    """Executes primitive actions (by registry name) in a ``TabletopEnv`` and renders a keyframe after each.

    A ``PlanningError`` from a primitive is a failed action (the environment is unchanged); a ``PhysicsError``
    propagates and ends the episode as a broken scene. Agents observe the scene through ``agent_view`` (the
    weights and stiffnesses measured in this episode, no ground truth); ``hidden`` names further properties the
    object set withholds.
    """

    def __init__(self, env: Any, registry: Any, renderer: Renderer | None = None,
                 cameras: Sequence[str] = ("front",), hidden: Sequence[str] = (),
                 disturbances: Sequence[Disturbance] = ()):
        self.env = env
        self.disturbances = tuple(disturbances)
        self.events: list[DisturbanceEvent] = []  # what the disturbances did (the record's, never the agent's)
        self.steps = 0
        # The world at the start and after every primitive (muble.episode.fingerprint): the record's alone.
        self.fingerprints: list[dict] = [fingerprint(env)]
        self.registry = registry
        self.renderer = renderer
        self.cameras = tuple(cameras)
        self.hidden = tuple(hidden)
        self.scene_gt: SceneGraph | None = None
        self.approached: int | None = None  # object the open hand is in the grasp pose of
        self.over: int | None = None  # object the hand hovers over

    def render(self) -> dict[str, Frame]:
        if self.renderer is None:
            return {}
        return {camera: self.renderer.render(self.env.data, self.env.names.cameras.get(camera, camera))
                for camera in self.cameras}

    def observe(self, result: ActionResult | None, step: int) -> Observation:
        scene = self.env.sync_scene_graph()
        self._flag(scene)
        self.scene_gt = scene
        return Observation(scene=agent_view(scene, self.env.measurements, self.hidden), images=self.render(),
                           measurements=self.env.observation(), last_result=result, step=step)

    def ground_truth(self) -> SceneGraph:
        if self.scene_gt is None:
            self.scene_gt = self.env.sync_scene_graph()
            self._flag(self.scene_gt)
        return self.scene_gt

    def apply(self, action: ActionCall) -> ActionResult:
        primitive = self.registry.create("primitive", action.name, action.params)
        held = self.env.held_object
        self.steps += 1
        step = self.steps
        for d in self.disturbances:
            self._fired(d.before(self.env, action, step))
        listeners = [self._listener(d) for d in self.disturbances
                     if type(d).on_control is not Disturbance.on_control]
        self.env.control_listeners.extend(listeners)
        try:
            result = primitive.execute(self.env)
        except PlanningError as e:
            log.info("%s failed to plan: %s", action, e)
            result = ActionResult(False, failure_reason=f"planning: {e}")
        finally:
            for listener in listeners:
                self.env.control_listeners.remove(listener)
        if result.success:
            self._track(action, getattr(primitive, "hand_at_target", None), held)
        for d in self.disturbances:
            result, event = d.after(self.env, action, result, step)
            self._fired(event)
        self.fingerprints.append(fingerprint(self.env))
        return result

    def _listener(self, disturbance: Disturbance):
        def listen(env: Any) -> None:
            self._fired(disturbance.on_control(env))
        return listen

    def _fired(self, event: DisturbanceEvent | None) -> bool:
        if event is None:
            return False
        log.debug("disturbance: %s", event)
        self.events.append(event)
        if event.object is not None and event.object in (self.over, self.approached):
            self.approached = self.over = None  # the hand is no longer over or at the object that was moved
        return True

    def _track(self, action: ActionCall, hand_at: str | None, held_before: int | None) -> None:
        """Where the hand is, symbolically, after a successful primitive."""
        target = action.params.get("target")
        obj = int(target) if isinstance(target, int) or (isinstance(target, str) and target.isdigit()) else None
        released = held_before is not None and self.env.held_object is None
        if hand_at == "over":
            self.approached, self.over = None, obj
        elif hand_at == "grasp":
            self.approached, self.over = obj, None
        elif released:  # set down or let go of: the hand rises straight up from it
            self.approached, self.over = None, held_before
        elif self.env.held_object != held_before:  # grasped something (or lost it)
            self.approached, self.over = None, None
        else:
            self.approached = None if self.env.held_object is not None else self.approached

    def _flag(self, scene: SceneGraph) -> None:
        held = self.env.held_object
        raised = held is not None and is_lifted(self.env, held)
        for o in scene.objects:
            o.extra["in_hand"] = o.id == held
            o.extra["raised"] = o.id == held and raised
            o.extra["approached"] = held is None and o.id == self.approached
            o.extra["gripper_over"] = o.id == self.over

