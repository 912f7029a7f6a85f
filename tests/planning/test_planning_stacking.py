"""Stacking with the SHOP-VRB2 set: pick a stackable object up and lower it onto a stack base; it must rest on
the base (released, still, touching the base and not the table). ``benchmarks/stacking_acceptance.py`` runs
every pair the set can produce."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from muble import get_registry
from muble.sim.env import TabletopEnv
from tests.support.scenes import simple_scene


def act(env, name, **params):
    return get_registry().create("primitive", name, params).execute(env)


@pytest.fixture(scope="module")
def objects():
    return get_registry().create("object_set", "shopvrb2", {"cache_dir": None})


def _touching(env, obj_id: int) -> set[int]:
    m, d = env.model, env.data
    body = m.body(env.names.objects[obj_id]).id
    out = set()
    for c in d.contact[: d.ncon]:
        b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
        if body in (b1, b2):
            out.add(b2 if b1 == body else b1)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("top, base", [("glass", "plate"), ("mug", "bowl"), ("soda can", "chopping board")])
def test_planning_stack_a_stackable_object_on_a_stack_base(objects, top, base):
    rng = np.random.default_rng(0)
    models = []
    for category in (top, base):
        spec = objects.sample(rng, category=category)
        spec.size, spec.scale = "medium-sized", 1.0
        models.append(objects.build(spec))
    assert models[0].stackable and models[1].stack_base
    env = TabletopEnv(simple_scene([(0.42, -0.20), (0.52, 0.12)], models), dict(enumerate(models)))
    try:
        for name, params in [("approach", {"target": 0}), ("close_gripper", {}), ("lift", {})]:
            result = act(env, name, **params)
            assert result.success, (name, result.failure_reason)
        result = act(env, "lower", target=1)
        assert result.success, result.failure_reason
        env.hold(0.5)
        assert env.held_object is None
        touching = _touching(env, 0)
        base_body = env.model.body(env.names.objects[1]).id
        table = env.model.geom_bodyid[env.model.geom("table_collision").id]
        assert base_body in touching and table not in touching, (models[0].spec.model, models[1].spec.model)
        top_body = env.model.body(env.names.objects[0]).id
        assert float(np.linalg.norm(env.data.cvel[top_body][3:])) < 0.01  # at rest
        top_xy, base_xy = env.object_pose(0).pos[:2], env.object_pose(1).pos[:2]
        assert np.linalg.norm(top_xy - base_xy) < 0.5 * max(models[1].extents[:2])  # over the base, not beside it
    finally:
        env.close()


DATA = Path(__file__).parent / "data"


def _stack(top: int, base: int) -> list:
    return [("move", {"target": top}), ("approach", {"target": top}), ("close_gripper", {}), ("lift", {}),
            ("move", {"target": base}), ("lower", {"target": base})]


def _stack_in_scene(scene_file: str, top: int, base: int, under: int | None = None, build: bool = False) -> list:
    """Pick ``top`` up in the stored scene and stack it on ``base``; every primitive must succeed without
    unintended contact and ``top`` must end resting on ``base`` alone (and ``base`` still on ``under``, where it
    stands on another object; with ``build``, ``base`` is first stacked on ``under`` the same way). Returns the
    hand's orientation before and after the last move over a base."""
    from muble.io.scene_io import load_scene
    from muble.sim.build import env_from_object_set

    env = env_from_object_set(load_scene(DATA / scene_file), "shopvrb2")
    quats = []
    try:
        for name, params in (_stack(base, under) if build else []) + _stack(top, base):
            if name == "lower":
                quats.append(env.ee_pose().quat)
            result = act(env, name, **params)
            assert result.success, (name, result.failure_reason)
            assert not result.info.get("unintended_contacts"), (name, result.info)
            if name == "lift":
                quats.clear()
                quats.append(env.ee_pose().quat)
        env.hold(0.5)
        base_body = env.model.body(env.names.objects[base]).id
        table = env.model.geom_bodyid[env.model.geom("table_collision").id]
        touching = _touching(env, top)
        assert base_body in touching and table not in touching
        assert np.linalg.norm(env.object_pose(top).pos[:2] - env.object_pose(base).pos[:2]) < 0.03
        if under is not None:
            assert env.model.body(env.names.objects[under]).id in _touching(env, base)
            assert np.linalg.norm(env.object_pose(base).pos[:2] - env.object_pose(under).pos[:2]) < 0.03
    finally:
        env.close()
    return quats


def _turn_deg(a, b) -> float:
    return 2 * float(np.degrees(np.arccos(min(1.0, abs(float(a @ b))))))


@pytest.mark.slow
def test_planning_a_carried_bowl_turns_about_the_vertical_to_reach_a_base_in_the_far_corner():
    """The base bowl stands near the far corner: held the way it was picked up, the carried bowl's centre cannot
    come over it (the arm falls 16 mm short), so move turns the hand and the bowl about the vertical."""
    lifted, over_base = _stack_in_scene("bowl_stack_base_in_far_corner.json", top=2, base=1)
    assert _turn_deg(lifted, over_base) > 20.0


@pytest.mark.slow
def test_planning_lower_turns_the_held_bowl_where_a_tall_thermos_blocks_the_straight_descent():
    """Bowl 0 carried over bowl 3 as it was picked up: going down, the wrist would hit the 29 cm thermos beside
    the base, so lower turns the hand (and the bowl) about the vertical and puts it down from there."""
    _stack_in_scene("stack_base_beside_a_tall_neighbour.json", top=0, base=3)


@pytest.mark.slow
def test_planning_fingers_opened_inside_a_bowl_do_not_lift_it_as_they_rise():
    """A glass let go inside a bowl standing on a plate: opened fully, the fingers press on the bowl's inner wall
    and, rising, lifted the bowl off the plate; they close back to the glass's width plus a clearance first."""
    _stack_in_scene("glass_into_a_bowl_on_a_plate.json", top=1, base=2, under=0)


@pytest.mark.slow
def test_planning_the_hand_follows_a_can_that_slid_in_a_bowl_before_rising():
    """A soda can let go into a bowl on a food box slides about a centimetre down the bowl's curved floor against
    a finger; rising straight up, that finger tipped the can and the bowl off the box. The hand follows the can
    sideways first."""
    _stack_in_scene("can_into_a_bowl_on_a_food_box.json", top=0, base=3, under=2)


def test_planning_a_put_down_that_moved_another_object_or_missed_its_target_is_reported(objects):
    """``lower``'s check after the object came to rest: it must touch its target, stand as it was let go (with a
    target or without) and leave the others where they were; each way of failing is named."""
    from muble.stage.geometry import tilt_deg
    from muble_plugins.primitives.lower import misplaced

    rng = np.random.default_rng(0)
    models = [objects.build(objects.sample(rng, category=c)) for c in ("glass", "plate")]
    env = TabletopEnv(simple_scene([(0.42, -0.20), (0.52, 0.12)], models), dict(enumerate(models)))
    try:
        env.hold(0.3)
        bodies = [env.model.body(env.names.objects[i]).id for i in (0, 1)]
        table = int(env.model.geom_bodyid[env.model.geom("table_collision").id])
        here = {1: env.object_pose(1).pos.copy()}
        assert misplaced(env, 0, bodies[0], "left", table, here) is None
        assert "did not stay on object 1" in misplaced(env, 0, bodies[0], 1, bodies[1], here)
        moved = {1: here[1] + [0.05, 0.0, 0.0]}
        assert "moved object 1 by 5 cm" in misplaced(env, 0, bodies[0], "left", table, moved)
        upright = float(tilt_deg(env.object_pose(0).quat))
        assert misplaced(env, 0, bodies[0], "left", table, here, tilt_at_release=upright) is None
        assert "came to rest leaning" in misplaced(env, 0, bodies[0], "left", table, here, tilt_at_release=upright - 30)
        # Put back where it was (no target): it need touch nothing in particular, but must not have fallen over.
        assert misplaced(env, 0, bodies[0], None, table, here, tilt_at_release=upright) is None
        assert "came to rest leaning" in misplaced(env, 0, bodies[0], None, table, here, tilt_at_release=upright - 30)
    finally:
        env.close()


@pytest.mark.slow
def test_planning_a_bowl_held_by_its_rim_is_let_go_from_higher_up_into_a_wider_bowl():
    """A medium bowl held by its rim over a large bowl: nested where it would rest, its outer finger would go down
    into the large bowl and meets its wall about 3 cm above the release pose, at every turn; lower lets the bowl go
    from above that height, and it lands nested in the large bowl."""
    _stack_in_scene("medium_bowl_into_a_large_bowl.json", top=3, base=4)


@pytest.mark.slow
def test_planning_the_hand_moves_off_a_can_still_leaning_on_a_finger_before_rising():
    """A soda can let go into a large bowl on a chopping board slides with the opening finger, and after the hand
    has followed it once it still leans on that finger; rising then tipped it over against the bowl's rim (46
    degrees). The hand follows it again until no finger touches it, then rises."""
    _stack_in_scene("can_into_a_large_bowl_on_a_chopping_board.json", top=2, base=0, under=3, build=True)


@pytest.mark.slow
def test_planning_a_hand_closed_on_a_glass_it_did_not_take_opens_before_the_next_move():
    """Closing on a small glass whose wider top meets one finger's side before its pad, the grasp does not take
    (only one pad touches), and the closed hand stays round the glass. The next move starts in contact with it:
    rising closed lifted the glass along, so every move failed with its start in collision; the hand opens first,
    rises off it and moves, and the glass stays standing where it was."""
    from muble.io.scene_io import load_scene
    from muble.sim.build import env_from_object_set
    from muble.stage.geometry import tilt_deg

    env = env_from_object_set(load_scene(DATA / "glass_the_fingers_close_on_without_taking.json"), "shopvrb2")
    try:
        for name, params in _stack(2, 3) + [("move", {"target": 1}), ("approach", {"target": 1})]:
            result = act(env, name, **params)
            assert result.success, (name, result.failure_reason)
        glass = env.object_pose(1).pos.copy()
        assert not act(env, "close_gripper", target=1).success and env.held_object is None
        result = act(env, "move", target=1, attempt=1)
        assert result.success, result.failure_reason
        env.hold(0.5)
        assert np.linalg.norm(env.object_pose(1).pos - glass) < 0.01 and tilt_deg(env.object_pose(1).quat) < 5.0
    finally:
        env.close()
