"""Instruction generation on sampled scenes: valid, unambiguous, deterministic, in the original schema."""
from __future__ import annotations

import numpy as np
import pytest

from muble.programs.descriptions import SceneIndex
from muble.programs.descriptions import ATTRIBUTE_STEP, describe
from muble.programs.program import execute, outputs_match
from muble_plugins.common.geometry import room_on_part
from muble_plugins.common.synthetic import sample_scenes
from muble_plugins.tasks.generator import generate_for_template, generate_instructions
from muble_plugins.tasks.templates import TEMPLATES, OptionContext

STEP_ATTRIBUTE = {step: attr for attr, step in ATTRIBUTE_STEP.items()}


@pytest.fixture(scope="module")
def generated():
    scenes = sample_scenes(11, 60)
    return [(s, generate_instructions(s, np.random.default_rng([11, s.image_index]))) for s in scenes]


def _chains(program):
    """(description, filtered ids) of every attribute-filter chain of a program."""
    chains, desc, ids = [], [], None
    for step in program:
        if step["type"] in ("scene", "stack") or step["type"] not in STEP_ATTRIBUTE and desc:
            if desc:
                chains.append((tuple(desc), ids))
            desc = []
        if step["type"] in STEP_ATTRIBUTE:
            desc.append((STEP_ATTRIBUTE[step["type"]], step["input_value"]))
            ids = step["output"]
    if desc:
        chains.append((tuple(desc), ids))
    return chains


def test_every_template_yields_where_the_scene_allows(generated):
    for scene, instructions in generated:
        made = {i.template_id for i in instructions}
        index = SceneIndex(scene)
        for name, template in TEMPLATES.items():
            context = OptionContext(index, 2.0)
            has_options = any(template.feasible is None or template.feasible(o, context)
                              for o in template.options(context))
            assert (name in made) == has_options, (name, scene.image_index)
    counts = {n: sum(any(i.template_id == n for i in ins) for _, ins in generated) for n in TEMPLATES}
    assert all(c > 0 for c in counts.values()), counts


def test_instructions_are_5_to_16_words_and_programs_replay(generated):
    for scene, instructions in generated:
        for ins in instructions:
            assert 5 <= len(ins.instruction.split()) <= 16, ins.instruction
            trace = execute(ins.program, scene, weights="ground_truth")
            assert outputs_match(ins.program, trace) == [], ins.instruction


def test_descriptions_denote_exactly_their_objects(generated):
    for scene, instructions in generated:
        for ins in instructions:
            for desc, ids in _chains(ins.program):
                denoted = [o.id for o in scene.objects if all(getattr(o, a) == v for a, v in desc)]
                if ins.template_id == "remove":
                    denoted = [i for i in denoted if i in ids] if ids is not None else denoted
                assert denoted == ids, (ins.instruction, desc, ids)
                phrase = describe(desc, many=len(ids) > 1 or ins.template_id == "remove")
                assert phrase in ins.instruction, (phrase, ins.instruction)
                if "heaviest" not in ins.instruction and "lightest" not in ins.instruction \
                        and ins.template_id not in ("remove", "measure_weight_multi"):
                    assert len(ids) == 1, ins.instruction


def test_generation_is_deterministic_from_seed_and_scene():
    scene = sample_scenes(5, 1)[0]
    a = generate_instructions(scene, np.random.default_rng(3), per_template=2)
    b = generate_instructions(scene, np.random.default_rng(3), per_template=2)
    assert [(i.instruction, i.program) for i in a] == [(i.instruction, i.program) for i in b]


def test_weight_superlatives_have_a_margin(generated):
    for scene, instructions in generated:
        for ins in instructions:
            for k, step in enumerate(ins.program):
                if step["type"] == "filter_weight":
                    group = sorted(scene.object(i).weight_gt for i in ins.program[k - 1]["output"])
                    gap = group[-1] - group[-2] if step["input_value"] == "heaviest" else group[1] - group[0]
                    assert gap >= 2.0, ins.instruction


def test_objects_are_only_sent_to_table_parts_with_room_for_them():
    """The left part holds two plates and a chopping board: the mug (object 3) has no room there (the placing
    primitives find no free place for it either), but it has on the front part; instructions only use the latter."""
    from pathlib import Path

    from muble.io.scene_io import load_scene

    scene = load_scene(Path(__file__).parent / "data" / "left_part_full.json")
    mug, large_plate, small_plate = scene.object(3), scene.object(0), scene.object(1)
    assert not room_on_part(scene, [mug], "left")
    assert room_on_part(scene, [mug], "front")
    made = generate_for_template(TEMPLATES["move_single"], scene, np.random.default_rng(0), count=-1)
    moves = {(ins.program[-2]["output"][0], ins.program[-1]["input_value"]) for ins in made}
    assert (3, "front") in moves and (3, "left") not in moves
    # Objects put down in turn: the second must fit beside the first (the right part takes either plate).
    assert room_on_part(scene, [large_plate], "right") and room_on_part(scene, [small_plate], "right")
    assert not room_on_part(scene, [large_plate, small_plate], "right")


def test_room_on_a_part_takes_footprints_as_the_objects_stand():
    """A bbox is the object's own extents: a thin board fits a 6 cm corridor between two walls along its length,
    not across it (the free-place rule of the placing primitives on the boxes' outlines, 2 cm apart)."""
    from muble import SceneGraph, SceneObject
    from muble.stage.geometry import yaw_quat

    def box(i, x, y, size, yaw=0.0):
        return SceneObject(id=i, model="board", name="chopping board", shape="cuboid", size="large",
                           material="wooden", colour="brown", position=np.array([x, y, 0.0]),
                           orientation=yaw_quat(yaw), weight_gt=100.0, stackable=False, stack_base=False,
                           pickupable=True, bbox={"x": size[0], "y": size[1], "z": 0.02})

    walls = [box(0, 0.5, -0.375, (0.8, 0.25)), box(1, 0.5, -0.095, (0.8, 0.19))]  # y < -0.25 and y > -0.19
    along, across = box(2, 0.5, 0.2, (0.30, 0.01)), box(3, 0.5, 0.2, (0.30, 0.01), yaw=np.pi / 2)
    scene = SceneGraph(objects=[*walls, along, across])
    assert room_on_part(scene, [along], "left")
    assert not room_on_part(scene, [across], "left")
    # Turned a quarter round, a box's x and y extents are the other way about on the table: the same room.
    assert room_on_part(scene, [box(3, 0.5, 0.2, (0.01, 0.30), yaw=np.pi / 2)], "left")


def _room_as_the_rule_states(scene, movers, part, gap=0.02, spacing=0.01) -> bool:
    """The room check written plainly: every mover, in turn, at ``free_places``' first place on the part, beside
    the outlines of the objects that stay and of those put down before it."""
    from muble.stage.footprint import outline
    from muble.stage.free_place import free_places
    from muble.stage.table import scene_part_region

    (x0, x1), (y0, y1) = scene_part_region(scene, part)
    moving = {o.id for o in movers}
    obstacles = [outline(o) for o in scene.objects if o.id not in moving]
    for obj in movers:
        held = outline(obj) - np.asarray(obj.position[:2], dtype=float)
        places = free_places((x0, y0), (x1, y1), held, obstacles, gap=gap, spacing=spacing)
        if not places:
            return False
        obstacles.append(held + places[0])
    return True


def test_the_room_check_answers_as_the_rule_states_it():
    """The room check builds outlines and forbidden regions only where they decide the answer (one memo per
    scene): its answers are the plain rule's, for one to three movers in every order on every part, with both
    answers occurring (a crowded left part too)."""
    import itertools
    from pathlib import Path

    from muble.io.scene_io import load_scene
    from muble.stage.footprint import Outlines

    crowded = load_scene(Path(__file__).parent / "data" / "left_part_full.json")
    answers = []
    for scene in [crowded, *sample_scenes(21, 8)]:
        memo = Outlines()
        tuples = [t for k in (1, 2, 3) for t in itertools.permutations(scene.objects, k)][:30]
        for movers in tuples:
            for part in ("left", "right", "front", "back"):
                want = _room_as_the_rule_states(scene, list(movers), part)
                assert room_on_part(scene, list(movers), part, outlines=memo) == want, ([o.id for o in movers], part)
                answers.append(want)
    assert True in answers and False in answers
