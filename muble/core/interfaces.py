"""The plugin interfaces, one per plugin kind (``muble.plugins.KINDS``). Implementations live in plugins and reach
the core only by registry name.

Every optional hook has a documented no-op default, so a plugin overrides only what it needs.
The environment they receive is ``muble.core.environment.Environment``, the one interface plugins may rely on.
"""
from __future__ import annotations

import functools
import inspect
import warnings
from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

# The planner and the collision world it plans in are defined beside the environment that hands them to primitives
# (``Environment.planner``, ``Environment.collision_world``), which imports nothing from here; they are interfaces of
# this module all the same (``INTERFACES``, ``muble.core.interfaces.CollisionWorld``).
from muble.core.environment import CollisionWorld, Environment, MotionPlanner  # noqa: F401 - re-exported
from muble.core.errors import MubleDeprecationWarning
from muble.core.types import ActionCall, ActionResult, Answer, Frame, Observation, ObservationMode, Outcome, Track

if TYPE_CHECKING:  # pragma: no cover
    import mujoco

    from muble.core.objects import ObjectModel, ObjectSpec
    from muble.core.params import Param
    from muble.core.scene import SceneGraph
    from muble.core.training import TrainingRun


class Renderer(ABC):
    """Turns simulation states into frames.

    ``setup`` is called once per scene with the scene graph and the compiled MuJoCo model; a keyframe renderer
    builds its scene there and afterwards only moves transforms. Called again with the same scene graph and model
    objects it must return at once (callers need not remember what a shared renderer was last set up with). ``render`` draws the state in ``data`` as seen by
    the MuJoCo camera named ``camera`` and returns RGB, depth and segmentation from one render.
    """

    @abstractmethod
    def setup(self, scene: "SceneGraph", model: "mujoco.MjModel") -> None: ...

    @abstractmethod
    def render(self, data: "mujoco.MjData", camera: str) -> Frame: ...

    def close(self) -> None:
        """Release GPU/GL resources and scene data. Optional; default does nothing."""


class PrimitiveAction(ABC):
    """A named, parameterised action (``approach(target=3)``, ``move_vel(velocity, duration)``).

    Subclasses declare ``params``: the parameters they accept, as names (any value) or typed
    ``muble.core.params.Param`` records (object id, table part, bounded number …); the action loop checks every
    agent's call against them before it runs (``Outcome.INVALID_ACTION`` otherwise). ``execute`` plans through the
    environment's planner, drives the physics loop until done or failed and returns an ``ActionResult`` whose
    ``success`` says whether the primitive's end state was reached (it checks it: tracking error, lost grasp …);
    a ``PlanningError`` is a failed action that left the environment as it was. A primitive renders nothing: the
    action loop renders the keyframe afterwards.
    """

    params: ClassVar[tuple["str | Param", ...]] = ()
    # Where a successful call leaves the hand with respect to its ``target`` object, for the flags the physical
    # world reports: "over" (hovering above it, ``gripper_over``), "grasp" (open, in its grasp pose,
    # ``approached``) or None (neither).
    hand_at_target: ClassVar[str | None] = None
    # What a successful call's ``ActionResult.measurement`` is: a measured property of the held object ("weight" in
    # g, "stiffness" in N/m, as in ``env.measurements``) or None. Sequence files record the last weight.
    measures: ClassVar[str | None] = None
    # The unit of that measurement ("g", "N/m"), for reports; "" where it has none.
    measure_unit: ClassVar[str] = ""
    # The measuring procedure itself, ``reading(env, ...)`` (a ``staticmethod``), for a primitive that measures: what
    # ``execute`` calls once it has checked that there is something to measure; written against the environment's
    # sensing members, as the built-in ones are (``muble_plugins.primitives.measure``, ``.handling``). The
    # deprecated ``Environment.<name>()`` of the earlier API forwards to it. None for a primitive that measures
    # nothing.
    reading: ClassVar[Any] = None

    def __init__(self, **params: Any) -> None:
        from muble.core.params import specs

        unknown = sorted(set(params) - {p.name for p in specs(self.params)})
        if unknown:
            from muble.core.errors import ConfigError

            raise ConfigError(
                f"primitive '{type(self).__name__}' got unknown parameter(s) {unknown}; "
                f"it accepts: {', '.join(p.name for p in specs(self.params)) or '(none)'}"
            )
        self.arguments = dict(params)

    @abstractmethod
    def execute(self, env: "Environment") -> ActionResult: ...

    def feasible(self, env: "Environment") -> None:
        """Raise ``PlanningError`` when this primitive could not succeed from the environment's current state,
        without moving anything (the scene generator asks ``approach`` whether every object can be grasped).
        Optional; the default raises nothing (no check)."""


    def symbolic_effect(self, scene: "SceneGraph") -> ActionResult:
        """What the primitive does in the symbolic world (no physics): change ``scene`` (ground truth; the
        gripper flags in ``SceneObject.extra``, read and set with ``muble.core.symbolic``) and return the result;
        the world prefixes a failure's reason with the call. Ground-truth plans of tasks that use the primitive are
        rolled out through it. Optional; by default the primitive fails there as not modelled."""
        return ActionResult(False, failure_reason=f"primitive '{type(self).__name__}' has no symbolic model "
                                                  "(PrimitiveAction.symbolic_effect)")


class Sensor(ABC):
    """Reads the simulation. ``read`` is called on demand; ``on_step`` after every control step."""

    @abstractmethod
    def read(self, env: "Environment") -> dict[str, Any]: ...

    def reset(self, env: "Environment") -> None:
        """Called after every environment reset. Optional; default does nothing."""

    def on_step(self, env: "Environment") -> None:
        """Called after every control step. Optional; default does nothing. Keep it cheap."""


@dataclass
class Instruction:
    """One generated instruction in the SHOP-VRB2 instruction schema."""

    instruction: str
    program: list[dict[str, Any]]
    template_id: str
    task_id: str
    image_filename: str = ""
    image_index: int = 0
    split: str = ""
    extra: dict[str, Any] = field(default_factory=dict)


class Task(ABC):
    """A task template family: generates instructions, plans towards its goal and judges success.

    ``next_actions`` is the task's closed-loop planner: the built-in oracle agent asks the instruction's task for
    the next primitives from what it observes, so any task plugin that implements it is solvable by the oracle.
    ``judge`` receives the whole episode record; its default judges the final scene and answer with ``check``.
    """

    task_id: ClassVar[str] = ""

    @abstractmethod
    def generate(self, scene: "SceneGraph", rng: np.random.Generator) -> list[Instruction]:
        """Every valid instruction of this family for ``scene`` (possibly none)."""

    @abstractmethod
    def ground_truth(self, instruction: Instruction, scene: "SceneGraph") -> list[ActionCall]:
        """The primitive sequence that solves ``instruction`` in ``scene``."""

    @abstractmethod
    def check(self, instruction: Instruction, scene: "SceneGraph", answer: Answer | None) -> Outcome:
        """Judge the final ground-truth scene graph (and answer, for queries)."""

    def next_actions(self, instruction: Instruction, observation: Observation) -> list[ActionCall] | Answer:
        """The primitives that lead from the observed state towards the goal (empty when it holds), or the
        answer once a query can be answered. Called again after every primitive (closed loop) with what an agent
        may know (``muble.core.observation``): plan from the observation only. Optional, but without it the
        built-in oracle cannot solve the task; raise ``PlanningError`` when the goal cannot be reached."""
        raise NotImplementedError(f"task '{type(self).__name__}' does not plan towards its goal "
                                  "(Task.next_actions); the oracle agent cannot solve it")

    def admits(self, objects: list[Any]) -> bool:
        """Whether a scene of ``objects`` (``muble.core.objects.ObjectSpec``: sampled, not yet placed) could suit
        this task at all; the scene generator asks before it places them, and places a set only when this is true.
        A task whose instructions need something rare of the objects (weights close together) spares the
        placement of sets that lack it; it must never refuse a set that could suit. Optional; by default every set
        is placed."""
        return True

    def judge(self, instruction: Instruction, episode: Any) -> Outcome:
        """The outcome of a finished episode from its record (``muble.episode.EpisodeResult``: ``actions``,
        ``steps`` with each action's ``result`` and ``scene_gt``, ``answer``, ``final_scene``, ``initial_gt``; all
        ground truth). Optional; by default ``check`` on the final scene and answer."""
        return self.check(instruction, episode.final_scene, episode.answer)


class ObjectSet(ABC):
    """A catalogue of object models with physical properties.

    ``hidden_properties`` names object properties (scene-object fields or ``extra`` keys) that agents must not
    see beyond the ones always withheld (ground-truth weight and stiffness, see ``muble.core.observation``).
    ``physical_properties(spec)`` says which hidden physical properties (friction, centre of mass, loose contents)
    an object can carry, so the scene generator draws them for it when asked to; by default none.
    """

    hidden_properties: ClassVar[tuple[str, ...]] = ()

    @abstractmethod
    def categories(self) -> list[str]: ...

    @abstractmethod
    def sample(self, rng: np.random.Generator, category: str | None = None) -> "ObjectSpec":
        """A random object description (model, attributes, weight, stiffness) from the catalogue."""

    @abstractmethod
    def build(self, spec: "ObjectSpec") -> "ObjectModel":
        """The model for ``spec``: visual mesh, convex collision parts, mass, inertia, friction, grasp frames."""

    def default_stiffness(self, material: str) -> float | None:
        """The contact stiffness (N/m) of a scene object of ``material`` whose scene gives none (the original
        SHOP-VRB2 files have none), used when the environment is built. Optional; the default, ``None``, makes such
        an object a ``SceneValidationError``."""
        return None

    def physical_properties(self, spec: "ObjectSpec") -> tuple[str, ...]:
        """Which of the hidden physical properties the scene generator draws
        (``muble.core.physical_properties.PROPERTIES``: ``friction``, ``com_offset``, ``contents``) the object
        ``spec`` describes can carry; the generator draws those asked for (``GeneratorConfig.physical_properties``)
        for it and no others. ``contents`` needs a closed container (``ObjectModel.closed``). Optional; the
        default, none, leaves every object as its model builds it."""
        return ()


class Agent(ABC):
    """Maps an instruction and observation to the next primitive action or a final answer.

    ``privileged`` agents (the oracle) are given the program and the graph view whatever the run's track and
    observation mode, and their actions are expressed in the mode's action form (``muble.episode.modes``): they
    prove each mode solvable and are never a contestant.
    """

    privileged: bool = False

    def reset(self, instruction: Instruction, observation: Observation, *, track: Track = Track.program,
              mode: ObservationMode = ObservationMode.graph) -> None:
        """Called at the start of an episode with what the agent is told: its ``track`` (``program``: the
        instruction's program is given; ``language``: its text only) and the observation ``mode`` of every
        observation of the episode (``graph``, ``masks``, ``image``; ``muble.episode.modes``). Every runner
        passes both (in process, through Gymnasium's ``AgentPolicy`` and over ``muble serve``). Optional; default
        does nothing."""

    @abstractmethod
    def act(self, instruction: Instruction, observation: Observation) -> ActionCall | Answer | None:
        """The next action, an answer, or ``None`` when the agent considers the task done."""


# The keyword arguments ``Agent.reset`` gained after agents were written against ``reset(instruction,
# observation)``: each runner passes them through ``reset_agent``, which leaves out those an older agent's
# ``reset`` does not take.
RESET_KEYWORDS = ("track", "mode")


def reset_agent(agent: Agent, instruction: Instruction, observation: Observation, *, track: Track,
                mode: ObservationMode) -> None:
    """``agent.reset(instruction, observation, track=track, mode=mode)``, as every runner calls it.

    An agent written for the earlier signature, ``reset(self, instruction, observation)``, is called without the
    keyword arguments it does not take (with one ``MubleDeprecationWarning`` per agent class naming them), so it
    still plays its episodes instead of failing each as ``agent_error``. Its ``reset`` is inspected once per
    class."""
    keywords: dict[str, Any] = {"track": track, "mode": mode}
    taken = _reset_keywords(type(agent))
    agent.reset(instruction, observation, **{k: v for k, v in keywords.items() if taken is None or k in taken})


@functools.cache
def _reset_keywords(cls: type[Agent]) -> frozenset[str] | None:
    """The keywords of ``RESET_KEYWORDS`` that ``cls.reset`` takes; None when it takes any (``**kwargs``) or its
    signature cannot be read. Warns once for a class whose ``reset`` misses some."""
    try:
        parameters = inspect.signature(cls.reset).parameters.values()
    except (TypeError, ValueError):  # a reset written in C or wrapped beyond inspection: call it as documented
        return None
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters):
        return None
    by_name = {p.name for p in parameters if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                                        inspect.Parameter.KEYWORD_ONLY)}
    missing = [k for k in RESET_KEYWORDS if k not in by_name]
    if missing:
        # Reported where the old reset is written, which is what its author has to change.
        code = getattr(cls.reset, "__code__", None)
        warnings.warn_explicit(
            f"{cls.__module__}.{cls.__qualname__}.reset takes no keyword argument "
            f"{' or '.join(repr(k) for k in missing)}, so MuBlE calls it without: write it as "
            "reset(self, instruction, observation, *, track=Track.program, mode=ObservationMode.graph) (or add "
            "**kwargs); the old signature is served until MuBlE 0.2", MubleDeprecationWarning,
            code.co_filename if code else "<unknown>", code.co_firstlineno if code else 0, module=cls.__module__)
    return frozenset(by_name & set(RESET_KEYWORDS))


class Trainer(ABC):
    """Trains one learned part (a planner, an instruction parser, an attribute recogniser …) for ``muble train``.

    A trainer builds its own training data (symbolic roll-outs, rendered crops …) from ``run.seed``, trains, and
    leaves in ``run.out_dir`` a checkpoint that records ``run.record`` (the composed config and the code
    version) beside the weights. Same seed, same checkpoint. With ``run.resume`` a run that was stopped goes on
    from its last checkpoint in ``run.out_dir``; one made under another config is refused, never mixed in.
    """

    @abstractmethod
    def train(self, run: "TrainingRun") -> dict[str, Any]:
        """Train; return the run's figures (losses, held-out accuracy, seconds for data and for training)."""


@dataclass
class DisturbanceEvent:
    """What a disturbance did, as the episode record keeps it.

    ``step`` is the primitive (1-based) during or after which it fired; ``trigger`` says what fired it;
    ``force`` (N, world frame) is the largest force applied and ``impulse`` (N·s) the total, where it pushed;
    ``detail`` holds what else it did (the gripper's opening, the reading it spoiled, where it pushed to)."""

    kind: str
    step: int
    trigger: str
    object: int | None = None
    force: list[float] | None = None
    impulse: list[float] | None = None
    duration: float = 0.0
    detail: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for key in ("force", "impulse"):
            if out[key] is not None:
                out[key] = [round(float(v), 4) for v in out[key]]
        out["duration"] = round(float(out["duration"]), 4)
        return out


class Disturbance(ABC):  # noqa: B024 - every hook is optional; an ABC like the other plugin kinds
    """A physical event the world applies during an episode while the agent still acts (plugin kind
    ``disturbance``, docs/closed_loop.md). It never writes a pose: it acts through MuJoCo (a force on an object,
    ``Environment.apply_force``; a grip that loosens) and the world moves as the physics says.

    The physical world calls it around every primitive: ``before`` it runs, ``on_control`` after every control
    step while it runs (a slip while lifting), ``after`` it, before the agent observes (which may change the result
    the agent gets: a reading that failed). Each returns the ``DisturbanceEvent`` it applied, if any, which goes
    into the episode record and never into an observation: the agent sees only the consequences. Firing only during
    or right after a primitive, a disturbance always leaves the agent at least one decision after it.

    ``reset`` gets the episode's generator on the disturbance's own stream and the initial ground-truth scene:
    draw the trigger there (which primitive, which object, how hard), nowhere else. ``planned`` says whether it
    is planned to fire in this episode (the record counts planned against fired)."""

    kind: str = ""  # the registered name, set by the world from the registry
    planned: bool = True

    def applies(self, instruction: Instruction) -> bool:
        """Whether the disturbance can act in an episode of ``instruction`` (a slip needs something lifted, a
        toppled stack a stack): a split plans only those that can. Optional; by default every episode."""
        return True

    def reset(self, rng: np.random.Generator, scene: "SceneGraph") -> None:
        """Draw this episode's trigger. Optional; by default nothing is drawn."""

    def before(self, env: "Environment", action: ActionCall, step: int) -> DisturbanceEvent | None:
        """Before the ``step``-th primitive runs."""
        return None

    def on_control(self, env: "Environment") -> DisturbanceEvent | None:
        """After every control step while a primitive runs. Keep it cheap."""
        return None

    def after(self, env: "Environment", action: ActionCall, result: ActionResult,
              step: int) -> tuple[ActionResult, DisturbanceEvent | None]:
        """Right after the ``step``-th primitive, before the agent observes: the result the agent gets (changed
        only by a disturbance of the reading) and the event, if one fired."""
        return result, None


INTERFACES: dict[str, type] = {
    "renderer": Renderer,
    "planner": MotionPlanner,
    "primitive": PrimitiveAction,
    "sensor": Sensor,
    "task": Task,
    "object_set": ObjectSet,
    "agent": Agent,
    "trainer": Trainer,
    "disturbance": Disturbance,
}
