"""``muble run``: one SHOP-VRB2 episode on the configured robot, renderer, planner, task, objects and agent.

It generates scene ``scene_index`` from ``seed``, picks an instruction of the configured task (with
``split=NAME``: index ``scene_index`` of that split as ``muble generate`` makes it, its scene, template and
instruction, see ``muble.episode.components.split_episode``), lets the agent act with real physics, renders a
keyframe after every primitive, and writes the scene, the sequence file, the keyframes, a GIF, the keyframes'
MuJoCo states (``keyframes/<episode>_states.npz``, for ``muble render --keyframes``) and a manifest under the
run's output folder. The last line printed is the outcome.
"""
from __future__ import annotations

import logging
import numbers
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from muble.app.hydra_app import run_hydra_job
from muble.core.errors import MubleError
from muble.episode.components import build_components, episode_runner, scene_generator
from muble.episode.runner import KeyframeStateRecorder
from muble.io.manifest import make_manifest
from muble.io.scene_io import write_json_atomic

log = logging.getLogger(__name__)

# Program steps whose answer is a weight in grams (the SHOP-VRB2 queries).
_WEIGHT_QUERIES = ("query_weight",)


def format_answer(value: Any, instruction: Any = None) -> str:
    """An answer for people: weights in grams to 0.1 g (``261.3 g``), per object where the answer maps ids to
    values; anything else as it is. The exact value stays in the files."""
    program = getattr(instruction, "program", None) or []
    unit = " g" if program and program[-1].get("type") in _WEIGHT_QUERIES else ""

    def one(v: Any) -> str:
        if isinstance(v, numbers.Real) and not isinstance(v, bool):
            return f"{float(v):.1f}{unit}"
        return str(v)

    if isinstance(value, dict):
        return ", ".join(f"object {k}: {one(v)}" for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return ", ".join(one(v) for v in value)
    return one(value)


# Scenes after the asked one looked at, when the task has no instruction for it, to name one that suits in the
# error (each costs a scene's generation, about a second).
SUITED_SCENES_LOOKED_AT = 10


def _suited_scene_index(generator: Any, task: Any, seed: int, index: int, first: int | None = None) -> int | None:
    """The first scene index from ``first`` (default: the one after ``index``) to ``index +
    SUITED_SCENES_LOOKED_AT`` for which ``task`` has an instruction with ``seed``, or None."""
    from muble.episode.runner import instruction_rng

    for candidate in range(index + 1 if first is None else first, index + 1 + SUITED_SCENES_LOOKED_AT):
        try:
            scene = generator.generate(candidate)
        except MubleError:
            continue
        if task.generate(scene, instruction_rng(seed, candidate)):
            return candidate
    return None


def _physical_properties_hint(cfg: DictConfig, components: dict[str, Any]) -> str | None:
    """Where the generator draws not every hidden physical property (``generator.physical_properties``) and the
    task has an instruction once it does (the physical family compares friction, centre of mass, contents: only
    objects whose scene carries them take part), the override that makes such scenes; else None."""
    from muble.core.physical_properties import PROPERTIES

    chosen = list(cfg.generator.physical_properties)
    if all(name in chosen for name in PROPERTIES):
        return None
    override = f"generator.physical_properties=[{','.join(PROPERTIES)}]"
    probe = cfg.copy()
    probe.generator.physical_properties = list(PROPERTIES)
    generator = scene_generator(probe, components["object_set"])
    try:
        suited = _suited_scene_index(generator, components["task"], cfg.seed, cfg.scene_index, cfg.scene_index)
    finally:
        generator.close()
    if suited is None:
        return None
    where = "this scene has one" if suited == cfg.scene_index else f"scene_index={suited} has one"
    return (f"its scenes carry no hidden physical property it needs (generator.physical_properties={chosen}): with "
            f"{override} {where} (the physical family; docs/physical_properties.md)")


def _configured_scene(cfg: DictConfig, components: dict[str, Any]) -> tuple[Any, Any]:
    """Scene ``scene_index`` of the generator seeded with ``seed`` and the configured task's instruction for it;
    a task with none for the scene is an error that names a scene that has one."""
    from muble.episode.runner import NoInstructionError, choose_instruction, no_instruction

    generator = scene_generator(cfg, components["object_set"])
    try:
        scene = generator.generate(cfg.scene_index)
        try:
            instruction = choose_instruction(components["task"], scene, cfg.seed, cfg.scene_index, cfg.task.name)
        except NoInstructionError:
            suited = _suited_scene_index(generator, components["task"], cfg.seed, cfg.scene_index)
            last = cfg.scene_index + SUITED_SCENES_LOOKED_AT
            hint = (f"scene_index={suited} has one with this seed (muble run uses the scene it is given; "
                    "muble generate looks for one that suits)" if suited is not None else
                    _physical_properties_hint(cfg, components) or
                    f"nor do scenes {cfg.scene_index + 1}..{last}: choose another seed or task")
            raise no_instruction(cfg.task.name, cfg.scene_index, cfg.seed, hint) from None
    finally:
        generator.close()
    return scene, instruction


def job(cfg: DictConfig) -> dict:
    from muble.dataset.production import split_seed, with_split
    from muble.episode.components import split_episode
    from muble.episode.runner import write_episode

    cfg = with_split(cfg)  # with split=NAME: a protocol split's own objects, generator and template mix
    split = None if cfg.get("split") is None else str(cfg.split)
    out_dir = Path(cfg.output.dir)
    components = build_components(cfg)
    seeds = {"seed": cfg.seed, "scene_index": cfg.scene_index}
    if split is not None:
        seeds.update(split=split, split_seed=split_seed(cfg.seed, split))
    manifest = make_manifest(seeds, OmegaConf.to_container(cfg, resolve=True))
    summary = {kind: type(c).__name__ for kind, c in components.items() if kind != "sensors" and c is not None}
    if cfg.dry_run:
        write_json_atomic(out_dir / "manifest.json", manifest, indent=2)
        print(f"muble run: dry run; built {', '.join(f'{k}={v}' for k, v in summary.items())}; "
              f"manifest in {out_dir}")
        return summary
    if split is None:
        task = components["task"]
        scene, instruction = _configured_scene(cfg, components)
        stem = f"episode_{cfg.seed}_{cfg.scene_index:06d}"
    else:
        suited = split_episode(cfg, split, cfg.scene_index, components["object_set"])
        scene, instruction, task = suited.scene, suited.instruction, suited.task
        log.info("index %d of split %s as muble generate makes it: template %s (the split's template mix; "
                 "task= is not used)", cfg.scene_index, split, suited.template)
        stem = f"episode_{cfg.seed}_{split}_{cfg.scene_index:06d}"
    log.info("instruction: %s", instruction.instruction)
    recorder = KeyframeStateRecorder(components["renderer"], len(cfg.episode.cameras))
    output = episode_runner(cfg, {**components, "renderer": recorder}).execute(scene, instruction, task)
    states = recorder.keyframe_states(output, cfg.robot.name, cfg.objects.name, cfg.episode.cameras[0])
    written = write_episode(output, out_dir, stem, gif=cfg.output.gif, action_names=cfg.episode.action_names,
                            states=states)
    manifest["outputs"] = written
    manifest["outcome"] = output.result.outcome.value
    write_json_atomic(out_dir / "manifest.json", manifest, indent=2)
    r = output.result
    # The instruction and each step were logged as they happened (muble.episode.runner): not printed again here.
    if r.answer is not None:
        print(f"answer: {format_answer(r.answer.value, instruction)}")
    if r.error:
        print(f"error: {r.error}")
    gif = next((p for p in written if p.endswith(".gif")), None)
    print(f"outputs: {out_dir}" + (f" (GIF {out_dir / gif})" if gif else ""))
    print(f"outcome: {r.outcome.value} ({len(r.actions)} primitives, {output.timing.total:.1f} s)")
    return {"outcome": r.outcome.value, **summary}


def main(argv: list[str]) -> int:
    return run_hydra_job("run", argv, job, prog="muble run")
