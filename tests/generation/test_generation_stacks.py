"""The generator's stack check: a stack the ground truth builds must stand upright in physics."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from muble import get_registry
from muble.generation import checks
from muble.generation.config import GeneratorConfig
from muble.io.scene_io import load_scene
from muble.programs.program import stack_pairs, stacked_pairs
from muble.sim.build import object_models
from muble.sim.env import ROBOT_DEFAULTS
from muble.stage.layout import Placement

DATA = Path(__file__).parent / "data"


def _check(name: str, chains: list[list[int]]) -> str | None:
    scene = load_scene(DATA / name)
    models = object_models(scene, get_registry().create("object_set", "shopvrb2"))
    placements = [Placement(float(o.position[0]), float(o.position[1]), float(np.radians(o.rotation)))
                  for o in scene.objects]
    cfg = GeneratorConfig()
    return checks.stacks_stand([models[o.id] for o in scene.objects], placements, stack_pairs(chains),
                               cfg.table_x, cfg.table_y, ROBOT_DEFAULTS["timestep"])


def test_a_glass_into_a_bowl_on_a_food_box_stands():
    # glass3 (object 2) into bowl2 (3) on the cylindrical food box (0): the oracle stacks it in physics.
    assert _check("glass_into_a_bowl_on_a_food_box.json", [[2], [3], [0]]) is None


def test_a_mug_wider_than_a_small_bowls_bottom_leans_and_is_refused():
    # mug2 (2) into bowl3 at 0.85 scale (1) on a chopping board (0): the mug's base rests on the bowl's sloping
    # wall and tips towards its handle (the episode's put-down ended 25 degrees over).
    reason = _check("mug_into_a_small_bowl_on_a_board.json", [[2], [1], [0]])
    assert reason is not None and reason.startswith("object 2 on object 1 comes to rest leaning")
    # The bowl alone on the board stands: the check names the pair that does not.
    assert _check("mug_into_a_small_bowl_on_a_board.json", [[1], [0]]) is None


def test_a_bowl_whose_way_onto_a_food_box_passes_a_wine_glass_is_refused():
    # bowl3 at 1.15 scale (4, 15.6 cm wide) onto food box 2 (1): centred over the box its rim overlaps the wine
    # glass (0) standing 13 cm from the box's centre; the put-down's straight descent was blocked there.
    reason = _check("bowl_onto_a_food_box_beside_a_wine_glass.json", [[4], [1]])
    assert reason == "object 4 set down on object 1 comes within 5 mm of object 0 on the way"


def test_stacked_pairs_reads_the_programs_stack_output_bottom_pair_first():
    program = [{"type": "scene"}, {"type": "stack", "output": [[2], [1], [0]]}]
    assert stacked_pairs(program) == [(1, 0), (2, 1)]
    assert stacked_pairs([{"type": "scene"}, {"type": "pick_up", "output": [3]}]) == []
