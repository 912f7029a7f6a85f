"""The tabletop described once: every rectangle on the table is a stage's or derived from one (the generator's
defaults included), a bbox is object-frame extents with the world box computed from the pose, the layout sampler
both the generator and the synthetic scenes use keeps its rules, and settling, tilt and turns are defined once."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from muble import ConfigError, SceneObject
from muble.generation.config import STAGE_OPTIONS, GeneratorConfig, on_stage
from muble.stage.footprint import axis_outline, height, outline
from muble.stage.geometry import hull_2d, polygon_distance, quat_matrix, turn_deg, world_extents, yaw_quat
from muble.stage.layout import BoxShape, Placement, TableLayout, distance_to_point, fits
from muble.stage.rest import SETTLED_DISPLACEMENT, SETTLED_TURN, settled, upright
from muble.stage.table import STAGES, UNNAMED_STAGE, part_region
from muble_plugins.common.synthetic import sample_scenes


def _object(size, quat=(1.0, 0.0, 0.0, 0.0), xy=(0.5, 0.0)) -> SceneObject:
    return SceneObject(id=0, model="m", name="baking tray", shape="flat", size="large", material="metal",
                       colour="gray", position=np.array([*xy, 0.0]), orientation=np.asarray(quat, dtype=float),
                       weight_gt=100.0, stackable=False, stack_base=True, pickupable=False,
                       bbox={"x": size[0], "y": size[1], "z": size[2]})


def test_every_stage_keeps_its_areas_on_its_table_top():
    for stage in STAGES.values():
        (x0, x1), (y0, y1) = stage.top
        assert x1 - x0 == pytest.approx(stage.table_size[0]) and y1 - y0 == pytest.approx(stage.table_size[1])
        for (lo, hi), (edge_lo, edge_hi) in zip(stage.reach, stage.top):
            assert edge_lo < lo < hi < edge_hi
        for part in ("left", "right", "front", "back", "centre"):
            for (lo, hi), (p_lo, p_hi), (edge_lo, edge_hi) in zip(stage.part_region(part), stage.place, stage.top):
                assert p_lo <= lo < hi <= p_hi and edge_lo + stage.edge_margin <= lo and hi <= edge_hi - stage.edge_margin
    assert STAGES[UNNAMED_STAGE].top == ((0.16, 1.06), (-0.6, 0.6))  # robosuite's table, as for the Panda
    assert np.allclose(STAGES["original"].top, [[-0.23, 1.13], [-0.4, 0.4]])
    # Unclipped by a table top, a part's region is the place area split at the part's lines.
    assert part_region("left", STAGES[UNNAMED_STAGE].place)[1] == (-0.40, -0.04)


def test_the_generators_table_options_default_to_the_stage_and_a_set_value_wins():
    defaults = GeneratorConfig()
    for name, value in STAGE_OPTIONS.items():
        assert getattr(defaults, name) == value(STAGES[UNNAMED_STAGE])
    original = on_stage(dataclasses.replace(defaults, stage="original"))
    for name, value in STAGE_OPTIONS.items():
        assert getattr(original, name) == value(STAGES["original"])
    assert original.table_y == [-0.4, 0.4]
    mine = on_stage(dataclasses.replace(defaults, stage="original", table_y=[-0.3, 0.3], margin=0.02))
    assert mine.table_y == [-0.3, 0.3] and mine.margin == 0.02 and mine.table_x == list(STAGES["original"].top[0])
    with pytest.raises(ConfigError, match="unknown stage 'moon'.*generator.stage"):
        on_stage(dataclasses.replace(defaults, stage="moon"))


def test_a_bbox_is_object_frame_extents_and_the_world_box_follows_the_pose():
    size = (0.30, 0.10, 0.02)
    assert np.allclose(world_extents(size, yaw_quat(0.0)), size)
    assert np.allclose(world_extents(size, yaw_quat(math.pi / 2)), [0.10, 0.30, 0.02])
    c, s = math.cos(math.pi / 6), math.sin(math.pi / 6)
    assert np.allclose(world_extents(size, yaw_quat(math.pi / 6)), [0.30 * c + 0.10 * s, 0.30 * s + 0.10 * c, 0.02])
    on_side = Rotation.from_euler("x", 90, degrees=True).as_quat(scalar_first=True)
    assert np.allclose(world_extents(size, on_side), [0.30, 0.02, 0.10])
    assert height(_object(size, on_side)) == pytest.approx(0.10) and height(_object(size)) == pytest.approx(0.02)
    # The footprint turns with the object; the symbolic world's put-down footprint lies along the world axes.
    turned = _object(size, yaw_quat(math.pi / 2))
    assert np.allclose(np.ptp(outline(turned), axis=0), [0.10, 0.30])
    assert np.allclose(np.ptp(axis_outline(turned), axis=0), [0.30, 0.10])
    assert np.allclose(outline(turned).mean(axis=0), [0.5, 0.0])


def test_rotations_turns_and_polygon_distances():
    rotations = Rotation.random(200, rng=np.random.default_rng(4))
    for rot, other in zip(rotations[:100], rotations[100:]):
        q = rot.as_quat(scalar_first=True)
        assert np.allclose(quat_matrix(q), rot.as_matrix(), atol=1e-12)
        angle = np.degrees((other * rot.inv()).magnitude())
        assert turn_deg(q, other.as_quat(scalar_first=True)) == pytest.approx(angle, abs=1e-6)
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert polygon_distance(square, square + [0.5, 0.5]) == 0.0
    assert polygon_distance(square, square + [1.25, 0.0]) == pytest.approx(0.25)
    assert polygon_distance(square, square + [2.0, 2.0]) == pytest.approx(math.sqrt(2.0))
    diamond = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]) + [2.6, 0.5]
    assert polygon_distance(square, diamond) == pytest.approx(0.6)


def test_settled_and_upright_are_the_stated_limits():
    assert settled(SETTLED_DISPLACEMENT, SETTLED_TURN) and settled(0.0)
    assert not settled(SETTLED_DISPLACEMENT + 1e-6) and not settled(0.0, SETTLED_TURN + 0.01)
    assert not settled(math.inf) and settled(0.009, limit=0.01)
    leaning = Rotation.from_euler("x", 25, degrees=True).as_quat(scalar_first=True)
    assert upright(yaw_quat(1.0)) and not upright(leaning) and upright(15.0) and not upright(25)


def test_one_layout_sampler_places_the_synthetic_scenes_as_the_generator_places_objects():
    stage = STAGES[UNNAMED_STAGE]
    for scene in sample_scenes(3, 30):
        placements = [Placement(o.position[0], o.position[1], math.radians(o.rotation)) for o in scene.objects]
        shapes = [BoxShape(o.bbox["x"], o.bbox["y"]) for o in scene.objects]
        for obj, shape, p in zip(scene.objects, shapes, placements):  # a synthetic bbox is the box placed
            assert polygon_distance(outline(obj), shape.posed(p)) == 0.0
            assert np.allclose(np.sort(outline(obj), axis=0), np.sort(shape.posed(p), axis=0), atol=1e-9)
        for shape, p in zip(shapes, placements):
            assert stage.reach[0][0] <= p.x <= stage.reach[0][1] and stage.reach[1][0] <= p.y <= stage.reach[1][1]
            assert fits(shape.footprint, p, *stage.top)
            assert distance_to_point(shape.footprint, p, (0.0, 0.0)) >= stage.robot_clearance
        for i in range(len(shapes)):
            for j in range(i + 1, len(shapes)):
                gap = polygon_distance(shapes[i].posed(placements[i]), shapes[j].posed(placements[j]))
                assert gap >= stage.object_margin - 1e-9
    # The sampler refuses what breaks a rule: a box wider than the reach area beside the robot never fits.
    layout = TableLayout.on_stage(stage)
    assert layout.try_place(BoxShape(0.5, 1.3), np.random.default_rng(0), 50) is None


def _random_outlines(rng, count: int, region) -> list[np.ndarray]:
    """Outlines of turned boxes of 3-25 cm standing in and around ``region`` ((x0, x1), (y0, y1))."""
    (x0, x1), (y0, y1) = region
    shapes = []
    for _ in range(count):
        size = rng.uniform(0.03, 0.25, 2)
        corners = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]) * size
        c, s = math.cos(a := rng.uniform(0, 2 * math.pi)), math.sin(a)
        centre = rng.uniform([x0 - 0.1, y0 - 0.1], [x1 + 0.1, y1 + 0.1])
        shapes.append(hull_2d(corners @ np.array([[c, -s], [s, c]]).T + centre))
    return shapes


def test_the_nearest_and_any_free_place_are_free_places_own_answers():
    """``first_free_place`` is ``free_places(...)[0]`` to the bit and ``has_free_place`` its emptiness, on empty,
    crowded and full boxes, with gaps, turns and preferred points; both answers occur."""
    from muble.stage.free_place import first_free_place, free_places, has_free_place

    rng = np.random.default_rng(11)
    region = ((0.28, 0.74), (-0.32, -0.04))
    lo, hi = (region[0][0], region[1][0]), (region[0][1], region[1][1])
    answers = set()
    for trial in range(150):
        obstacles = _random_outlines(rng, int(rng.integers(0, 9)), region)
        held = _random_outlines(rng, 1, ((-0.01, 0.01), (-0.01, 0.01)))[0]
        gap, yaw = float(rng.choice([0.0, 0.015, 0.02, 0.06])), float(rng.choice([0.0, rng.uniform(-3, 3)]))
        prefer = None if trial % 3 else rng.uniform(lo, hi)
        places = free_places(lo, hi, held, obstacles, prefer, gap, 0.01, yaw)
        first = first_free_place(lo, hi, held, obstacles, prefer, gap, 0.01, yaw)
        if places:
            assert first is not None and first.tobytes() == places[0].tobytes(), trial
        else:
            assert first is None, trial
        assert has_free_place(lo, hi, held, obstacles, gap, 0.01, yaw) == bool(places), trial
        answers.add(bool(places))
    assert answers == {True, False}
    empty = ((0.3, 0.0), (0.2, 0.1))  # a box with no centre
    assert first_free_place(*empty, held, []) is None and not has_free_place(*empty, held, [])


def test_a_search_builds_only_the_regions_and_outlines_its_answer_needs(monkeypatch):
    """A box far from every obstacle is answered without a forbidden region or an outline built; a crowded one
    builds the regions next to the answer only, and each footprint's outline once."""
    from muble.stage import free_place
    from muble.stage.free_place import Footprint, first_free_place, free_places, has_free_place

    built = []
    forbidden = free_place.forbidden
    monkeypatch.setattr(free_place, "forbidden", lambda *a: built.append(1) or forbidden(*a))

    def footprint(shape):
        def build():
            outlines.append(1)
            return shape
        return Footprint(shape, build)

    outlines = []
    square = np.array([[-0.02, -0.02], [0.02, -0.02], [0.02, 0.02], [-0.02, 0.02]])
    far = [footprint(square + [1.5, 1.5]), footprint(square + [-1.0, 0.3])]
    held = footprint(square)
    assert has_free_place((0.3, -0.3), (0.7, 0.3), held, far)
    assert np.allclose(first_free_place((0.3, -0.3), (0.7, 0.3), held, far), [0.5, 0.0], rtol=0, atol=1e-12)
    assert built == [] and outlines == []
    # An obstacle on the box's centre and one in its far corner: only the first decides the nearest place.
    near, corner = square * 3 + [0.5, 0.0], square + [0.3, -0.3]
    shapes = [footprint(near), footprint(corner)]
    want = free_places((0.3, -0.3), (0.7, 0.3), square, [near, corner])[0]
    built.clear()
    assert first_free_place((0.3, -0.3), (0.7, 0.3), held, shapes).tobytes() == want.tobytes()
    assert len(built) == 1 and len(outlines) == 2  # the held outline and the centre obstacle's
    first_free_place((0.3, -0.3), (0.7, 0.3), held, shapes)
    assert len(outlines) == 2  # built once


def test_outlines_are_built_once_per_object_and_never_stale():
    """The room check's memo gives one footprint per object as it stands, its outline ``outline``'s to the bit; a
    moved, turned or resized object (or another with the same id) gets its own, never the old one."""
    from muble.stage.footprint import Outlines

    memo = Outlines()
    obj = _object((0.3, 0.1, 0.02), yaw_quat(0.4), (0.5, -0.1))
    first = memo(obj)
    assert memo(obj) is first and first.outline is first.outline
    assert first.outline.tobytes() == outline(obj).tobytes() and not first.outline.flags.writeable
    # The corners it rules out far centres with hold the outline.
    assert polygon_distance(first.outline, hull_2d(first.around)) == 0.0
    assert sorted(map(tuple, first.outline)) == sorted(map(tuple, hull_2d(first.around)))
    for changed in (dataclasses.replace(obj, position=np.array([0.52, -0.1, 0.0])),
                    dataclasses.replace(obj, orientation=yaw_quat(0.5)),
                    dataclasses.replace(obj, bbox={"x": 0.3, "y": 0.12, "z": 0.02}),
                    dataclasses.replace(obj, model="other", bbox={"x": 0.2, "y": 0.1, "z": 0.02})):
        again = memo(changed)
        assert again is not first and again.outline.tobytes() == outline(changed).tobytes()
    obj.position = np.array([0.6, 0.1, 0.0])  # moved in place
    assert memo(obj) is not first and memo(obj).outline.tobytes() == outline(obj).tobytes()
