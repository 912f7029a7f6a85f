"""End-to-end success of the oracle agent with physics, per SHOP-VRB2 task type, and its failure taxonomy.

Each seed's scenes are a ``val`` split made the way ``muble generate`` makes a dataset: every template gets an
equal share of the indices, and each index a scene drawn to suit its template and kept only when the generator's
checks pass (visibility, rest, the robot's reach, the ground truth's stacks standing). ``muble eval
agent=oracle`` then runs every episode: the real pipeline, MuJoCo physics, the configured planner. Failed
episodes are sorted into the failure classes of the taxonomy; execution errors are split further by the primitive
that failed, so grasp failures (approach / close_gripper) show apart from carrying and placing.

Goal: the oracle succeeds on at least 99% of a seed's episodes, with at most one failure in 30 for every task type.

    python benchmarks/oracle_success.py [--scenes 30] [--templates stack_simple remove] [--seed 0] [--workers 2]
    python benchmarks/oracle_success.py --scenes 30 --seeds 7 8 9     # several seeds: overall and per seed

Datasets are kept under --root/s<seed> (generation resumes); every run is deterministic in (seed, scene index).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

GOAL = 0.99
GRASP_PRIMITIVES = ("approach", "close_gripper")
SPLIT = "val"


def muble(*args: str) -> None:
    exe = Path(sys.executable).with_name("muble")
    proc = subprocess.run([str(exe), *args], env=dict(os.environ), capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout[-3000:] + proc.stderr[-3000:])
        raise SystemExit(f"muble {args[0]} failed with exit code {proc.returncode}")


def failure_kind(record: dict) -> str:
    """The failure class, with execution errors (too many failed primitives) split by the last one that failed."""
    from muble.core.types import Outcome

    outcome = record["outcome"]
    if outcome != Outcome.EXECUTION_ERROR:
        return outcome
    error = record.get("error") or ""
    failed = error.split("the last ", 1)[1].split("(")[0] if "the last " in error else \
        (record["primitives"][-1].split("(")[0] if record["primitives"] else "unknown")
    return f"execution_error:{'grasp' if failed in GRASP_PRIMITIVES else failed}"


def evaluate_seed(seed: int, templates: list[str], scenes: int, root: Path, workers: int) -> list[dict]:
    """The oracle's episodes on a ``val`` split of ``scenes`` per template, generated as ``muble generate`` makes
    a dataset (every index its template, a scene drawn to suit it, the generator's checks) and run by
    ``muble eval``; generation resumes where a previous run stopped."""
    data = root / f"s{seed}"
    executor = [f"dataset.workers={workers}", f"dataset.executor={'serial' if workers == 1 else 'processes'}"]
    muble("generate", f"seed={seed}", f"dataset.splits=[{SPLIT}]", f"dataset.sizes=[{scenes * len(templates)}]",
          f"dataset.templates=[{','.join(templates)}]", "dataset.sequences=false", f"dataset.root={data}",
          *executor, f"hydra.run.dir={root / f's{seed}_generate'}")
    out = root / f"s{seed}_eval"
    muble("eval", "agent=oracle", f"seed={seed}", f"dataset.splits=[{SPLIT}]", f"dataset.root={data}", *executor,
          f"hydra.run.dir={out}", "evaluation.plot=false")
    return [json.loads(line) for line in (out / f"episodes_{SPLIT}.jsonl").read_text().splitlines() if line.strip()]


def run_seed(args, seed: int) -> dict:
    """Every template on ``seed``'s split; prints one line per template and the failure examples."""
    start = time.perf_counter()
    every = evaluate_seed(seed, args.templates, args.scenes, args.root, args.workers)
    per_template, without_grasp, failures, examples = {}, {}, Counter(), {}
    retried = {}  # episodes in which the oracle retried a failed primitive (an ``attempt=`` call), per template
    episodes, successes, failed_per_template = 0, 0, {}
    for template in args.templates:
        records = [r for r in every if r["template"] == template]
        ok = sum(r["outcome"] == "success" for r in records)
        episodes, successes = episodes + len(records), successes + ok
        failed_per_template[template] = len(records) - ok
        retried[template] = sum(any("attempt=" in p for p in r["primitives"]) for r in records)
        per_template[template] = round(ok / max(len(records), 1), 4)
        judged = [r for r in records if failure_kind(r) != "execution_error:grasp"]
        without_grasp[template] = round(ok / max(len(judged), 1), 4)
        kinds = Counter(failure_kind(r) for r in records if r["outcome"] != "success")
        failures.update(kinds)
        for r in records:
            if r["outcome"] != "success":
                examples.setdefault(failure_kind(r), f"{template} #{r['index']}: {r['error']}")
        print(f"seed {seed} {template:24s} {ok:3d}/{len(records):3d}  {100 * per_template[template]:5.1f}%  "
              f"retried in {retried[template]:2d}  {dict(kinds) if kinds else ''}", flush=True)
    print(f"seed {seed} failure taxonomy:", dict(failures))
    for kind, example in sorted(examples.items()):
        print(f"  {kind}: {example[:300]}")
    return {
        "seed": seed, "success_per_template": per_template, "failures": dict(failures),
        "grasp_failures": failures.get("execution_error:grasp", 0), "episodes_with_retries": retried,
        "min_success_excluding_grasp_failures": min(without_grasp.values()) if without_grasp else 0.0,
        "episodes": episodes, "successes": successes, "overall": round(successes / max(episodes, 1), 4),
        "max_failures_per_template": max(failed_per_template.values(), default=0),
        "seconds": round(time.perf_counter() - start, 1),
    }


def main() -> None:
    from muble.io.instructions_io import SHOPVRB2_TEMPLATES

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", type=int, default=10, help="scenes per template (acceptance: 30)")
    parser.add_argument("--templates", nargs="*", default=list(SHOPVRB2_TEMPLATES))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seeds", type=int, nargs="*", help="several seeds in turn (overrides --seed)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--root", type=Path, default=Path("/tmp/muble_oracle_success"))
    args = parser.parse_args()

    runs = [run_seed(args, seed) for seed in (args.seeds or [args.seed])]
    allowed = max(1, args.scenes // 30)  # failures per task type the goal allows: one in 30
    worst = min(min(r["success_per_template"].values(), default=0.0) for r in runs)
    summary = {
        "benchmark": "oracle_success", "metric": "overall success of the worst seed", "unit": "ratio",
        "value": min(r["overall"] for r in runs), "goal": GOAL, "failures_per_type_allowed": allowed,
        "min_success_rate_per_task_type": worst, "scenes_per_template": args.scenes,
        "templates": len(args.templates),
        "meets_goal": all(r["overall"] >= GOAL and r["max_failures_per_template"] <= allowed for r in runs),
    }
    if len(runs) == 1:
        summary.update(runs[0])
    else:
        episodes, successes = sum(r["episodes"] for r in runs), sum(r["successes"] for r in runs)
        summary.update(seeds=[r["seed"] for r in runs], overall=round(successes / max(episodes, 1), 4),
                       episodes=episodes, per_seed=runs, seconds=round(sum(r["seconds"] for r in runs), 1))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
