"""Instruction generation: sample template options, describe the objects, phrase the text, build the program.

Rejection is cheap because it happens on object-level options first (see ``templates``); descriptions come from
the scene's ``SceneIndex``, so every noun phrase denotes exactly its intended objects. Output is deterministic
given the random generator's state and the scene.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from muble import ConfigError, Instruction, SceneGraph
from muble.core.errors import unknown_name
from muble.core.instructions_io import program_step
from muble.core.program import OPPOSITE_PART, execute

from muble_plugins.tasks.descriptions import Description, SceneIndex
from muble_plugins.tasks.templates import TEMPLATES, OptionContext, Template
from muble_plugins.tasks.vocabulary import ATTRIBUTE_STEP, describe

MIN_WORDS, MAX_WORDS = 5, 16


def _chain(desc: Description) -> list[dict[str, Any]]:
    return [program_step("scene")] + [program_step(ATTRIBUTE_STEP[a], input_value=v) for a, v in desc]


def _filters(desc: Description) -> list[dict[str, Any]]:
    return [program_step(ATTRIBUTE_STEP[a], input_value=v) for a, v in desc]


# template id -> (option, chosen descriptions) -> (text slots, program without outputs)
Builder = Callable[[tuple, list[Description]], tuple[dict[str, str], list[dict[str, Any]]]]
_BUILDERS: dict[str, Builder] = {
    "measure_weight_single": lambda o, d: ({"O1": describe(d[0])}, _chain(d[0]) + [program_step("query_weight")]),
    "measure_weight_multi": lambda o, d: ({"O1s": describe(d[0], many=True)},
                                          _chain(d[0]) + [program_step("query_weight")]),
    "pick_up_lightest": lambda o, d: ({"O1s": describe(d[0], many=True), "WS": o[1]},
                                      _chain(d[0]) + [program_step("filter_weight", input_value=o[1]),
                                                      program_step("pick_up")]),
    "move_single": lambda o, d: ({"O1": describe(d[0]), "TP": o[1]},
                                 _chain(d[0]) + [program_step("move_to", input_value=o[1])]),
    "remove": lambda o, d: ({"O1s": describe(d[0], many=True), "TP": o[1]},
                            [program_step("scene"), program_step("filter_table_part", input_value=o[1])]
                            + _filters(d[0]) + [program_step("move_to", input_value=OPPOSITE_PART[o[1]])]),
    "move_weight": lambda o, d: ({"O1s": describe(d[0], many=True), "WS": o[1], "TP": o[2]},
                                 _chain(d[0]) + [program_step("filter_weight", input_value=o[1]),
                                                 program_step("move_to", input_value=o[2])]),
    "stack_simple": lambda o, d: ({"O1": describe(d[0]), "O2": describe(d[1])},
                                  _chain(d[0]) + _chain(d[1]) + [program_step("stack")]),
    "stack_weight": lambda o, d: ({"O1s": describe(d[0], many=True), "WS": o[1], "O2": describe(d[1])},
                                  _chain(d[0]) + [program_step("filter_weight", input_value=o[1])]
                                  + _chain(d[1]) + [program_step("stack")]),
    "stack_three": lambda o, d: ({"O1": describe(d[0]), "O2": describe(d[1]), "O3": describe(d[2])},
                                 _chain(d[0]) + _chain(d[1]) + _chain(d[2]) + [program_step("stack")]),
    "stack_order": lambda o, d: ({"O1s": describe(d[0], many=True)},
                                 _chain(d[0]) + [program_step("order_weight", input_value="ascending"),
                                                 program_step("stack")]),
}


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
                          index: SceneIndex | None = None, weight_margin: float = 2.0) -> list[Instruction]:
    """Up to ``count`` instructions of ``template`` for ``scene`` (``count < 0``: one per valid option)."""
    index = index or SceneIndex(scene)
    context = OptionContext(index, weight_margin)
    options = list(template.options(context))
    if not options:
        return []
    build = _BUILDERS[template.template_id]
    out: list[Instruction] = []
    for k in rng.permutation(len(options)):
        option = options[int(k)]
        if template.feasible is not None and not template.feasible(option, context):
            continue
        descs = [_choose(rng, index.unique[x] if isinstance(x, int) else index.groups[x])
                 for x in _described(option)]
        slots, program = build(option, descs)
        for phrasing in rng.permutation(len(template.texts)):
            text = template.texts[int(phrasing)].format(**slots)
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
    """Instructions of every template (or those named) for one scene, numbered in ``instruction_idx`` order."""
    unknown = [n for n in templates or () if n not in TEMPLATES]
    if unknown:
        raise ConfigError(unknown_name("template", unknown[0], list(TEMPLATES)))
    index = SceneIndex(scene, extra_steps)
    out: list[Instruction] = []
    for name in templates or list(TEMPLATES):
        out += generate_for_template(TEMPLATES[name], scene, rng, count=per_template, index=index,
                                     weight_margin=weight_margin)
    for k, ins in enumerate(out):
        ins.extra["instruction_idx"] = k
    return out
