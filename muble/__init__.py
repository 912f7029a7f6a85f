"""MuBlE: a simulation environment and benchmark for task planning in robot manipulation."""
from muble.quiet import quiet_third_party

# Before anything imports robosuite: its messages about optional parts MuBlE does not use are dropped in every
# process that imports MuBlE, spawned workers included (MUBLE_VERBOSE=1 keeps them).
quiet_third_party()

from muble.core.errors import (
    ConfigError,
    InitialStateError,
    MubleError,
    PhysicsError,
    PlanningError,
    PluginError,
    RenderError,
    SceneValidationError,
)
from muble.core.environment import Environment, EnvironmentNames, TableTop
from muble.core.interfaces import (
    Agent,
    CollisionWorld,
    Disturbance,
    DisturbanceEvent,
    Instruction,
    MotionPlanner,
    ObjectSet,
    PrimitiveAction,
    Renderer,
    Sensor,
    Task,
    Trainer,
)
from muble.core.physical_properties import Property
from muble.core.training import TrainingRun
from muble.core.params import Param
from muble.core.ranges import bounded
from muble.core.scene import RLE, SceneGraph, SceneObject
from muble.core.types import (
    SEG_BACKGROUND,
    SEG_ROBOT,
    SEG_TABLE,
    ActionCall,
    ActionResult,
    Answer,
    Frame,
    JointGoal,
    Observation,
    ObservationMode,
    Outcome,
    Pose,
    PoseGoal,
    Track,
    Trajectory,
)
from muble.plugins import PluginRecord, get_registry, hookimpl
from muble.plugins import deprecated as _deprecated

# The modules that moved answer to their old names for one minor release, each import warning with the new name.
_deprecated.install()

__version__ = "0.1.0"
"""MuBlE's version (also in ``pyproject.toml``); manifests record it beside the code revision."""

__all__ = [
    "SEG_BACKGROUND", "SEG_ROBOT", "SEG_TABLE", "ActionCall", "ActionResult", "Agent", "Answer", "CollisionWorld",
    "ConfigError", "Disturbance", "DisturbanceEvent", "Environment", "EnvironmentNames", "Frame", "Instruction", "JointGoal", "MotionPlanner", "MubleError", "ObjectSet", "Observation",
    "ObservationMode", "Outcome", "Param", "PhysicsError", "PlanningError", "PluginError", "PluginRecord", "Pose", "PoseGoal",
    "PrimitiveAction", "Property", "RLE", "RenderError", "Renderer", "SceneGraph", "SceneObject", "SceneValidationError",
    "Sensor", "TableTop", "Task", "Track", "Trainer", "TrainingRun", "Trajectory", "__version__", "bounded", "get_registry", "hookimpl", "InitialStateError",
]
