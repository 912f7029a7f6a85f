"""The task mix of a dataset split: which template and how many objects each scene index gets, and a scene
generated to suit that template.

Drawing a template per scene and falling back to another when it does not apply skews a split towards the
templates that apply to most scenes (moving one object) and away from the demanding ones (stacking three, or by
weight order). Here the template comes first: index ``i`` of a split is assigned a template so that every block
of ``len(weights)`` consecutive indices holds the templates in proportion to their weights (equal shares by
default; Sainte-Laguë apportionment, then shuffled within the block), and likewise an object count from the
generator's count probabilities. The scene generator then draws scene samples for the index, all with that
object count, until the template yields an instruction whose ground truth the symbolic oracle completes.

Everything is a pure function of (split seed, index): the template and count orders are drawn from the named
streams ``split.template_mix`` and ``split.count_mix`` (keyed by block), the scene samples from the generator's
``scene.*`` streams and the instruction from ``episode.instruction`` (``muble.core.streams``).
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from muble.core import streams
from muble.core.errors import ConfigError, PlanningError, SceneGenerationError
from muble.core.interfaces import Instruction, Task
from muble.core.scene import SceneGraph
from muble.programs.program import stacked_pairs

TEMPLATE_KEY, COUNT_KEY = streams.TEMPLATE_MIX, streams.COUNT_MIX  # the purposes of balanced_choice's draws

_sequences: dict[tuple[float, ...], list[int]] = {}
_lock = threading.Lock()


def apportioned(weights: Sequence[float], length: int) -> list[int]:
    """The first ``length`` categories of the Sainte-Laguë sequence for ``weights``: each next item goes to the
    category with the highest ``weight / (2 * count + 1)`` (the lower index on ties), so every prefix holds each
    category within about one item of its share, and longer prefixes extend shorter ones."""
    key = tuple(float(w) for w in weights)
    with _lock:
        seq = _sequences.setdefault(key, [])
        if len(seq) < length:
            counts = np.zeros(len(key))
            for k in seq:
                counts[k] += 1
            w = np.asarray(key)
            while len(seq) < length:
                k = int(np.argmax(w / (2 * counts + 1)))
                counts[k] += 1
                seq.append(k)
        return seq[:length]


def balanced_choice(weights: Sequence[float], seed: int, index: int, key: str) -> int:
    """The category of ``index``: blocks of ``len(weights)`` consecutive indices take their share of the
    apportioned sequence, in an order shuffled per block, drawn from the named stream ``key``
    (``TEMPLATE_KEY``, ``COUNT_KEY``)."""
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or len(w) == 0 or np.any(w < 0) or not np.isfinite(w).all() or w.sum() <= 0:
        raise ConfigError(f"weights {list(weights)} must be non-negative numbers, not all zero")
    size = len(w)
    block, slot = divmod(int(index), size)
    entries = apportioned(w / w.sum(), (block + 1) * size)[block * size:]
    order = streams.stream(key, int(seed), block).permutation(size)
    return entries[int(order[slot])]


def template_weights(templates: Sequence[str], weights: Sequence[float] | None) -> list[float]:
    """``weights`` checked against ``templates`` (empty or None: equal shares)."""
    if not weights:
        return [1.0] * len(templates)
    if len(weights) != len(templates):
        raise ConfigError(f"dataset.template_weights has {len(weights)} entries for {len(templates)} templates "
                          f"{list(templates)}; give one weight per template or none (equal shares)")
    if any(float(w) < 0 for w in weights) or sum(float(w) for w in weights) <= 0:
        raise ConfigError(f"dataset.template_weights {list(weights)} must be non-negative, not all zero")
    return [float(w) for w in weights]


@dataclass
class SuitedScene:
    """A scene generated for its index's template, with the instruction and ground truth chosen there."""

    scene: SceneGraph
    task: Task
    template: str
    instruction: Instruction
    ground_truth: list
    samples: int  # scene samples drawn for the index (1 = the first suited the template)
    rejections: dict[str, int]  # layouts rejected on the way, per check ("not accepted": the template)


def suited_scene(generator: Any, tasks: dict[str, Task], weights: Sequence[float], seed: int, index: int,
                 instruction_rng, max_samples: int | None = None) -> SuitedScene:
    """The scene for ``index`` of a split whose template mix is ``tasks`` (name -> task) with ``weights``.

    ``generator`` is a ``SceneGenerator`` seeded with the split's seed; ``instruction_rng(index)`` gives the
    random stream an instruction is chosen with. A scene sample is accepted when the template yields an
    instruction whose ground truth the symbolic oracle completes; the generator's own checks (visibility,
    rest, the stacks of that ground truth standing, reach) then run on the accepted layout only. Raises ``SceneGenerationError`` when no sample in
    ``max_samples`` (default: the generator's ``scene_samples``) suits the template.
    """
    names = list(tasks)
    template = names[balanced_choice(weights, seed, index, TEMPLATE_KEY)]
    config = generator.config
    max_samples = config.scene_samples if max_samples is None else max_samples
    count = config.min_objects + balanced_choice(config.count_probabilities, seed, index, COUNT_KEY)
    distractors = int(config.distractors)
    task = tasks[template]
    chosen: dict[str, Any] = {}

    def accept(scene: SceneGraph) -> bool:
        for instruction in task.generate(scene, instruction_rng(index)):
            if distractors:
                free = unreferenced(instruction.program, scene)
                if len(free) < distractors:
                    continue  # the instruction would refer to (or depend on) an object meant to distract
                chosen["distractors"] = free
            try:
                chosen["plan"] = task.ground_truth(instruction, scene)
            except PlanningError:
                continue
            chosen["instruction"] = instruction
            return True
        return False

    before = dict(generator.failures)
    reasons: dict[str, int] = {}
    for sample in range(max_samples):
        chosen.clear()
        try:
            scene = generator.generate(index, sample=sample, objects=count + distractors, accept=accept,
                                       stacks=lambda _: stacked_pairs(chosen["instruction"].program),
                                       admits=getattr(task, "admits", None))
        except SceneGenerationError as e:
            for k, v in e.reasons.items():
                reasons[k] = reasons.get(k, 0) + v
            continue
        rejections = {k: v - before.get(k, 0) for k, v in generator.failures.items() if v > before.get(k, 0)}
        if distractors:
            scene.extra.setdefault("generator", {})["distractors"] = chosen["distractors"]
        return SuitedScene(scene, task, template, chosen["instruction"], chosen["plan"], sample + 1, rejections)
    detail = ", ".join(f"{k}: {v}" for k, v in sorted(reasons.items()))
    raise SceneGenerationError(
        f"scene {index}: no scene sample with {count} objects suits template '{template}' in {max_samples} "
        f"samples ({detail}); lower its share in dataset.template_weights, raise generator.scene_samples, or "
        "use an object set with the objects the template needs", index=index, reasons=reasons)


def unreferenced(program: list[dict[str, Any]], scene: SceneGraph) -> list[int]:
    """Ids of the scene's objects that no step of ``program`` (as generated: with each step's ``output``) yields,
    the ``scene`` step's "every object" aside: no filter, relation, comparison or action of the instruction picks
    them, so removing them would change neither its meaning nor its ground truth."""
    named: set[int] = set()

    def collect(value: Any) -> None:
        if isinstance(value, (list, tuple)):
            for v in value:
                collect(v)
        elif isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            named.add(int(value))

    for step in program:
        if step.get("type") != "scene":
            collect(step.get("output"))
    return [o.id for o in scene.objects if o.id not in named]


def choose_from_mix(tasks: list[Any], weights: np.ndarray, scene: Any, rng: np.random.Generator):
    """An instruction for a given scene from a template mix: a template drawn by weight, then the others in drawn
    order. (``suited_scene`` goes the other way: the template first, then a scene that suits it.)

    Returns (None, None) when no template of the mix applies to the scene (e.g. a weight comparison in a scene
    with a single object of each kind). A template of weight zero is never tried."""
    weights = np.asarray(weights, dtype=float)
    if np.all(weights > 0):
        order = rng.choice(len(tasks), size=len(tasks), replace=False, p=weights)
    else:
        drawn = np.flatnonzero(weights > 0)
        order = drawn[rng.choice(len(drawn), size=len(drawn), replace=False, p=weights[drawn] / weights[drawn].sum())]
    for k in order:
        candidates = tasks[int(k)].generate(scene, rng)
        if candidates:
            return tasks[int(k)], candidates[0]
    return None, None
