"""The ten SHOP-VRB2 Task plugins and the stiffness family: one class per template, sharing generation, planning
and checking."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from muble import ActionCall, Answer, Instruction, Observation, Outcome, PlanningError, SceneGraph, Task
from muble.core.ranges import bounded, configured
from muble.programs.descriptions import SceneIndex

from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.episodes import run_symbolic_episode
from muble_plugins.common.success import check
from muble_plugins.common.task_planner import plan_next
from muble_plugins.tasks.generator import generate_for_template
from muble_plugins.tasks.templates import (ALL_TEMPLATES, PHYSICAL_TEMPLATES, STIFFNESS_TEMPLATES, Template,
                                          load_templates)


@dataclass
class ShopVrb2TaskConfig:
    instructions_per_scene: int = 1  # -1: one per valid option
    extra_steps: int = 0  # allow descriptions this many words longer than the shortest
    weight_margin_g: float = 2.0  # weights compared by a template differ at least this much
    # ... and at least weight_close_pairs of them (an order's neighbours, a superlative's choice against each other
    # candidate) at most weight_gap_max_g (None: no bound): a split of close comparisons, where one reading of a noisy
    # sensor may order a pair wrong (shopvrb2_v2's noisy_sensing, docs/closed_loop.md)
    weight_gap_max_g: float | None = bounded(None, gt=0)
    weight_close_pairs: int = bounded(1, ge=1)


class ShopVrb2Task(Task):
    """A SHOP-VRB2 template: instructions with CLEVR-IEP programs, ground-truth primitives, success check.

    Built from a ``ShopVrb2TaskConfig`` (the registry's checked instance) and/or keyword overrides of its fields.
    """

    template: ClassVar[Template]

    def __init__(self, config: ShopVrb2TaskConfig | None = None, **options):
        self.config = configured(ShopVrb2TaskConfig, config, options, owner=f"task '{self.template.template_id}'")

    def generate(self, scene: SceneGraph, rng: np.random.Generator) -> list[Instruction]:
        cfg = self.config
        return generate_for_template(self.template, scene, rng, count=cfg.instructions_per_scene,
                                     index=SceneIndex(scene, cfg.extra_steps), weight_margin=cfg.weight_margin_g,
                                     weight_gap_max=cfg.weight_gap_max_g,
                                     weight_close_pairs=cfg.weight_close_pairs)

    def admits(self, objects: list) -> bool:
        """With close weight comparisons asked for (``weight_gap_max_g``), whether the objects' weights hold enough
        close pairs for this template at all, whichever of them its option picks: an order needs
        ``weight_close_pairs`` pairs between ``weight_margin_g`` and ``weight_gap_max_g`` apart, a superlative an
        object with that many others that far on one side of it. Always true otherwise."""
        cfg = self.config
        if cfg.weight_gap_max_g is None:
            return True
        weights = sorted(float(o.weight_g) for o in objects)
        low, high, need = cfg.weight_margin_g, cfg.weight_gap_max_g, cfg.weight_close_pairs
        if "order_weight" in self.template.step_types:
            return sum(low <= b - a <= high for i, a in enumerate(weights) for b in weights[i + 1:]) >= need
        for w in weights:
            if sum(low <= v - w <= high for v in weights) >= need or sum(low <= w - v <= high for v in weights) >= need:
                return True
        return False

    def ground_truth(self, instruction: Instruction, scene: SceneGraph) -> list[ActionCall]:
        """The oracle's primitives, rolled out in the symbolic world from ``scene`` (weights unknown at start), in
        at most as many primitives as an episode allows (``muble.episode.DEFAULT_MAX_STEPS``)."""
        episode = run_symbolic_episode(instruction, scene, OracleAgent(task=self))
        if episode.outcome is not Outcome.SUCCESS:
            raise PlanningError(f"no ground-truth plan for '{instruction.instruction}': the oracle's roll-out "
                                f"ended in {episode.outcome.value} after {len(episode.actions)} primitives")
        return episode.actions

    def check(self, instruction: Instruction, scene: SceneGraph, answer: Answer | None) -> Outcome:
        return check(instruction, scene, answer)

    def next_actions(self, instruction: Instruction, observation: Observation) -> list[ActionCall] | Answer:
        """Backward chaining from the program's goal on the observed scene (its ``weight`` fields and
        ``extra["stiffness_measured"]`` hold what the agent measured; the gripper's state comes from the scene's
        flags)."""
        plan = plan_next(instruction.program, observation.scene)
        return plan.answer if plan.answer is not None else plan.actions


def task_class(template: Template, class_name: str | None = None) -> type[ShopVrb2Task]:
    """A Task plugin class for a template (built-in, or read from any template file)."""
    name = class_name or "".join(w.capitalize() for w in template.template_id.split("_")) + "Task"
    return type(name, (ShopVrb2Task,), {"template": template, "task_id": template.task_id,
                                        "__doc__": f"Template '{template.template_id}': {template.description}."})


def template_file_tasks(path: str | Path) -> dict[str, type[ShopVrb2Task]]:
    """Task classes for every template of a template file, by template id (what a plugin registers)."""
    return {name: task_class(t) for name, t in load_templates(path).items()}


# The ten SHOP-VRB2 templates' task class names, by template id, in registration order.
SHOP_VRB2_CLASS_NAMES = {
    "measure_weight_single": "MeasureWeightSingle", "measure_weight_multi": "MeasureWeightMulti",
    "pick_up_lightest": "PickUpByWeight", "move_single": "MoveSingle", "remove": "RemoveFromPart",
    "move_weight": "MoveByWeight", "stack_simple": "StackSimple", "stack_weight": "StackByWeight",
    "stack_three": "StackThree", "stack_order": "StackOrder",
}

# The stiffness family (stiffness_templates.yaml) and the physical family (physical_templates.yaml): registered,
# but not in the default SHOP-VRB2 mix.
STIFFNESS_TASK_CLASSES: dict[str, type[ShopVrb2Task]] = {name: task_class(t) for name, t in
                                                         STIFFNESS_TEMPLATES.items()}
PHYSICAL_TASK_CLASSES: dict[str, type[ShopVrb2Task]] = {name: task_class(t) for name, t in
                                                        PHYSICAL_TEMPLATES.items()}

TASK_CLASSES: dict[str, type[ShopVrb2Task]] = {
    **{template_id: task_class(ALL_TEMPLATES[template_id], class_name)
       for template_id, class_name in SHOP_VRB2_CLASS_NAMES.items()},
    **STIFFNESS_TASK_CLASSES,
    **PHYSICAL_TASK_CLASSES}
