"""Producing a dataset split: every index is a pure function of (seed, split, index), written atomically.

``produce_index`` runs in any worker (local process, Ray task or the driver): it builds the configured plugins
once per process, takes the index's template and object count from the split's task mix
(``muble.generation.task_mix``), generates a scene that suits that template with an instruction whose ground
truth is feasible, renders its image, runs the oracle with physics for the ground-truth sequence (observations
after every primitive, keyframes and the keyframes' MuJoCo states, ``keyframes/<stem>_states.npz``, which
``muble render --keyframes`` draws again with another renderer) and writes all of it, the instruction file last.
An index whose instruction file exists is complete; a killed run leaves only hidden temporaries, removed on
restart, so a restarted run ends byte-identical to an uninterrupted one.
"""
from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, MutableMapping

from muble.core.streams import split_seed  # noqa: F401 - a split's seed, read here by generate and eval
from muble.episode.components import split_episode
from muble.generation.ground_truth import apply_masks
from muble.io.atomic import write_bytes_atomic
from muble.io.layout import DatasetLayout

log = logging.getLogger(__name__)

_components_cache: dict[str, Any] = {}


@dataclass(frozen=True)
class IndexJob:
    """One unit of work: the resolved config (plain data, picklable), the split and the scene index."""

    config: dict[str, Any]
    split: str
    index: int


def with_split(cfg: Any) -> Any:
    """``cfg`` as its ``split`` (``muble run``'s, the Gymnasium environments', ``muble serve``'s) is produced
    (``split_run_config``); ``cfg`` itself when it names no split."""
    from muble.io.layout import check_split_name

    split = cfg.get("split")
    return cfg if split is None else split_run_config(cfg, check_split_name(str(split), "split"))


def split_run_config(cfg: Any, split: str) -> Any:
    """A composed config (``DictConfig``) as ``muble generate`` produces ``split`` with it: a protocol split's
    own ``objects``, ``generator`` and ``dataset`` settings merged over the run's (``split_config``); ``cfg``
    itself without a protocol. A split the protocol does not name is a ``ConfigError`` that lists its splits.
    ``muble run``, the Gymnasium environments and ``muble serve`` build their plugins from it when ``split`` is
    set, then ``split_episode`` makes the split's indices."""
    from omegaconf import open_dict

    from muble.core.errors import ConfigError, unknown_name
    from muble.dataset.protocol import SPLIT_GROUPS, protocol_of, split_config

    protocol = protocol_of(cfg)
    if protocol is None:
        return cfg
    if split not in (protocol.get("splits") or {}):
        raise ConfigError(unknown_name(f"split of protocol '{protocol.get('name')}'", split,
                                       list(protocol.get("splits") or {})) + "; choose it with split=")
    # The protocol's settings of the split alone (its common ones, then the split's own), merged over the run's as
    # split_config merges them over a resolved copy.
    changes = split_config({"protocol": protocol, **{group: {} for group in SPLIT_GROUPS}}, split)
    out = cfg.copy()
    with open_dict(out):
        out.merge_with({group: changes[group] for group in SPLIT_GROUPS if changes[group]})
    return out


def cached_components(config: dict[str, Any], renderer: bool = True, task: bool = True) -> dict[str, Any]:
    """The configured plugins, built once per worker process (and config): workers run many indices. The renderer
    is kept open from index to index (``KeptRenderer``)."""
    key = json.dumps([config, renderer, task], sort_keys=True, default=str)
    if key not in _components_cache:
        from omegaconf import OmegaConf

        from muble.episode.components import build_components

        from muble.episode.components import KeptRenderer

        for components in _components_cache.values():
            if components.get("renderer") is not None:
                components["renderer"].inner.close()
        _components_cache.clear()
        components = build_components(OmegaConf.create(config), renderer=renderer, task=task)
        if components.get("renderer") is not None:
            # Every index of this process runs on its calling thread, one at a time: the renderer (its GL
            # context and uploaded meshes) serves them all instead of being made and closed per episode.
            components["renderer"] = KeptRenderer(components["renderer"], close_at_exit=True)
        _components_cache[key] = components
    return _components_cache[key]


def produce_index(job: IndexJob, timings: MutableMapping[str, float] | None = None) -> tuple[int, dict[str, str]]:
    """Generate and write everything of one scene index; returns (index, {relative path: sha256}).

    ``timings``, when given, gets the seconds of each stage added (``scene.<generator stage>``, ``scene.other``:
    choosing the template's instruction and its symbolic ground truth, masks, set-up; ``episode.physics``,
    ``episode.planning``, ``episode.keyframes``; ``image`` without sequences; ``writing``: encoding and files)."""
    stage: MutableMapping[str, float] = timings if timings is not None else {}

    def add(key: str, seconds: float) -> None:
        stage[key] = stage.get(key, 0.0) + seconds

    began = time.perf_counter()
    from muble.episode.runner import KeyframeStateRecorder, png_bytes, write_episode
    from muble.io.instructions_io import instruction_to_dict
    from muble.io.scene_io import scene_to_dict

    from muble.dataset.protocol import split_config

    cfg = split_config(job.config, job.split)  # a protocol split's own object set and generator settings
    ds = cfg["dataset"]
    layout = DatasetLayout(Path(ds["root"]), job.split)
    out = layout.split_dir
    components = cached_components(cfg)
    generated: dict[str, float] = {}
    try:
        suited = split_episode(cfg, job.split, job.index, components["object_set"], generated)
    finally:
        for name, seconds in generated.items():
            add(f"scene.{name}", seconds)
        add("scene.other", time.perf_counter() - began - sum(generated.values()))
    scene, task, instruction = suited.scene, suited.task, suited.instruction
    written: dict[str, str] = {}

    from muble.episode.components import episode_runner
    from omegaconf import OmegaConf

    if ds["sequences"]:
        # The keyframes' MuJoCo states are kept too, so that the keyframes can be rendered again later (Blender).
        cameras = cfg["episode"]["cameras"]
        recorder = KeyframeStateRecorder(components["renderer"], len(cameras)) if components["renderer"] else None
        runner = episode_runner(OmegaConf.create(cfg), {**components, "renderer": recorder})
        output = runner.execute(scene, instruction, task)
        add("episode.physics", output.timing.physics)
        add("episode.planning", output.timing.planning)
        add("episode.keyframes", output.timing.rendering)
        began = time.perf_counter()
        states = None if recorder is None else recorder.keyframe_states(
            output, cfg["robot"]["name"], cfg["objects"]["name"], cameras[0])
        written.update(write_episode(output, out, layout.stem(job.index), gif=ds["gif"],
                                     action_names=cfg.get("episode", {}).get("action_names", "registry"),
                                     states=states))
        image = output.keyframes[0] if output.keyframes else None
    else:
        began = time.perf_counter()
        image = _render_initial(episode_runner(OmegaConf.create(cfg), components), scene)
        add("image", time.perf_counter() - began)
        began = time.perf_counter()
        written[layout.scene(job.index)] = write_bytes_atomic(
            out / layout.scene(job.index), json.dumps(scene_to_dict(scene)).encode())
    if image is not None:
        written[layout.image(job.index)] = write_bytes_atomic(out / layout.image(job.index), png_bytes(image))
    instruction.split, instruction.image_index = job.split, job.index
    record = instruction_to_dict(instruction)
    record["ground_truth_actions"] = [[a.name, a.params] for a in suited.ground_truth]
    record["scene_samples"] = suited.samples
    written[layout.instruction(job.index)] = write_bytes_atomic(
        out / layout.instruction(job.index), json.dumps(record).encode())
    add("writing", time.perf_counter() - began)
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
