"""One evaluation episode per dataset index: the stored scene and instruction, the configured agent, real physics.

``evaluate_index`` runs in any worker (local process, Ray task or the driver) and returns a plain record, so
results are the same whichever executor ran them. The task that judges an episode is the instruction's template.
"""
from __future__ import annotations

import json
import logging
import re
from pathlib import Path
from typing import Any

import numpy as np

from muble.core.errors import ConfigError, MubleError
from muble.dataset.layout import PREFIX, DatasetLayout
from muble.dataset.production import IndexJob, cached_components

log = logging.getLogger(__name__)

# One unit of evaluation work: the same (config, split, index) record as a dataset job.
EvalJob = IndexJob


def split_indices(layout: DatasetLayout) -> list[int]:
    """The indices of a split that are complete (their instruction file exists) and have a scene file."""
    pattern = re.compile(rf"^{PREFIX}_{re.escape(layout.split)}_(\d+)\.json$")
    found = []
    folder = layout.split_dir / "instructions"
    for path in folder.glob("*.json") if folder.is_dir() else ():
        m = pattern.match(path.name)
        if m and (layout.split_dir / layout.scene(int(m.group(1)))).is_file():
            if json.loads(path.read_text(encoding="utf-8")).get("instruction") is None:
                continue  # a scene no template of the mix applied to
            found.append(int(m.group(1)))
    return sorted(found)


def build_components(config: dict[str, Any]) -> dict[str, Any]:
    """The configured plugins, once per process and config; no renderer unless ``evaluation.render``, and no task
    (each instruction names its own template)."""
    return cached_components(config, renderer=bool(config["evaluation"]["render"]), task=False)


def plain(value: Any) -> Any:
    """JSON-ready data from answers and measurements (numpy scalars and arrays included)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)


def evaluate_index(job: EvalJob) -> dict[str, Any]:
    """Run the agent on one stored index; returns its result record (an error becomes an outcome, not a crash)."""
    from omegaconf import OmegaConf

    from muble.app.run import episode_runner
    from muble.core.instructions_io import instruction_from_dict
    from muble.core.scene_io import load_scene
    from muble.core.types import Outcome
    from muble.plugins.registry import get_registry

    cfg = job.config
    layout = DatasetLayout(Path(cfg["dataset"]["root"]), job.split)
    scene = load_scene(layout.split_dir / layout.scene(job.index))
    record = json.loads((layout.split_dir / layout.instruction(job.index)).read_text(encoding="utf-8"))
    instruction = instruction_from_dict(record, job.index)
    out: dict[str, Any] = {"split": job.split, "index": job.index, "template": instruction.template_id,
                           "task": instruction.task_id, "instruction": instruction.instruction,
                           "ground_truth_primitives": len(record.get("ground_truth_actions", []))}
    components = build_components(cfg)
    task = get_registry().create("task", instruction.template_id, {})
    runner = episode_runner(OmegaConf.create(cfg), components)
    try:
        output = runner.execute(scene, instruction, task)
    except MubleError as e:
        # A scene the simulator cannot even build is the broken-scene class of the taxonomy, not a crash.
        log.warning("%s %d: %s", job.split, job.index, e)
        return {**out, "outcome": Outcome.BROKEN_SCENE.value, "primitives": [], "answer": None,
                "error": f"{type(e).__name__}: {e}", "timing": None, "keyframes": []}
    result = output.result
    written = []
    if cfg["evaluation"]["render"] and cfg["evaluation"]["keyframes"] and output.keyframes:
        from muble.episode.runner import png_bytes
        from muble.dataset.atomic import write_bytes_atomic

        folder = Path(cfg["output"]["dir"]) / "keyframes" / layout.stem(job.index)
        for i, rgb in enumerate(output.keyframes):
            write_bytes_atomic(folder / f"frame_{i:04d}.png", png_bytes(rgb))
            written.append(str(folder / f"frame_{i:04d}.png"))
    t = output.timing
    return {**out, "outcome": result.outcome.value, "primitives": [str(a) for a in result.actions],
            "answer": None if result.answer is None else plain(result.answer.value), "error": result.error,
            "timing": {"physics": t.physics, "planning": t.planning, "rendering": t.rendering, "total": t.total},
            "keyframes": written}


def check_split(layout: DatasetLayout) -> list[int]:
    """The split's indices, or a ConfigError saying how to point at a generated split."""
    if not layout.split_dir.is_dir():
        present = sorted(p.name for p in layout.root.iterdir() if p.is_dir() and (p / "instructions").is_dir())
        raise ConfigError(f"split '{layout.split}' is not in dataset {layout.root}; splits present: "
                          f"{', '.join(present) or '(none)'}. Set dataset.splits=[...] to one of them or generate "
                          f"it with `muble generate dataset.splits=[{layout.split}] dataset.root={layout.root}`")
    found = split_indices(layout)
    if not found:
        raise ConfigError(f"split '{layout.split}' in {layout.root} has no complete index (no instructions/*.json "
                          "with a matching scenes/*.json); finish generating it with `muble generate`")
    return found
