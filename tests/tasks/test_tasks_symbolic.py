"""The symbolic world has one mechanism for every primitive: each plays its own ``symbolic_effect``."""
from __future__ import annotations

import ast
import inspect

import muble_plugins.common.symbolic as symbolic
from muble import ActionCall, PrimitiveAction, get_registry
from muble.core.symbolic import CARRIED_TO
from muble_plugins.common.symbolic import PRIMITIVES, SymbolicWorld
from muble_plugins.common.synthetic import sample_scenes


def test_each_builtin_primitive_declares_its_symbolic_effect_beside_its_execution():
    registry = get_registry()
    for name in PRIMITIVES:
        cls = registry.get("primitive", name).record.factory
        assert cls.symbolic_effect is not PrimitiveAction.symbolic_effect, name
        assert inspect.getmodule(cls.symbolic_effect) is inspect.getmodule(cls.execute), name


def test_the_symbolic_world_names_no_primitive():
    tree = ast.parse(inspect.getsource(symbolic.SymbolicWorld))
    names = {"move", "approach", "close_gripper", "open_gripper", "lift", "lower", "weigh", "squeeze"}
    found = [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and n.value in names]
    compared = [ast.unparse(n) for n in ast.walk(tree) if isinstance(n, ast.Compare)
                and any(isinstance(s, ast.Attribute) and s.attr == "name" for s in [n.left, *n.comparators])]
    assert found == [] and compared == []


def test_a_carried_object_goes_down_on_the_spot_move_chose_and_the_world_reports_measurements():
    scene = sample_scenes(3, 1)[0]
    obj = next(o for o in scene.objects if o.pickupable)
    world = SymbolicWorld(scene)
    for call in (ActionCall("move", {"target": obj.id}), ActionCall("approach", {"target": obj.id}),
                 ActionCall("close_gripper", {"target": obj.id}), ActionCall("lift"), ActionCall("weigh"),
                 ActionCall("move", {"target": "left"})):
        assert world.apply(call).success, call
    held = world.scene.object(obj.id)
    spot = list(held.extra[CARRIED_TO])
    assert CARRIED_TO not in world.observe(None, 0).scene.object(obj.id).extra  # ground truth only
    assert world.measured == {obj.id: {"weight": obj.weight_gt}}
    assert world.apply(ActionCall("lower", {"target": "left"})).success
    assert list(held.position) == spot and held.extra["touching"] == ["table"] and CARRIED_TO not in held.extra
    assert held.extra["gripper_over"] and not held.extra["in_hand"]


def test_a_failed_effect_names_the_call():
    world = SymbolicWorld(sample_scenes(3, 1)[0])
    assert world.apply(ActionCall("lift")).failure_reason == \
        "lift(): lifting needs a grasped object resting on its support"
    assert world.apply(ActionCall("lift", {"speed": 2})).failure_reason.startswith("lift(speed=2): bad parameters")
