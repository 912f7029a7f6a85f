"""Producing a dataset split: every index is a pure function of (seed, split, index), written atomically.

``produce_index`` runs in any worker (local process, Ray task or the driver): it builds the configured plugins
once per process, generates the scene, renders its image, picks an instruction from the template mix, runs the
oracle with physics for the ground-truth sequence (observations after every primitive, keyframes) and writes
all of it, the instruction file last. An index whose instruction file exists is complete; a killed run leaves
only hidden temporaries, removed on restart, so a restarted run ends byte-identical to an uninterrupted one.
"""
from __future__ import annotations

import json
import logging
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from muble.core.errors import ConfigError
from muble.dataset.atomic import write_bytes_atomic
from muble.dataset.layout import DatasetLayout
from muble.generation.ground_truth import apply_masks

log = logging.getLogger(__name__)

_components_cache: dict[str, Any] = {}


@dataclass(frozen=True)
class IndexJob:
    """One unit of work: the resolved config (plain data, picklable), the split and the scene index."""

    config: dict[str, Any]
    split: str
    index: int


def split_seed(seed: int, split: str) -> int:
    """Each split draws from its own stream (a stable hash of its name, not Python's salted hash)."""
    return int(seed) * 1_000_003 + zlib.crc32(split.encode())


def cached_components(config: dict[str, Any], renderer: bool = True, task: bool = True) -> dict[str, Any]:
    """The configured plugins, built once per worker process (and config): workers run many indices."""
    key = json.dumps([config, renderer, task], sort_keys=True, default=str)
    if key not in _components_cache:
        from omegaconf import OmegaConf

        from muble.app.run import build_components

        _components_cache.clear()
        _components_cache[key] = build_components(OmegaConf.create(config), renderer=renderer, task=task)
    return _components_cache[key]


def choose_instruction(tasks: list[Any], weights: np.ndarray, scene: Any, rng: np.random.Generator):
    """An instruction from the template mix: a template drawn by weight, then the others in drawn order.

    Returns (None, None) when no template of the mix applies to the scene (e.g. a weight comparison in a scene
    with a single object of each kind)."""
    order = rng.choice(len(tasks), size=len(tasks), replace=False, p=weights)
    for k in order:
        candidates = tasks[int(k)].generate(scene, rng)
        if candidates:
            return tasks[int(k)], candidates[0]
    return None, None


def produce_index(job: IndexJob) -> tuple[int, dict[str, str]]:
    """Generate and write everything of one scene index; returns (index, {relative path: sha256})."""
    from muble.core.scene_io import scene_to_dict
    from muble.core.instructions_io import instruction_to_dict
    from muble.episode.runner import instruction_rng, png_bytes, write_episode
    from muble.generation.generator import SceneGenerator
    from muble.plugins.registry import get_registry

    cfg = job.config
    ds = cfg["dataset"]
    layout = DatasetLayout(Path(ds["root"]), job.split)
    out = layout.split_dir
    components = cached_components(cfg)
    registry = get_registry()
    seed = split_seed(cfg["seed"], job.split)
    generator_options = dict(cfg["generator"], split=job.split)
    generator = SceneGenerator(generator_options, seed=seed, object_set=components["object_set"])
    try:
        scene = generator.generate(job.index)
    finally:
        generator.close()
    scene.image_filename = Path(layout.image(job.index)).name
    written: dict[str, str] = {}

    tasks = [registry.create("task", name, {}) for name in ds["templates"]]
    weights = np.asarray(ds["template_weights"] or [1.0] * len(tasks), dtype=float)
    if len(weights) != len(tasks) or np.any(weights < 0) or weights.sum() <= 0:
        raise ConfigError("dataset.template_weights needs one non-negative weight per template, not all zero")
    rng = instruction_rng(seed, job.index)
    task, instruction = choose_instruction(tasks, weights / weights.sum(), scene, rng)

    from muble.app.run import episode_runner
    from omegaconf import OmegaConf

    runner = episode_runner(OmegaConf.create(cfg), components)
    if instruction is not None and ds["sequences"]:
        output = runner.execute(scene, instruction, task)
        written.update(write_episode(output, out, layout.stem(job.index), gif=ds["gif"]))
        image = output.keyframes[0] if output.keyframes else None
    else:
        image = _render_initial(runner, scene)
        written[layout.scene(job.index)] = write_bytes_atomic(
            out / layout.scene(job.index), json.dumps(scene_to_dict(scene)).encode())
    if image is not None:
        written[layout.image(job.index)] = write_bytes_atomic(out / layout.image(job.index), png_bytes(image))
    if instruction is None:
        # The scene stays in the dataset (indices keep their meaning); its instruction record says why it has none.
        record = {"split": job.split, "image_filename": scene.image_filename, "image_index": job.index,
                  "instruction": None, "skipped": f"no template of {list(ds['templates'])} applies to this scene"}
    else:
        instruction.split, instruction.image_index = job.split, job.index
        record = instruction_to_dict(instruction)
        record["ground_truth_actions"] = [[a.name, a.params] for a in task.ground_truth(instruction, scene)]
    written[layout.instruction(job.index)] = write_bytes_atomic(
        out / layout.instruction(job.index), json.dumps(record).encode())
    return job.index, written


def _render_initial(runner: Any, scene: Any):
    """The scene's image from the first configured camera, without running an episode."""
    if runner.renderer is None:
        return None
    from muble.sim.build import object_models
    from muble.sim.env import TabletopEnv

    env = TabletopEnv(scene, object_models(scene, runner.object_set, runner.object_set_name), runner.robot, {})
    try:
        runner.renderer.setup(env.sync_scene_graph(), env.model)
        camera = env.names.cameras.get(runner.cameras[0], runner.cameras[0])
        frame = runner.renderer.render(env.data, camera)
        if frame.segmentation is not None:
            apply_masks(scene, frame.segmentation)
        return frame.rgb
    finally:
        env.close()
        runner.renderer.close()
