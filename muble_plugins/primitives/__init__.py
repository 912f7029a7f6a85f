"""Built-in primitive actions: move, approach, close/open gripper, lift, lower, weigh, reweigh, squeeze, push, balance, shake,
move_vel.

Composite actions (pick up = approach + close_gripper + lift) are sequences of these and need no code here.
"""
from muble import PluginRecord, hookimpl


@hookimpl
def muble_register_primitives() -> list[PluginRecord]:
    from muble_plugins.primitives.gripper import CloseGripper, OpenGripper, Squeeze, Weigh
    from muble_plugins.primitives.approach import Approach
    from muble_plugins.primitives.lift import Lift
    from muble_plugins.primitives.lower import Lower
    from muble_plugins.primitives.move import Move
    from muble_plugins.primitives.move_vel import MoveVel
    from muble_plugins.primitives.probing import Balance, Push, Shake
    from muble_plugins.primitives.reweigh import Reweigh

    return [
        PluginRecord("move", Move, "move the hand above an object or a table part (left/right/front/back/centre)"),
        PluginRecord("approach", Approach, "bring the open hand into the grasp pose of an object"),
        PluginRecord("close_gripper", CloseGripper, "close the fingers; grasps the object between them"),
        PluginRecord("open_gripper", OpenGripper, "open the fingers; releases the held object"),
        PluginRecord("lift", Lift, "raise the hand straight up by a height (m)"),
        PluginRecord("lower", Lower, "put the held object down on an object or a free place on a table part"),
        PluginRecord("weigh", Weigh, "measure the weight (g) of the held object with the wrist force sensor"),
        PluginRecord("reweigh", Reweigh, "weigh the held object again, independently: set it down, zero the sensor, "
                                         "pick it up again and read"),
        PluginRecord("squeeze", Squeeze, "measure the stiffness (N/m) of the object between the fingers"),
        PluginRecord("push", Push, "measure the friction coefficient of the held object, pushed along the table"),
        PluginRecord("balance", Balance, "measure the centre of mass (mm off its base centre) of the held object"),
        PluginRecord("shake", Shake, "shake the held object: whether loose contents rattle inside"),
        PluginRecord("move_vel", MoveVel, "move the hand at a constant velocity (m/s) for a duration (s)"),
    ]


@hookimpl
def muble_register_properties() -> list:
    from muble_plugins.primitives.properties import BUILTIN

    return list(BUILTIN)
