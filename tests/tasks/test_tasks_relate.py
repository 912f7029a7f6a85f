"""filter_relate: the objects left, right, in front of or behind one object, as the original relationships."""
from __future__ import annotations

import numpy as np
import pytest

from muble import PlanningError, SceneGraph, SceneObject
from muble.io.instructions_io import program_step
from muble.io.scene_io import load_scenes
from muble.programs.program import RELATIONS, execute, related


def _scene(*xy) -> SceneGraph:
    return SceneGraph(objects=[
        SceneObject(id=i, model="mug1", name="mug" if i else "plate", shape="cylindrical", size="small",
                    material="ceramic", colour="red", position=np.array([x, y, 0.0]),
                    orientation=np.array([1.0, 0, 0, 0]), weight_gt=100.0 + i, stackable=True, stack_base=False,
                    pickupable=True) for i, (x, y) in enumerate(xy)])


def test_relations_follow_the_table_parts_naming():
    scene = _scene((0.5, 0.0), (0.4, -0.2), (0.6, 0.1))
    assert related(scene, 0, "left") == [1] and related(scene, 0, "right") == [2]
    assert related(scene, 0, "front") == [2] and related(scene, 0, "behind") == [1]


def test_relations_reproduce_the_original_relationships(reference_dir):
    _, scenes = load_scenes(reference_dir / "NS_AP_demo_scenes.json")
    for scene in scenes:
        for relation in RELATIONS:
            recorded = scene.relationships[relation]
            assert [sorted(related(scene, o.id, relation)) for o in scene.objects] == [sorted(r) for r in recorded]


def test_filter_relate_in_a_program():
    scene = _scene((0.5, 0.0), (0.4, -0.2), (0.6, 0.1), (0.45, -0.1))
    program = [program_step("scene"), program_step("filter_name", input_value="plate"),
               program_step("filter_relate", input_value="left"), program_step("filter_name", input_value="mug"),
               program_step("query_weight")]
    assert execute(program, scene, weights="ground_truth").final == [101.0, 103.0]


@pytest.mark.parametrize("steps,says", [
    ([("filter_name", "mug"), ("filter_relate", "left")], "relates to one object, but the steps before it give 3"),
    ([("filter_name", "plate"), ("filter_relate", "above")], "unknown relation 'above'"),
])
def test_filter_relate_errors_say_what_to_change(steps, says):
    scene = _scene((0.5, 0.0), (0.4, -0.2), (0.6, 0.1), (0.45, -0.1))
    program = [program_step("scene")] + [program_step(t, input_value=v) for t, v in steps]
    with pytest.raises(PlanningError, match=says):
        execute(program, scene, weights="ground_truth")
