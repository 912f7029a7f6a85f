"""One evaluation episode per dataset index: the stored scene and instruction, the configured agent, real physics.

``evaluate_index`` runs in any worker (local process, Ray task or the driver) and returns a plain record, so
results are the same whichever executor ran them. The task that judges an episode is the instruction's template.

Two optional members of an agent are read here, so any agent can use them: an ``output_dir`` attribute is set to
the run's output folder before each episode (an agent that keeps files of its own, such as the ``llm`` agent's
request logs, puts them beside the records), and ``stats()``, called after the episode, returns that episode's
counters (a mapping of names to numbers: tokens, requests, retries …), stored in the record's ``agent_stats`` and
summed per task type in the report (``muble.evaluation.report.agent_totals``). A third, ``samples()``, also read
after the episode, returns its observations per request (names to lists of numbers, such as the seconds each
request waited), stored in the record's ``agent_samples`` only where an agent has it; the report takes the
latency's percentiles from them (``muble.evaluation.usage``).
"""
from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import Any

from muble.core.errors import MubleError, PhysicsError, SceneValidationError, unknown_name
from muble.core.types import Outcome
from muble.dataset.production import IndexJob, cached_components, split_seed
from muble.dataset.protocol import episode_config
from muble.core.symbolic import ArmState
from muble.episode.fingerprint import platform
from muble.episode.plain import plain
from muble.evaluation.report import UNKNOWN
from muble.io.layout import DatasetLayout

log = logging.getLogger(__name__)

# One unit of evaluation work: the same (config, split, index) record as a dataset job.
EvalJob = IndexJob


def build_components(config: dict[str, Any]) -> dict[str, Any]:
    """The configured plugins, once per process and config; no renderer unless ``evaluation.render``, and no task
    (each instruction names its own template)."""
    from muble.evaluation.resume import draws

    return cached_components(config, renderer=draws(config), task=False)


def _record(job: EvalJob) -> dict[str, Any]:
    """The fields of a result known before anything is read; the data fills in the rest."""
    return {"split": job.split, "index": job.index, "template": UNKNOWN, "task": None, "instruction": None,
            "ground_truth_primitives": 0, "ground_truth_measurements": 0, "file": None}


def _failed(out: dict[str, Any], outcome: Outcome, error: str, file: str | None) -> dict[str, Any]:
    return {**out, "outcome": outcome.value, "primitives": [], "measurements": 0, "answer": None, "error": error,
            "timing": None, "keyframes": [], "file": file}


def measuring_primitives() -> set[str]:
    """The registered primitives that measure a property of an object (``PrimitiveAction.measures``: a weight, a
    stiffness). Counting their calls tells how much an agent measured beside what the task needed; the registry
    says which they are, so a plugin's own measuring primitive counts too."""
    from muble.plugins.registry import get_registry

    registry = get_registry()
    return {name for name in registry.names("primitive")
            if getattr(registry.get("primitive", name).record.factory, "measures", None)}


def ground_truth_counts(record: dict[str, Any]) -> dict[str, int]:
    """``ground_truth_primitives`` and ``ground_truth_measurements`` of a stored instruction record: the length of
    its ground-truth action sequence (the oracle's plan, ``[name, params]`` per primitive) and how many of those
    actions measure. Names in the original release's spelling count as the primitives they stand for."""
    from muble.io.action_names import from_original

    actions = record.get("ground_truth_actions", [])
    measuring = measuring_primitives()
    measured = sum(1 for a in actions if isinstance(a, (list, tuple)) and a and isinstance(a[0], str)
                   and from_original(a[0]) in measuring)
    return {"ground_truth_primitives": len(actions), "ground_truth_measurements": measured}


def _describe(job: EvalJob, e: BaseException) -> str:
    """An error for the record, logged: ours say what to change; anything else (a bug) is named by its type too,
    with its traceback in the log."""
    log.warning("%s %d: %s", job.split, job.index, e, exc_info=not isinstance(e, MubleError))
    return str(e) if isinstance(e, MubleError) else f"{type(e).__name__}: {e}"


def evaluate_index(job: EvalJob, agent: Any = None) -> dict[str, Any]:
    """Run the agent on one stored index; returns its result record whatever the files hold or the code raises.

    A file that cannot be read, parsed or built is ``invalid_data`` with the file named in ``file``; a scene that
    builds but breaks the physics is ``broken_scene``; any other error ends the episode as ``execution_error`` with
    the exception's type and message (and its traceback in the log), never as a crash of the evaluation.
    """
    out = _record(job)
    try:
        return _evaluate(job, out, agent)
    except Exception as e:  # a bug, not the data's fault: recorded with its type, traceback logged
        log.exception("%s %d: unexpected error", job.split, job.index)
        return _failed(out, Outcome.EXECUTION_ERROR, f"unexpected {type(e).__name__}: {e}", out["file"])


def _evaluate(job: EvalJob, out: dict[str, Any], agent: Any = None) -> dict[str, Any]:
    from omegaconf import OmegaConf

    from muble.episode.components import episode_runner
    from muble.evaluation.files import uses_files
    from muble.plugins.registry import get_registry

    cfg = episode_config(job.config, job.split)  # a protocol split's disturbances and sensor noise
    layout = DatasetLayout(Path(cfg["dataset"]["root"]), job.split)
    loaded = _from_files(job, out) if uses_files(cfg["dataset"]) else _from_dataset(job, out, layout)
    if isinstance(loaded, dict):
        return loaded  # the data's fault: the record says which file and why
    scene, instruction, scene_file, scene_name = loaded
    registry = get_registry()
    task = registry.create("task", instruction.template_id, {})
    runner = episode_runner(OmegaConf.create(cfg), build_components(cfg))
    if agent is not None:  # another agent than the configured one (muble verify's replay of the records)
        runner = dataclasses.replace(runner, agent=agent)
    agent = getattr(runner, "agent", None)
    output_dir = (cfg.get("output") or {}).get("dir")
    if output_dir and hasattr(agent, "output_dir"):
        agent.output_dir = Path(output_dir)
    runner.seed = split_seed(int(cfg.get("seed") or 0), job.split)  # the split's own disturbance draws
    runner.decision_timeout = float(cfg["evaluation"].get("decision_timeout") or 0.0)
    runner.step_log_level = logging.DEBUG  # quiet by default: one line per episode, its primitives under --verbose
    try:
        output = runner.execute(scene, instruction, task, key=job.index)
    except SceneValidationError as e:  # the runner could not build the scene: an object model or mass refused
        return _failed(out, Outcome.INVALID_DATA, f"{scene_file}: {_describe(job, e)}", scene_name)
    except PhysicsError as e:  # built, but does not start at rest or breaks the simulation
        return _failed(out, Outcome.BROKEN_SCENE, f"{type(e).__name__}: {_describe(job, e)}", scene_name)
    result = output.result
    written = []
    if cfg["evaluation"]["render"] and cfg["evaluation"]["keyframes"] and output.keyframes:
        from muble.episode.runner import png_bytes
        from muble.io.atomic import write_bytes_atomic

        folder = Path(cfg["output"]["dir"]) / "keyframes" / layout.stem(job.index)
        for i, rgb in enumerate(output.keyframes):
            write_bytes_atomic(folder / f"frame_{i:04d}.png", png_bytes(rgb))
            written.append(str(folder / f"frame_{i:04d}.png"))
    t = output.timing
    measuring = measuring_primitives()
    steps = [{"action": str(step.action), "success": bool(step.result.success),
              "measurement": plain(step.result.measurement), "failure_reason": step.result.failure_reason,
              "held": None if step.scene_gt is None else ArmState.of(step.scene_gt).held}
             for step in result.steps]
    return {**out, "outcome": result.outcome.value, "primitives": [str(a) for a in result.actions], "steps": steps,
            "measurements": sum(1 for step in result.steps if step.action.name in measuring and step.result.success),
            "answer": None if result.answer is None else plain(result.answer.value), "error": result.error,
            "timing": {"physics": t.physics, "planning": t.planning, "rendering": t.rendering, "total": t.total},
            "keyframes": written, "file": scene_name if result.outcome == Outcome.BROKEN_SCENE else None,
            "traceback": result.traceback,  # agent_error: where the agent raised
            "agent_stats": agent_stats(agent), "fingerprints": output.fingerprints, "platform": platform(),
            **agent_samples(agent),
            **({"disturbances": output.disturbances, "disturbances_planned": output.disturbances_planned}
               if runner.disturbances else {})}


def agent_stats(agent: Any) -> dict[str, float] | None:
    """The agent's counters of the episode just run (its optional ``stats()``), numbers only; None without."""
    stats = getattr(agent, "stats", None)
    if not callable(stats):
        return None
    try:
        values = stats()
    except Exception:  # noqa: BLE001 - an agent's bookkeeping must not cost the episode's record
        log.exception("agent.stats() raised; the record has no agent_stats")
        return None
    return {str(k): float(v) for k, v in dict(values or {}).items()
            if isinstance(v, (int, float)) and not isinstance(v, bool)}


def agent_samples(agent: Any) -> dict[str, dict[str, list[float]]]:
    """``{"agent_samples": …}``: the agent's per-request observations of the episode just run (its optional
    ``samples()``: names to lists of numbers); empty without, so other agents' records are as they were."""
    samples = getattr(agent, "samples", None)
    if not callable(samples):
        return {}
    try:
        values = dict(samples() or {})
    except Exception:  # noqa: BLE001 - an agent's bookkeeping must not cost the episode's record
        log.exception("agent.samples() raised; the record has no agent_samples")
        return {}
    return {"agent_samples": {str(k): [float(v) for v in series] for k, series in values.items()}}


def _instruction_checked(job: EvalJob, out: dict[str, Any], record: dict[str, Any], instruction: Any,
                         instruction_file: Any, instruction_name: str) -> dict[str, Any] | None:
    """Fill the record from the instruction; a failed record when its template is not registered."""
    from muble.io.scene_io import in_file
    from muble.plugins.registry import get_registry

    out.update(task=instruction.task_id, instruction=instruction.instruction, **ground_truth_counts(record))
    registry = get_registry()
    if instruction.template_id not in registry.names("task"):
        error = in_file(SceneValidationError(unknown_name("template", instruction.template_id, registry.names("task")),
                                             field="template_id"), instruction_file)
        return _failed(out, Outcome.INVALID_DATA, _describe(job, error), instruction_name)
    out["template"] = instruction.template_id
    return None


def _from_files(job: EvalJob, out: dict[str, Any]) -> dict[str, Any] | tuple:
    """Instruction ``job.index`` of ``dataset.instructions_file`` and its scene from ``dataset.scenes_file``."""
    from muble.evaluation.files import load_files

    dataset = job.config["dataset"]
    instruction_name = f"{Path(dataset['instructions_file']).name} instruction {job.index}"
    scene_name = Path(dataset["scenes_file"]).name
    try:
        record, instruction = load_files(dataset).instruction(job.index)
    except Exception as e:  # recorded with its type and message
        return _failed(out, Outcome.INVALID_DATA, _describe(job, e), instruction_name)
    failed = _instruction_checked(job, out, record, instruction, dataset["instructions_file"], instruction_name)
    if failed is not None:
        return failed
    try:
        scene = load_files(dataset).scene_for(instruction)
    except Exception as e:  # recorded with its type and message
        return _failed(out, Outcome.INVALID_DATA, _describe(job, e), scene_name)
    scene_name = f"{scene_name} scene {scene.image_filename or scene.image_index}"
    return scene, instruction, Path(dataset["scenes_file"]), scene_name


def _from_dataset(job: EvalJob, out: dict[str, Any], layout: DatasetLayout) -> dict[str, Any] | tuple:
    """The stored scene and instruction of ``job.index`` in a generated dataset split."""
    from muble.io.instructions_io import load_instruction
    from muble.io.scene_io import load_scene

    scene_file, instruction_file = (layout.split_dir / layout.scene(job.index),
                                    layout.split_dir / layout.instruction(job.index))
    scene_name, instruction_name = (f"{job.split}/{layout.scene(job.index)}",
                                    f"{job.split}/{layout.instruction(job.index)}")

    # The data: every way a file can be unusable is the data's fault (invalid_data), named by file.
    if not instruction_file.is_file():
        error = SceneValidationError(f"the instruction file {instruction_file} is missing (the dataset lists this "
                                     "index)")
        return _failed(out, Outcome.INVALID_DATA, _describe(job, error), instruction_name)
    try:
        record, instruction = load_instruction(instruction_file)
        if instruction is None:
            raise SceneValidationError(f"{instruction_file} has no instruction (no template applied to the scene)")
    except Exception as e:  # recorded with its type and message
        return _failed(out, Outcome.INVALID_DATA, _describe(job, e), instruction_name)
    failed = _instruction_checked(job, out, record, instruction, instruction_file, instruction_name)
    if failed is not None:
        return failed
    if not scene_file.is_file():
        error = SceneValidationError(f"the scene file {scene_file} is missing (the dataset lists this index)")
        return _failed(out, Outcome.INVALID_DATA, _describe(job, error), scene_name)
    try:
        scene = load_scene(scene_file)
    except Exception as e:  # recorded with its type and message
        return _failed(out, Outcome.INVALID_DATA, _describe(job, e), scene_name)
    return scene, instruction, scene_file, scene_name
