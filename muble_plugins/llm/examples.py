"""Worked examples for the system prompt, from a split's ground-truth sequences (``agent.examples``).

An example is a stored instruction of another scene (a training split's, as the protocol allows), its objects in
a few words, and the decisions that solve it: the ground-truth primitives as the JSON the model is asked to reply
with, the answer for a query, then the stop. Examples of the episode's own template come first.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

from muble import ConfigError
from muble.io.action_names import from_original
from muble.programs.program import QUERY_STEPS
from muble.io.layout import DatasetLayout

log = logging.getLogger(__name__)

POOL = 200  # instruction files read from the split: enough for every template many times, read in a second
QUERY_TASKS = tuple(QUERY_STEPS)  # tasks whose recorded target is the answer


def _objects(scene_file: Path) -> list[str]:
    try:
        scene = json.loads(scene_file.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    words = ("colour", "material", "name")
    return [f"{i}: " + " ".join(str(o.get(w)) for w in words if o.get(w) is not None)
            for i, o in enumerate(scene.get("objects", []))]


def example_from(record: dict[str, Any], scene_file: Path) -> dict[str, Any] | None:
    """One worked example from a stored instruction record (None without a ground-truth sequence)."""
    actions = record.get("ground_truth_actions")
    if not record.get("instruction") or not actions:
        return None
    decisions: list[dict[str, Any]] = [{"name": from_original(a[0]), "params": a[1] if len(a) > 1 else {}}
                                       for a in actions if isinstance(a, (list, tuple)) and a]
    task = record.get("task") or {}
    if task.get("task") in QUERY_TASKS:
        decisions.append({"answer": task.get("target")})
    decisions.append({"stop": True})
    program = [{"type": s.get("type"), "input_value": s.get("input_value")} for s in record.get("program", [])]
    return {"template": record.get("template_id"), "instruction": record["instruction"], "program": program,
            "objects": _objects(scene_file), "decisions": decisions}


def load_examples(root: Path, split: str) -> list[dict[str, Any]]:
    """The worked examples of the first ``POOL`` indices of ``root``'s ``split`` that have ground truth."""
    layout = DatasetLayout(root, split)
    folder = layout.split_dir / "instructions"
    if not folder.is_dir():
        raise ConfigError(f"agent.examples_root: {layout.split_dir} has no instructions folder; give a dataset "
                          "folder written by `muble generate` and the split to draw examples from "
                          "(agent.examples_split)")
    pool = []
    for file in sorted(folder.glob("*.json"))[:POOL]:
        try:
            record = json.loads(file.read_text(encoding="utf-8"))
        except (OSError, ValueError) as e:
            log.warning("example %s skipped: %s", file, e)
            continue
        example = example_from(record, layout.split_dir / "scenes" / file.name)
        if example is not None:
            pool.append(example)
    if not pool:
        raise ConfigError(f"agent.examples_root: no instruction with a ground-truth sequence in {folder}; "
                          "generate the split with dataset.sequences=true")
    return pool


def pick_examples(pool: list[dict[str, Any]], template: str, k: int) -> list[dict[str, Any]]:
    """``k`` examples: the episode's template first, then the others, each in index order."""
    if k <= 0:
        return []
    same = [e for e in pool if e["template"] == template]
    return (same + [e for e in pool if e["template"] != template])[:k]
