"""Value types exchanged through the core interfaces."""
from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from muble.core.errors import PlanningError, unknown_name

# Segmentation labels besides object ids (objects use their scene id, >= 0).
SEG_BACKGROUND = -1
"""Segmentation label of pixels that show no object, table or robot (objects are labelled with their id, >= 0)."""
SEG_TABLE = -2
"""Segmentation label of the table's pixels."""
SEG_ROBOT = -3
"""Segmentation label of the robot's pixels (arm, gripper and mount)."""
TABLE_PARTS = ("left", "right", "front", "back", "centre")
"""The table's named parts, as seen from the scene camera (where each lies on a stage: ``muble.stage.table``)."""
_PART_ALIASES = {"center": "centre"}


def canonical_part(part: str) -> str:
    """The part's name (``center`` is ``centre``); an unknown name raises ``PlanningError`` listing the valid ones."""
    name = _PART_ALIASES.get(part, part)
    if name not in TABLE_PARTS:
        raise PlanningError(unknown_name("table part", str(part), TABLE_PARTS))
    return name


@dataclass
class Frame:
    """One rendered view. ``depth`` is metric distance along the optical axis (metres).

    ``segmentation`` holds, per pixel, the scene id of the object seen there, or one of
    ``SEG_BACKGROUND``, ``SEG_TABLE``, ``SEG_ROBOT``.
    """

    camera: str
    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray | None = None  # (H, W) float32, metres
    segmentation: np.ndarray | None = None  # (H, W) int32
    normals: np.ndarray | None = None  # (H, W, 3) float32, world frame

    @property
    def shape(self) -> tuple[int, int]:
        return self.rgb.shape[0], self.rgb.shape[1]

    def mask(self, label: int) -> np.ndarray:
        """Boolean mask of one segmentation label."""
        if self.segmentation is None:
            raise ValueError(f"frame from camera '{self.camera}' was rendered without segmentation")
        return self.segmentation == label


@dataclass
class Pose:
    """Position (metres) and orientation as a unit quaternion (w, x, y, z), world frame."""

    pos: np.ndarray
    quat: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))

    def __post_init__(self) -> None:
        self.pos = np.asarray(self.pos, dtype=float).reshape(3)
        self.quat = np.asarray(self.quat, dtype=float).reshape(4)


@dataclass
class JointGoal:
    """A motion goal given directly as a joint configuration."""

    q: np.ndarray


@dataclass
class PoseGoal:
    """A motion goal given as an end-effector pose; the planner solves IK."""

    pose: Pose
    position_tolerance: float = 0.005
    orientation_tolerance: float = 0.05  # radians


@dataclass
class Trajectory:
    """A joint-space path with timing: ``q[i]`` is to be reached at ``t[i]`` seconds."""

    q: np.ndarray  # (N, dof)
    t: np.ndarray  # (N,)
    joint_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        self.q = np.atleast_2d(np.asarray(self.q, dtype=float))
        self.t = np.asarray(self.t, dtype=float).reshape(-1)
        if len(self.q) != len(self.t):
            raise ValueError(f"trajectory has {len(self.q)} waypoints but {len(self.t)} times")
        if len(self.t) > 1 and np.any(np.diff(self.t) <= 0):
            raise ValueError("trajectory times must increase strictly")

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    def sample(self, time: float) -> np.ndarray:
        """Joint configuration at ``time`` (linear interpolation, clamped at both ends)."""
        return np.array([np.interp(time, self.t, self.q[:, j]) for j in range(self.q.shape[1])])


class Track(enum.StrEnum):
    """What an agent is told about the task (``muble.episode.modes``, ``docs/protocol.md``)."""

    program = "program"  # the instruction's text and its program, nothing computed on the ground truth
    language = "language"  # the text only


class ObservationMode(enum.StrEnum):
    """What an agent is told about the scene (``muble.episode.modes``, ``docs/protocol.md``)."""

    graph = "graph"  # ids, poses, visible attributes, contact state
    masks = "masks"  # images + per-object ids, masks, poses, bboxes, contact state; no attribute words
    image = "image"  # images only; a pixel of the latest image names an object in an action


class Outcome(str, enum.Enum):
    """Episode outcomes; everything but SUCCESS is a failure class of the taxonomy.

    Whose fault a failure is: ``INVALID_ACTION`` is the agent's (a call no primitive accepts: unknown name,
    unknown/missing parameter, wrong type, a target not in the scene), and so is ``AGENT_ERROR`` (the agent
    raised); ``INVALID_DATA`` and ``BROKEN_SCENE`` are the data's (a file that cannot be read or built; a scene that
    does not rest or breaks the physics); the others are the agent's course of action.
    """

    SUCCESS = "success"
    PROGRAM_FAILURE = "program_failure"
    INCORRECT_ANSWER = "incorrect_answer"
    EXECUTION_ERROR = "execution_error"
    SCENE_INCONSISTENCY = "scene_inconsistency"
    LOOP_DETECTED = "loop_detected"
    TIMEOUT = "timeout"
    BROKEN_SCENE = "broken_scene"
    INVALID_ACTION = "invalid_action"
    INVALID_DATA = "invalid_data"
    AGENT_ERROR = "agent_error"


@dataclass
class ActionCall:
    """A primitive action by registry name with its parameters, e.g. ``ActionCall("approach", {"target": 3})``."""

    name: str
    params: dict[str, Any] = field(default_factory=dict)

    def __str__(self) -> str:
        # An agent's malformed call (params not a mapping) is reported and logged as it came, never a crash.
        if not isinstance(self.params, dict):
            return f"{self.name}(params={self.params!r:.200})"
        args = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"{self.name}({args})"


@dataclass
class Answer:
    """A final answer to a query instruction (e.g. measured weights in grams)."""

    value: Any


@dataclass
class ActionResult:
    """What a primitive reports back to the action loop."""

    success: bool
    measurement: Any = None
    failure_reason: str | None = None
    info: dict[str, Any] = field(default_factory=dict)


@dataclass
class Observation:
    """What an agent sees after each primitive: images, scene graph, measurements, last result."""

    scene: Any  # muble.core.scene.SceneGraph
    images: dict[str, Frame] = field(default_factory=dict)
    measurements: dict[str, Any] = field(default_factory=dict)
    last_result: ActionResult | None = None
    step: int = 0
