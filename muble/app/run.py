"""``muble run``: one SHOP-VRB2 episode on the configured robot, renderer, planner, task, objects and agent.

It generates scene ``scene_index`` from ``seed``, picks an instruction of the configured task, lets the agent
act with real physics, renders a keyframe after every primitive, and writes the scene, the sequence file, the
keyframes, a GIF and a manifest under the run's output folder. The last line printed is the outcome.
"""
from __future__ import annotations

import logging
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from muble.app.config import GROUP_OF_KIND
from muble.app.hydra_app import run_hydra_job
from muble.core.manifest import make_manifest
from muble.core.scene_io import write_json_atomic
from muble.plugins.registry import get_registry

log = logging.getLogger(__name__)


def build_components(cfg: DictConfig, renderer: bool = True, task: bool = True) -> dict[str, object]:
    """Instantiate every configured plugin through the registry (a typo in any option fails here, early).

    ``renderer=False`` leaves the renderer out (None); ``task=False`` the task (when each instruction names its own).
    """
    registry = get_registry()
    components: dict[str, object] = {}
    for kind, group in GROUP_OF_KIND.items():
        if (kind == "renderer" and not renderer) or (kind == "task" and not task):
            components[kind] = None
            continue
        node = cfg[group]
        components[kind] = registry.create(kind, node.name, node)
    components["sensors"] = {name: registry.create("sensor", name, options or {})
                             for name, options in cfg.sensors.enabled.items()}
    return components


def episode_runner(cfg: DictConfig, components: dict[str, object]):
    from muble.episode.runner import EpisodeRunner

    robot = OmegaConf.to_container(cfg.robot, resolve=True)
    return EpisodeRunner(get_registry(), robot, components["planner"], components["agent"],
                         components["object_set"], cfg.objects.name, components["sensors"], components["renderer"],
                         tuple(cfg.episode.cameras), cfg.episode.max_steps)


def scene_generator(cfg: DictConfig, object_set: object):
    from muble.generation.generator import SceneGenerator

    options = OmegaConf.to_container(cfg.generator, resolve=True)
    return SceneGenerator(options, seed=cfg.seed, object_set=object_set)


def job(cfg: DictConfig) -> dict:
    from muble.episode.runner import choose_instruction, write_episode

    out_dir = Path(cfg.output.dir)
    components = build_components(cfg)
    manifest = make_manifest({"seed": cfg.seed, "scene_index": cfg.scene_index},
                             OmegaConf.to_container(cfg, resolve=True))
    summary = {kind: type(c).__name__ for kind, c in components.items() if kind != "sensors" and c is not None}
    if cfg.dry_run:
        write_json_atomic(out_dir / "manifest.json", manifest, indent=2)
        print(f"muble run: dry run; built {', '.join(f'{k}={v}' for k, v in summary.items())}; "
              f"manifest in {out_dir}")
        return summary
    generator = scene_generator(cfg, components["object_set"])
    try:
        scene = generator.generate(cfg.scene_index)
    finally:
        generator.close()
    instruction = choose_instruction(components["task"], scene, cfg.seed, cfg.scene_index)
    log.info("instruction: %s", instruction.instruction)
    output = episode_runner(cfg, components).execute(scene, instruction, components["task"])
    stem = f"episode_{cfg.seed}_{cfg.scene_index:06d}"
    written = write_episode(output, out_dir, stem, gif=cfg.output.gif)
    manifest["outputs"] = written
    manifest["outcome"] = output.result.outcome.value
    write_json_atomic(out_dir / "manifest.json", manifest, indent=2)
    r = output.result
    print(f"instruction: {instruction.instruction}")
    print(f"actions: {', '.join(str(a) for a in r.actions)}")
    if r.answer is not None:
        print(f"answer: {r.answer.value}")
    if r.error:
        print(f"error: {r.error}")
    gif = next((p for p in written if p.endswith(".gif")), None)
    print(f"outputs: {out_dir}" + (f" (GIF {out_dir / gif})" if gif else ""))
    print(f"outcome: {r.outcome.value} ({len(r.actions)} primitives, {output.timing.total:.1f} s)")
    return {"outcome": r.outcome.value, **summary}


def main(argv: list[str]) -> int:
    return run_hydra_job("run", argv, job, prog="muble run")
