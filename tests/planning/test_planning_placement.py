"""Putting objects down on a crowded table part: free places from real footprints, carrying an object straight
off its support, putting it back where it is."""
from __future__ import annotations

import numpy as np
import pytest

from muble import get_registry
from muble.sim.env import TabletopEnv
from muble.stage.table import part_box, parts_at
from muble_plugins.primitives import placement
from tests.support.scenes import simple_object_model, simple_scene

HELD = 0
BOARDS = [(0.36, -0.22), (0.66, -0.22)]  # leave a 10 cm slot (x 0.46-0.56) across the left part


@pytest.fixture(scope="module")
def env():
    can = simple_object_model("cylinder", (0.06, 0.06, 0.10), 200.0)
    board = simple_object_model("box", (0.20, 0.34, 0.02), 300.0, rgba=(0.5, 0.3, 0.1, 1))
    turned = simple_object_model("box", (0.34, 0.20, 0.02), 300.0, rgba=(0.5, 0.3, 0.1, 1))
    scene = simple_scene([(0.45, 0.15), *BOARDS], [can, board, turned])
    # The second board's long side lies along x in its own frame: a quarter turn lays it across the part.
    scene.objects[2].orientation = np.array([np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])
    environment = TabletopEnv(scene, {o.id: m for o, m in zip(scene.objects, [can, board, turned])})
    yield environment
    environment.close()


def act(env, name, **params):
    return get_registry().create("primitive", name, params).execute(env)


def _distance_to_board(xy, centre, half):
    outside = np.maximum(np.abs(np.asarray(xy) - centre) - half, 0.0)
    return float(np.linalg.norm(outside))


def test_a_crowded_part_still_has_the_slot_between_turned_boards(env):
    env.reset()
    lo, hi = part_box(env, "left")
    places = placement.free_places(env, lo, hi, HELD)
    assert places, "the 10 cm slot fits a 6 cm can with 1.5 cm to spare on each side"
    radius = 0.03
    for xy in places:
        for centre in BOARDS:
            # Both boards cover 0.20 m along x and 0.34 m along y on the table, the second one only once turned.
            gap = _distance_to_board(xy, np.array(centre), np.array([0.10, 0.17])) - radius
            assert gap >= placement.PLACE_GAP - 0.002, (xy, centre, gap)
    assert all(0.485 <= p[0] <= 0.535 for p in places)
    # Nearest the part's centre first.
    centre = 0.5 * (lo + hi)
    distances = [np.linalg.norm(p - centre) for p in places]
    assert distances == sorted(distances)


@pytest.mark.slow
def test_carry_off_the_support_without_lifting_and_put_down_in_the_slot(env):
    env.reset()
    for name, params in [("move", {"target": HELD}), ("approach", {"target": HELD}), ("close_gripper", {})]:
        result = act(env, name, **params)
        assert result.success, (name, result.failure_reason)
    assert env.held_object == HELD
    # Still standing on the table: moving must first leave that contact (allowed), then carry it over.
    result = act(env, "move", target="left")
    assert result.success, result.failure_reason
    assert result.info["unintended_contacts"] == []
    result = act(env, "lower", target="left")
    assert result.success, result.failure_reason
    assert result.info["unintended_contacts"] == []
    pos = env.object_pose(HELD).pos
    assert "left" in parts_at(*pos[:2])
    assert 0.47 <= pos[0] <= 0.55  # in the slot between the boards
    assert abs(pos[2]) < 0.005  # resting on the table top


@pytest.mark.slow
def test_lower_without_target_puts_the_object_back_in_its_parts(env):
    env.reset()
    before = parts_at(*env.object_pose(HELD).pos[:2])
    for name, params in [("move", {"target": HELD}), ("approach", {"target": HELD}), ("close_gripper", {}),
                         ("lift", {})]:
        assert act(env, name, **params).success, name
    result = act(env, "lower")
    assert result.success, result.failure_reason
    assert env.held_object is None
    pos = env.object_pose(HELD).pos
    assert parts_at(*pos[:2]) == before
    assert np.linalg.norm(pos[:2] - [0.45, 0.15]) < 0.05


def test_the_symbolic_world_puts_down_by_the_same_rule_in_the_same_slot(env):
    """Bounding boxes contain the collision geometry, so the symbolic world's spot is free in physics too."""
    from muble.stage.footprint import free_spot

    env.reset()
    scene = env.sync_scene_graph()
    spot = free_spot(scene, scene.object(HELD), "left")
    assert spot is not None
    assert 0.485 <= spot[0] <= 0.535, spot  # the slot between the boards, as in physics
    assert placement.is_free(env, np.array(spot[:2]), HELD)


def test_a_part_without_room_fails_alike_in_the_symbolic_world(env):
    from muble.stage.footprint import free_spot

    env.reset()
    scene = env.sync_scene_graph()
    wide = scene.object(HELD)
    wide.bbox = {"x": 0.2, "y": 0.2, "z": 0.1}  # wider than the slot
    assert free_spot(scene, wide, "left") is None
    # The symbolic move of a raised object to that part reports what physics reports.
    wide.extra.update(in_hand=True, raised=True)  # held and lifted, as the symbolic world records it
    result = get_registry().create("primitive", "move", {"target": "left"}).symbolic_effect(scene)
    assert not result.success
    assert result.failure_reason == placement.no_room("left", HELD)
