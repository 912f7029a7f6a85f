"""Instruction generation: sample template options, describe the objects, phrase the text, build the program.

Rejection is cheap because it happens on object-level options first (see ``templates``; each template's options,
text slots and program come from its template file, ``template_data``); descriptions come from
the scene's ``SceneIndex``, so every noun phrase denotes exactly its intended objects. Output is deterministic
given the random generator's state and the scene.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from muble import ConfigError, Instruction, SceneGraph
from muble.core.errors import unknown_name
from muble.programs.descriptions import SceneIndex
from muble.programs.program import execute
from muble.stage.footprint import Outlines

from muble_plugins.tasks.templates import ALL_TEMPLATES, TEMPLATES, OptionContext, Template

MIN_WORDS, MAX_WORDS = 5, 16


def _described(option: tuple) -> list[int | tuple[int, ...]]:
    """The option's entries that need a description: object ids and id groups (not words)."""
    return [x for x in option if not isinstance(x, str)]


def _choose(rng: np.random.Generator, items: list | tuple) -> Any:
    return items[int(rng.integers(len(items)))] if len(items) > 1 else items[0]


def _fill_io(program: list[dict[str, Any]], scene: SceneGraph) -> None:
    """Record each step's output (ground-truth weights) and, as its input, the output of the step before."""
    trace = execute(program, scene, weights="ground_truth")
    prev = None
    for step, out in zip(program, trace.outputs):
        if step["type"] not in ("scene", "stack"):
            step["input"] = prev
        step["output"] = out
        prev = out


def generate_for_template(template: Template, scene: SceneGraph, rng: np.random.Generator, *, count: int = 1,
                          index: SceneIndex | None = None, weight_margin: float = 2.0,
                          outlines: Outlines | None = None, weight_gap_max: float | None = None,
                          weight_close_pairs: int = 1) -> list[Instruction]:
    """Up to ``count`` instructions of ``template`` for ``scene`` (``count < 0``: one per valid option);
    ``outlines``: the scene's outline memo, where the caller lists other templates for the same scene;
    ``weight_gap_max`` and ``weight_close_pairs``: how close the weights it compares are (``OptionContext``)."""
    index = index or SceneIndex(scene)
    context = OptionContext(index, weight_margin, outlines if outlines is not None else Outlines(),
                            weight_gap_max=weight_gap_max, weight_close_pairs=weight_close_pairs)
    options = list(template.options(context))
    if not options:
        return []
    build, fill = template.build, template.fill
    if build is None or fill is None:
        raise ConfigError(f"template {template.template_id!r} has no build or fill function: it cannot generate "
                          "instructions")
    out: list[Instruction] = []
    for k in rng.permutation(len(options)):
        option = options[int(k)]
        if template.feasible is not None and not template.feasible(option, context):
            continue
        descs = [_choose(rng, index.unique[x] if isinstance(x, int) else index.groups[x])
                 for x in _described(option)]
        slots, program = build(option, descs)
        for phrasing in rng.permutation(len(template.texts)):
            text = fill(template.texts[int(phrasing)], slots)
            if MIN_WORDS <= len(text.split()) <= MAX_WORDS:
                break
        else:
            continue
        _fill_io(program, scene)
        final = program[-1]
        out.append(Instruction(
            instruction=text[0].upper() + text[1:],
            program=program,
            template_id=template.template_id,
            task_id=template.task_id,
            image_filename=scene.image_filename,
            image_index=scene.image_index,
            split=scene.split,
            extra={"template_internal_idx": int(phrasing), "template_overall_idx": template.index,
                   "instruction_idx": 0,
                   "task": {"task": final["type"], "target": final["output"], "input_value": final["input_value"]}},
        ))
        if 0 <= count <= len(out):
            break
    return out


def generate_instructions(scene: SceneGraph, rng: np.random.Generator, *, templates: list[str] | None = None,
                          per_template: int = 1, extra_steps: int = 0,
                          weight_margin: float = 2.0) -> list[Instruction]:
    """Instructions of the ten SHOP-VRB2 templates (or of those named, the stiffness family's included) for one
    scene, numbered in ``instruction_idx`` order."""
    unknown = [n for n in templates or () if n not in ALL_TEMPLATES]
    if unknown:
        raise ConfigError(unknown_name("template", unknown[0], list(ALL_TEMPLATES)))
    index = SceneIndex(scene, extra_steps)
    outlines = Outlines()  # each object's outline once for all the templates
    out: list[Instruction] = []
    for name in templates or list(TEMPLATES):
        out += generate_for_template(ALL_TEMPLATES[name], scene, rng, count=per_template, index=index,
                                     weight_margin=weight_margin, outlines=outlines)
    for k, ins in enumerate(out):
        ins.extra["instruction_idx"] = k
    return out
