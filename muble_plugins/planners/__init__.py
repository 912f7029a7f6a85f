"""Built-in motion planners: OMPL sampling-based joint-space planning and straight-line Cartesian motion.

OMPL itself is imported only when a path has to be sampled, not when the records are gathered.
"""
from muble import PluginRecord, hookimpl


@hookimpl
def muble_register_planners() -> list[PluginRecord]:
    from muble_plugins.planners.ompl_planner import OmplPlanner, OmplPlannerConfig
    from muble_plugins.planners.straight_line import StraightLinePlanner, StraightLinePlannerConfig

    return [
        PluginRecord("ompl", OmplPlanner, "OMPL joint-space planner (RRTConnect by default) with path "
                     "simplification and trapezoidal timing", OmplPlannerConfig, takes_config=True),
        PluginRecord("straight_line", StraightLinePlanner, "straight-line Cartesian motion of the hand for short "
                     "moves (approach, lift, lower)", StraightLinePlannerConfig, takes_config=True),
    ]
