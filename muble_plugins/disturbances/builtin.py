"""The built-in disturbances: a grip that loosens while lifting, an object bumped across the table, a reading that
fails once. Each acts through MuJoCo (the gripper's actuators, a force on the object) and never writes a pose."""
from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass

import mujoco
import numpy as np

from muble import ActionCall, ActionResult, Disturbance, DisturbanceEvent, bounded, get_registry
from muble.stage.rest import at_rest
from muble.stage.free_place import free_mask, free_places
from muble.stage.table import part_box, parts_at
from muble_plugins.primitives.placement import footprint, obstacles

logger = logging.getLogger(__name__)

G = 9.81


def _steps(instruction) -> set[str]:
    return {str(step.get("type")) for step in instruction.program}


# Program steps that have the robot pick an object up (and so lift it): moving, stacking, picking up, and every
# step that compares or asks for a hidden property, which is measured in the hand.
HANDLING_STEPS = {"move_to", "stack", "pick_up"}


def _measured_step(step: str) -> bool:
    """A program step that compares or asks for a hidden property (``filter_weight``, ``query_friction`` …)."""
    from muble.programs.program import QUANTITIES

    kind, _, name = step.partition("_")
    return kind in ("filter", "order", "query") and name in QUANTITIES


# ---- slip ----------------------------------------------------------------------------------------------------------
@dataclass
class SlipConfig:
    lifts: int = bounded(1, ge=1)  # it slips during one of the first `lifts` lifts of a held object (drawn)
    min_height: float = bounded(0.015, ge=0.005, le=0.1)  # m above where it was grasped that it slips at (drawn)
    max_height: float = bounded(0.03, ge=0.005, le=0.1)


class Slip(Disturbance):
    """While a held object is lifted, the grip loosens: the fingers open and the object drops back from
    ``min_height``..``max_height`` above where it was grasped onto what it stood on. The lift then fails as the
    object slipped out of the hand; the agent sees the object back down and the hand empty."""

    def __init__(self, config: SlipConfig) -> None:
        if config.max_height < config.min_height:
            raise ValueError(f"slip: max_height {config.max_height} is below min_height {config.min_height}")
        self.config = config
        self.nth = 1
        self.height = config.min_height
        self.lifts = 0
        self.armed: tuple[int, int] | None = None  # (step, object) while the chosen lift runs
        self.fired = False

    def applies(self, instruction) -> bool:
        steps = _steps(instruction)
        return bool(steps & HANDLING_STEPS) or any(_measured_step(t) for t in steps)

    def reset(self, rng: np.random.Generator, scene) -> None:
        self.nth = int(rng.integers(1, self.config.lifts + 1))
        self.height = float(rng.uniform(self.config.min_height, self.config.max_height))
        self.lifts, self.armed, self.fired = 0, None, False

    def before(self, env, action: ActionCall, step: int) -> DisturbanceEvent | None:
        self.armed = None
        if self.fired or action.name != "lift" or env.held_object is None:
            return None
        self.lifts += 1
        if self.lifts == self.nth:
            self.armed = (step, env.held_object)
        return None

    def on_control(self, env) -> DisturbanceEvent | None:
        if self.armed is None or self.fired or env.held_object is None:
            return None
        step, held = self.armed
        grasped_at = env.cache.get("slip.grasp_z")
        z = float(env.object_pose(held).pos[2])
        if grasped_at is None or grasped_at[0] != (step, held):
            env.cache["slip.grasp_z"] = grasped_at = ((step, held), z)
        risen = z - grasped_at[1]
        if risen < self.height:
            return None
        env.set_gripper(-1.0)  # the fingers let go: the weld of the grasp model releases, the object falls
        self.fired, self.armed = True, None
        logger.info("slip: object %d slips out of the hand %.1f cm up", held, risen * 100)
        return DisturbanceEvent("slip", step, f"lift {self.nth} of a held object, {risen * 100:.1f} cm up",
                                held, detail={"height_m": round(risen, 4), "gripper": "opened"})


# ---- bump ----------------------------------------------------------------------------------------------------------
class AfterPutDown(Disturbance):
    """A disturbance of what the agent just let go of: it acts after the ``nth`` (drawn from 1..``count``)
    successful ``lower`` whose released object ``counts`` (on the table, on another object); where ``act`` finds
    nothing to do, the next such put-down is tried. Subclasses draw their own values in ``draw``."""

    trigger = "put-down"

    def __init__(self, count: int) -> None:
        self.count = count
        self.nth, self.seen = 1, 0
        self.held_before: int | None = None
        self.fired = False

    def reset(self, rng: np.random.Generator, scene) -> None:
        self.nth = int(rng.integers(1, self.count + 1))
        self.seen, self.held_before, self.fired = 0, None, False
        self.draw(rng)

    def draw(self, rng: np.random.Generator) -> None:
        """Draw this episode's values (after ``nth``, from the same stream)."""

    def before(self, env, action: ActionCall, step: int) -> DisturbanceEvent | None:
        self.held_before = env.held_object
        return None

    def after(self, env, action: ActionCall, result: ActionResult, step: int):
        obj = self.held_before
        if self.fired or action.name != "lower" or not result.success or obj is None or env.held_object is not None:
            return result, None
        if not self.counts(env, obj, action):
            return result, None
        self.seen += 1
        if self.seen < self.nth:
            return result, None
        event = self.act(env, obj, action, step)
        self.fired = event is not None
        return result, event

    def counts(self, env, obj: int, action: ActionCall) -> bool:
        raise NotImplementedError

    def act(self, env, obj: int, action: ActionCall, step: int) -> DisturbanceEvent | None:
        raise NotImplementedError


@dataclass
class BumpConfig:
    put_downs: int = bounded(1, ge=1)  # it knocks the object of one of the first `put_downs` table put-downs (drawn)
    min_distance: float = bounded(0.05, ge=0.02, le=0.4)  # m the object is knocked (drawn between these)
    max_distance: float = bounded(0.12, ge=0.02, le=0.4)
    speed: float = bounded(0.2, gt=0.0, le=1.0)  # m/s at most while it slides
    clearance: float = bounded(0.02, ge=0.0, le=0.2)  # m kept from every other object along the way and at the end


class Bump(AfterPutDown):
    """An object just set down on the table is knocked sideways to another free place on the table: a horizontal
    force low on the object (so that it slides standing, as a nudge at its base would move it) drives it about
    ``min_distance``..``max_distance`` (drawn, with the direction) to a free place on the table (``_goal``: out of
    the part it was put in where one is free; a shorter or longer knock where none is, ``_near_goal``); then it comes
    to rest. Where the object has no free place at all, the nearest other object standing alone on the table is
    knocked instead; where none has, it waits for the next put-down on the table."""

    def __init__(self, config: BumpConfig) -> None:
        if config.max_distance < config.min_distance:
            raise ValueError(f"bump: max_distance {config.max_distance} is below min_distance {config.min_distance}")
        super().__init__(config.put_downs)
        self.config = config
        self.distance, self.angle = config.min_distance, 0.0

    def applies(self, instruction) -> bool:
        return "move_to" in _steps(instruction)

    def draw(self, rng: np.random.Generator) -> None:
        self.distance = float(rng.uniform(self.config.min_distance, self.config.max_distance))
        self.angle = float(rng.uniform(0.0, 2 * np.pi))

    def counts(self, env, obj: int, action: ActionCall) -> bool:
        return _on_table(env, obj)

    def act(self, env, obj: int, action: ActionCall, step: int) -> DisturbanceEvent | None:
        part = action.params.get("target")
        put_in = {part} if isinstance(part, str) else None  # the table part the agent just put it on
        goal = self._goal(env, obj, put_in)
        if goal is None:
            # The object just put down has no free place to go (a tray takes most of the table): the nearest
            # other object standing alone on the table is knocked instead, so that the bump planned acts.
            for other in self._neighbours(env, obj):
                goal = self._goal(env, other)  # out of the parts it stands in, as first
                if goal is not None:
                    logger.info("bump: no free place for object %d; object %d is knocked instead", obj, other)
                    obj = other
                    break
        if goal is None:
            logger.info("bump: no free place %.0f cm from object %d", self.distance * 100, obj)
            return None
        start = env.object_pose(obj).pos.copy()
        push = slide_to(env, obj, goal, self.config.speed)
        end = env.object_pose(obj).pos
        logger.info("bump: object %d knocked %.1f cm", obj, 100 * float(np.linalg.norm(end[:2] - start[:2])))
        return _pushed("bump", step, f"put-down {self.nth} on the table", obj, push, start, goal, end)

    @staticmethod
    def _neighbours(env, obj: int) -> list[int]:
        """The other objects that stand on the table with nothing on them, nearest ``obj`` first."""
        here = env.object_pose(obj).pos[:2]
        alone = []
        for other in env.object_ids:
            if other == obj or other == env.held_object or not _on_table(env, other):
                continue
            top = env.object_top(other)
            outline = footprint(env, env.model.body(env.names.objects[other]).id)
            lo, hi = outline.min(axis=0), outline.max(axis=0)
            if any(env.object_pose(k).pos[2] > env.object_pose(other).pos[2] + 0.01 and env.object_top(k) > top
                   and np.all(env.object_pose(k).pos[:2] >= lo) and np.all(env.object_pose(k).pos[:2] <= hi)
                   for k in env.object_ids if k != other):
                continue  # something stands on it: knocking it would carry a stack
            alone.append(other)
        return sorted(alone, key=lambda o: float(np.linalg.norm(env.object_pose(o).pos[:2] - here)))

    def _goal(self, env, obj: int, put_in: set[str] | None = None) -> np.ndarray | None:
        """A free place for the object: its footprint there keeps ``clearance`` from every other's, and on the way
        there it comes no nearer to one than ``PATH_GAP`` (``clearance`` where it starts that clear). Places out of
        ``put_in``, the table part the agent just put it on (default: every part it stands in), come first: a knock
        that undoes the put-down, which an agent that does not look again misses. Each group in order of the
        distance's closeness to the drawn one, then of the turn from the drawn direction (15 degree steps)."""
        body = env.model.body(env.names.objects[obj]).id
        here = env.object_pose(obj).pos[:2]
        outline = footprint(env, body) - here
        others = obstacles(env, obj)
        lo, hi = _table_region(env)
        parts = put_in or _parts(env, here)
        start_free = bool(free_mask(here[None], outline, others, self.config.clearance)[0])
        # Out of the part it was put on may be further than the drawn distance: as far as FARTHEST_FALLBACK_BUMP.
        farthest = FARTHEST_FALLBACK_BUMP if put_in else FARTHEST_BUMP
        reach = np.arange(self.config.min_distance, farthest + 1e-9, 0.01)
        distances = [self.distance, *reach[np.argsort(np.abs(reach - self.distance), kind="stable")]]
        candidates = [here + d * np.array([np.cos(self.angle + t), np.sin(self.angle + t)])
                      for d, t in itertools.product(distances, np.radians(np.arange(0, 360, 15)))]
        candidates.sort(key=lambda goal: bool(_parts(env, goal) & parts))  # stable: the order above within each
        for goal in candidates:
            if np.any(goal < lo) or np.any(goal > hi):
                continue
            distance = float(np.linalg.norm(goal - here))
            way = here + np.linspace(0.0, 1.0, max(2, int(distance / 0.01)))[1:, None] * (goal - here)
            if not free_mask(goal[None], outline, others, self.config.clearance)[0]:
                continue
            if free_mask(way, outline, others, self.config.clearance if start_free else PATH_GAP).all():
                return goal
        return self._near_goal(here, outline, others, lo, hi, start_free)

    def _near_goal(self, here, outline, others, lo, hi, start_free: bool) -> np.ndarray | None:
        """Where no place ``min_distance`` or more away is free (a large object, or one put down at the table's
        edge among others, or a table mostly taken by a tray): the nearest free place ``NEAREST_BUMP`` to
        ``FARTHEST_FALLBACK_BUMP`` away, on the table's parts, along a free way, the clearance halved and halved again before the bump waits for another
        put-down. Every disturbance planned then acts where any room is left."""
        for clearance in (self.config.clearance, self.config.clearance / 2, self.config.clearance / 4):
            places = free_places(lo, hi, outline, others, prefer=here, gap=clearance, spacing=0.01)
            for goal in places:
                distance = float(np.linalg.norm(goal - here))
                if distance < NEAREST_BUMP:
                    continue
                if distance > FARTHEST_FALLBACK_BUMP:
                    break
                way = here + np.linspace(0.0, 1.0, max(2, int(distance / 0.01)))[1:, None] * (goal - here)
                if free_mask(way, outline, others, clearance if start_free else PATH_GAP).all():
                    return goal
        return None


TABLE_PARTS = ("left", "right", "front", "back")


def _parts(env, xy: np.ndarray) -> set[str]:
    """The named table parts (``TABLE_PARTS``) the point ``xy`` lies in, as the success check reads them
    (``muble.stage.table.parts_at``, by the split lines: not the narrower boxes a put-down aims for, which keep a
    margin from those lines)."""
    if "disturbances.directions" not in env.cache:
        env.cache["disturbances.directions"] = env.sync_scene_graph().directions
    return set(parts_at(float(xy[0]), float(xy[1]), env.cache["disturbances.directions"])) & set(TABLE_PARTS)


FARTHEST_BUMP = 0.2  # m an object is knocked at most, where no place at the drawn distance is free
NEAREST_BUMP = 0.03  # m an object is knocked at least, where no place min_distance away is free
FARTHEST_FALLBACK_BUMP = 0.35  # m it is knocked at most then: across a table mostly taken by a tray or a board
PATH_GAP = 0.003  # m kept from every other object on the way, where the object starts nearer than the clearance


def _pushed(kind: str, step: int, trigger: str, obj: int, push: dict, start: np.ndarray, goal: np.ndarray,
            end: np.ndarray) -> DisturbanceEvent:
    return DisturbanceEvent(kind, step, trigger, obj, force=push["peak"].tolist(), impulse=push["impulse"].tolist(),
                            duration=push["duration"],
                            detail={"from": np.round(start[:2], 4).tolist(), "to": np.round(goal, 4).tolist(),
                                    "ended": np.round(end, 4).tolist()})


def _table_region(env) -> tuple[np.ndarray, np.ndarray]:
    """The box (x, y) spanned by the table's named parts: where a placed object stays reachable."""
    boxes = [part_box(env, part) for part in TABLE_PARTS]
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


def _on_table(env, obj: int) -> bool:
    """The object stands on the table itself (touching it, not only other objects)."""
    m, d = env.model, env.data
    body = m.body(env.names.objects[obj]).id
    table = env.table().body
    touching = set()
    for c in d.contact[: d.ncon]:
        b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
        if body in (b1, b2):
            touching.add(b2 if b1 == body else b1)
    return table in touching


# m above the object's lowest point where a slide's force acts: at the height of the table's friction on it, so
# that the two make no moment that would tip it (a tall glass pushed at a quarter of its height falls over).
PUSH_HEIGHT = 0.003


def slide_to(env, obj: int, goal: np.ndarray, speed: float) -> dict:
    """Drive ``obj`` over the table to ``goal`` (x, y) with a horizontal force low on it, then let it come to
    rest; returns the peak force, the impulse (N·s) and the time the force acted. The force carries the
    object's weight times its friction with the table beside a speed servo, capped at three times its weight."""
    push = Push(env, obj)
    bottom = env.object_top(obj) - env.world_bbox(obj)["z"]
    push.drive(lambda pos: np.append(goal, pos[2]), speed, planar=True, height=bottom + PUSH_HEIGHT)
    return push.done()


def knock_off(env, obj: int, over: float, goal: np.ndarray, speed: float) -> dict:
    """Knock ``obj`` off what it stands on onto the table at ``goal`` (x, y): a force at its centre of mass that
    carries its weight lifts it until its bottom is ``over`` (world z) while moving it a third of the way, moves it
    the rest of the way across, and lowers it until it touches the table; then it comes to rest. Returns the
    push's figures as ``slide_to`` does."""
    push = Push(env, obj)
    body = push.body
    top = env.object_top(obj)
    bottom = top - env.world_bbox(obj)["z"]
    rise = max(0.0, over - bottom)
    start = env.data.xipos[body].copy()
    # Up and a third of the way across at once: out from under the hand that has just let it go (its fingers hang
    # a few centimetres above it), then across at that height and down.
    up = np.array([*(start[:2] + (np.asarray(goal) - start[:2]) / 3.0), start[2] + rise])
    push.drive(lambda pos: up, speed, planar=False)
    across = np.array([goal[0], goal[1], up[2]])
    push.drive(lambda pos: across, speed, planar=False)
    table_top = env.table().top_z
    down = np.array([goal[0], goal[1], table_top - 0.01])  # below reach: stopped by the table, not by the servo
    push.drive(lambda pos: down, 0.5 * speed, planar=False, until=lambda: _on_table(env, obj))
    return push.done()


# s a push may take at most per leg; gains of the force that drives it (per kg)
SLIDE_TIME = 3.0
SLIDE_KP = 4.0  # 1/s: desired speed per metre still to go
SLIDE_KV = 25.0  # 1/s: acceleration per m/s of speed error
SLIDE_TOLERANCE = 0.005  # m from the goal where the force ends, once the object is nearly still (SLIDE_STILL, m/s)
SLIDE_STILL = 0.02
SLIDE_FADE = 0.02  # m from the goal within which the friction fed forward fades out
STEADY_KP, STEADY_KV = 25.0, 8.0  # 1/s², 1/s: how a carried object is held as it stood (per its inertia)


class Push:
    """A force servo on one object: ``drive`` moves it towards a goal at a bounded speed, by a force through
    MuJoCo applied each control step (horizontal and low on it for a slide, with friction fed forward; at its
    centre of mass and carrying its weight for a lift), and ``done`` ends the force and lets it come to rest."""

    def __init__(self, env, obj: int) -> None:
        self.env, self.obj = env, obj
        self.body = env.model.body(env.names.objects[obj]).id
        self.mass = float(env.model.body_subtreemass[self.body])
        self.mu = _table_friction(env, self.body)
        self.impulse, self.peak, self.t = np.zeros(3), np.zeros(3), 0.0
        self.dt = float(getattr(env, "control_dt", 0.05))
        self.start_quat = env.data.xquat[self.body].copy()

    def drive(self, goal_at, speed: float, planar: bool, height: float | None = None, until=None) -> None:
        env, body, mass = self.env, self.body, self.mass
        axes = 2 if planar else 3
        start = self.t
        while self.t - start < SLIDE_TIME:
            pos = env.data.xipos[body].copy()
            error = (goal_at(pos) - pos)[:axes]
            velocity = _linear_velocity(env, body)[:axes]
            if until is not None and until():
                break
            if np.linalg.norm(error) < SLIDE_TOLERANCE and np.linalg.norm(velocity) < SLIDE_STILL:
                break  # there and nearly still: let go (a slippery object let go at speed slides on)
            want = SLIDE_KP * error
            if np.linalg.norm(want) > speed:
                want *= speed / np.linalg.norm(want)
            accel = SLIDE_KV * (want - velocity)
            if planar:
                # Friction fed forward along the way, fading out near the goal, where the servo brakes.
                direction = want / max(float(np.linalg.norm(want)), 1e-9) * min(1.0, float(np.linalg.norm(error))
                                                                                  / SLIDE_FADE)
                force = np.append(mass * (accel + self.mu * G * direction), 0.0)
                point = np.array([pos[0], pos[1], height])
            else:
                force = mass * (accel + [0.0, 0.0, G])
                point = None
            cap = 3.0 * mass * G
            if np.linalg.norm(force) > cap:
                force *= cap / np.linalg.norm(force)
            env.apply_force(self.obj, force, point, None if planar else self._steady())
            env.advance(self.dt)
            self.impulse += force * self.dt
            if np.linalg.norm(force) > np.linalg.norm(self.peak):
                self.peak = force
            self.t += self.dt

    def _steady(self) -> np.ndarray:
        """The torque that keeps a carried object as it stood (a damped spring on its turn from the start, scaled
        by its rotational inertia): knocked off, it lands standing, not tumbled by the rim it scraped."""
        env, body = self.env, self.body
        quat = env.data.xquat[body]
        error = np.zeros(3)
        mujoco.mju_subQuat(error, self.start_quat, quat)  # the rotation (body frame) from now back to the start
        rot = env.data.xmat[body].reshape(3, 3)
        spin = np.zeros(6)
        mujoco.mj_objectVelocity(env.model, env.data, mujoco.mjtObj.mjOBJ_BODY, body, spin, 0)
        inertia = float(np.max(env.model.body_inertia[body]))
        return inertia * (STEADY_KP * (rot @ error) - STEADY_KV * spin[:3])

    def done(self) -> dict:
        env = self.env
        env.apply_force(self.obj, np.zeros(3))
        waited = 0.0
        while waited < 1.5:
            env.advance(0.1)
            waited += 0.1
            if at_rest(float(np.linalg.norm(_linear_velocity(env, self.body)))):
                break
        return {"peak": self.peak, "impulse": self.impulse, "duration": self.t}


def _linear_velocity(env, body: int) -> np.ndarray:
    """The body's linear velocity (m/s, world frame) at its centre of mass."""
    out = np.zeros(6)
    mujoco.mj_objectVelocity(env.model, env.data, mujoco.mjtObj.mjOBJ_BODY, body, out, 0)
    return out[3:]


def _table_friction(env, body: int) -> float:
    """The sliding friction between the body and the table (MuJoCo's contact friction: the larger of the two)."""
    m = env.model
    table_geom = m.geom(env.names.table_geom).id
    geoms = np.flatnonzero(m.geom_bodyid == body)
    own = max(float(m.geom_friction[g, 0]) for g in geoms) if len(geoms) else 1.0
    return max(own, float(m.geom_friction[table_geom, 0]))


# ---- topple --------------------------------------------------------------------------------------------------------
@dataclass
class ToppleConfig:
    stackings: int = bounded(1, ge=1)  # it knocks off the top of one of the first `stackings` put-downs on an object
    speed: float = bounded(0.2, gt=0.0, le=1.0)  # m/s at most while it is pushed off
    # m between it and every other object where it ends: room for the open fingers to grasp it again
    clearance: float = bounded(0.05, ge=0.0, le=0.2)


KNOCK_CLEARANCE = 0.015  # m the knocked-off object's bottom passes over the tops of what it stood on and passes


class Topple(AfterPutDown):
    """The top object of a stack just made is knocked off onto the table: a force at its centre of mass lifts it
    out of or off what it stood on (``knock_off``), carries it across in a drawn direction (turned in 15 degree
    steps until a free place on the table is found) and sets it down there, standing as it stood."""

    def __init__(self, config: ToppleConfig) -> None:
        super().__init__(config.stackings)
        self.config = config
        self.angle = 0.0

    def applies(self, instruction) -> bool:
        return "stack" in _steps(instruction)

    def draw(self, rng: np.random.Generator) -> None:
        self.angle = float(rng.uniform(0.0, 2 * np.pi))

    def counts(self, env, obj: int, action: ActionCall) -> bool:
        return isinstance(action.params.get("target"), (int, np.integer))

    def act(self, env, obj: int, action: ActionCall, step: int) -> DisturbanceEvent | None:
        base = int(action.params["target"])
        found = self._goal(env, obj, base)
        if found is None:
            logger.info("topple: no free place beside object %d for object %d", base, obj)
            return None
        goal, over = found
        start = env.object_pose(obj).pos.copy()
        push = knock_off(env, obj, over, goal, self.config.speed)
        end = env.object_pose(obj).pos
        logger.info("topple: object %d knocked off object %d", obj, base)
        event = _pushed("topple", step, f"stacking {self.nth}", obj, push, start, goal, end)
        event.detail["base"] = base
        return event

    def _goal(self, env, top: int, base: int) -> tuple[np.ndarray, float] | None:
        """(place, height to carry the object's bottom over) for the knock: the nearest place along the drawn
        direction (then turned by 15 degree steps) where the top object's footprint keeps ``clearance`` from
        every other object's, the base's included, on the table's parts. The object is carried over everything
        its way passes near (``KNOCK_CLEARANCE`` above the highest top there); a way that needs it lifted more
        than ``KNOCK_LIFT`` above the base is passed over while another is free."""
        body = env.model.body(env.names.objects[top]).id
        here = env.object_pose(top).pos[:2]
        outline = footprint(env, body) - here
        reach = float(np.max(np.linalg.norm(outline, axis=1)))
        others = obstacles(env, top)
        others_ids = [i for i in env.object_ids if i != top]
        lo, hi = _table_region(env)
        base_top = env.object_top(base)

        def over(goal: np.ndarray) -> float:
            return max([base_top] + [env.object_top(j) for j, outline_j in zip(others_ids, others)
                                     if _near_way(outline_j, here, goal, reach)]) + KNOCK_CLEARANCE

        # Less clearance only where none is found with more: a crowded table, or a stack at its edge (the grasp
        # that picks the object up again then turns to where the fingers have room).
        for clearance in (self.config.clearance, *(c for c in FALLBACK_CLEARANCES if c < self.config.clearance)):
            fallback = None
            for turn in np.radians(np.arange(0, 360, 15)):
                a = self.angle + turn
                direction = np.array([np.cos(a), np.sin(a)])
                for distance in np.arange(0.02, 0.3, 0.01):
                    goal = here + distance * direction
                    if np.any(goal < lo) or np.any(goal > hi):
                        break
                    if not free_mask(goal[None], outline, others, clearance)[0]:
                        continue
                    height = over(goal)
                    if height <= base_top + KNOCK_LIFT:
                        return goal, height
                    if fallback is None or height < fallback[1]:
                        fallback = (goal, height)
                    break
            if fallback is not None:
                return fallback
            # No ray from the stack reaches a free place (the stack stands outside the parts' box, by its edge):
            # the free place on the parts nearest the drawn direction's.
            aim = here + 0.1 * np.array([np.cos(self.angle), np.sin(self.angle)])
            places = free_places(lo, hi, outline, others, prefer=aim, gap=clearance, spacing=0.01)
            if places:
                return places[0], over(places[0])
        return None


# m of clearance a topple settles for, in turn, where its configured clearance leaves no free place
FALLBACK_CLEARANCES = (0.04, 0.03, 0.02)
KNOCK_LIFT = 0.06  # m above the base's top a knocked-off object is carried at most, while a lower way is free


def _near_way(outline: np.ndarray, start: np.ndarray, goal: np.ndarray, reach: float) -> bool:
    """Whether any point of ``outline`` (a footprint on the table) comes within ``reach`` of the way from
    ``start`` to ``goal``."""
    way = goal - start
    t = np.clip((outline - start) @ way / max(float(way @ way), 1e-12), 0.0, 1.0)
    return bool(np.min(np.linalg.norm(outline - (start + t[:, None] * way), axis=1)) < reach)


# ---- sensor dropout ------------------------------------------------------------------------------------------------
@dataclass
class SensorDropoutConfig:
    readings: int = bounded(1, ge=1)  # one of the first `readings` measurements fails (drawn)


class SensorDropout(Disturbance):
    """A measuring primitive's reading is unstable once: it fails with the reason "reading unstable", and what it
    measured is forgotten (the agent has to measure again)."""

    def __init__(self, config: SensorDropoutConfig) -> None:
        self.config = config
        self.nth = 1
        self.readings = 0
        self.kept: dict | None = None
        self.fired = False

    def applies(self, instruction) -> bool:
        return any(_measured_step(t) for t in _steps(instruction))

    def reset(self, rng: np.random.Generator, scene) -> None:
        self.nth = int(rng.integers(1, self.config.readings + 1))
        self.readings, self.kept, self.fired = 0, None, False

    def before(self, env, action: ActionCall, step: int) -> DisturbanceEvent | None:
        measures = get_registry().measures(action.name) if isinstance(action.name, str) else None
        self.kept = None if self.fired or measures is None else \
            {i: dict(values) for i, values in env.measurements.items()}
        return None

    def after(self, env, action: ActionCall, result: ActionResult, step: int):
        if self.kept is None or not result.success:
            return result, None
        self.readings += 1
        if self.readings != self.nth:
            return result, None
        self.fired = True
        env.measurements.clear()
        env.measurements.update(self.kept)  # the unstable reading is not kept
        failed = ActionResult(False, failure_reason="reading unstable: the sensor did not settle; measure again",
                              info=dict(result.info or {}))
        return failed, DisturbanceEvent("sensor_dropout", step, f"measurement {self.nth}", _target(env, action),
                                        detail={"primitive": action.name})


def _target(env, action: ActionCall) -> int | None:
    target = action.params.get("target")
    if isinstance(target, (int, np.integer)):
        return int(target)
    return env.held_object


__all__ = ["Bump", "BumpConfig", "SensorDropout", "SensorDropoutConfig", "Slip", "SlipConfig"]
