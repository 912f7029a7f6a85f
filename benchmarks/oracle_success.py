"""End-to-end success of the oracle agent with physics, per SHOP-VRB2 task type, and its failure taxonomy.

For every template a small split restricted to that template is written by ``muble generate`` (seeded, scenes
and instructions only) and evaluated by ``muble eval agent=oracle``: the real pipeline, MuJoCo physics, the
configured planner. Failed episodes are sorted into the failure classes of the taxonomy; execution errors are
split further by the primitive that failed, so that grasp failures (approach / close_gripper) show apart from
placing and carrying.

Goal: the oracle succeeds on at least 98% of the episodes of every task type (acceptance: 50 scenes each).

    python benchmarks/oracle_success.py [--scenes 50] [--templates stack_simple remove] [--seed 0] [--workers 2]

Datasets are cached under --root (a template's split is re-generated only when missing); runs are
deterministic in (seed, template, index).
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

GOAL = 0.98
GRASP_PRIMITIVES = ("approach", "close_gripper")


def muble(*args: str) -> None:
    exe = Path(sys.executable).with_name("muble")
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    proc = subprocess.run([str(exe), *args], env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout[-3000:] + proc.stderr[-3000:])
        raise SystemExit(f"muble {args[0]} failed with exit code {proc.returncode}")


def failure_kind(record: dict) -> str:
    """The failure class, with execution errors split by the primitive that failed."""
    outcome = record["outcome"]
    if outcome != "execution_error" or not record["primitives"]:
        return outcome
    failed = record["primitives"][-1].split("(")[0]
    return f"execution_error:{'grasp' if failed in GRASP_PRIMITIVES else failed}"


def evaluate_template(template: str, scenes: int, seed: int, root: Path, workers: int) -> list[dict]:
    data = root / f"{template}_s{seed}_n{scenes}"
    common = ["dataset.splits=[val]", f"dataset.root={data}", f"seed={seed}",
              f"dataset.workers={workers}", f"dataset.executor={'serial' if workers == 1 else 'processes'}"]
    if not (data / "manifest.json").is_file():
        muble("generate", *common, f"dataset.sizes=[{scenes}]", f"dataset.templates=[{template}]",
              "dataset.sequences=false", f"hydra.run.dir={data}_gen")
    out = root / f"{template}_s{seed}_n{scenes}_eval"
    muble("eval", "agent=oracle", *common, f"hydra.run.dir={out}", "evaluation.plot=false")
    return [json.loads(line) for line in (out / "episodes_val.jsonl").read_text().splitlines() if line.strip()]


def main() -> None:
    from muble.app.config import SHOPVRB2_TEMPLATES

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", type=int, default=10, help="scenes per template (acceptance: 50)")
    parser.add_argument("--templates", nargs="*", default=list(SHOPVRB2_TEMPLATES))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--root", type=Path, default=Path("/tmp/muble_oracle_success"))
    args = parser.parse_args()

    start = time.perf_counter()
    per_template, without_grasp, failures, examples = {}, {}, Counter(), {}
    for template in args.templates:
        records = evaluate_template(template, args.scenes, args.seed, args.root, args.workers)
        ok = sum(r["outcome"] == "success" for r in records)
        per_template[template] = round(ok / max(len(records), 1), 4)
        judged = [r for r in records if failure_kind(r) != "execution_error:grasp"]
        without_grasp[template] = round(ok / max(len(judged), 1), 4)
        kinds = Counter(failure_kind(r) for r in records if r["outcome"] != "success")
        failures.update(kinds)
        for r in records:
            if r["outcome"] != "success":
                examples.setdefault(failure_kind(r), f"{template} #{r['index']}: {r['error']}")
        print(f"{template:24s} {ok:3d}/{len(records):3d}  {100 * per_template[template]:5.1f}%  "
              f"{dict(kinds) if kinds else ''}", flush=True)
    total = sum(1 for _ in per_template)
    worst = min(per_template.values()) if per_template else 0.0
    grasp = failures.get("execution_error:grasp", 0)
    print("failure taxonomy:", dict(failures))
    for kind, example in sorted(examples.items()):
        print(f"  {kind}: {example[:300]}")
    print(json.dumps({
        "benchmark": "oracle_success", "metric": "min_success_rate_per_task_type", "value": worst, "unit": "ratio",
        "goal": GOAL, "scenes_per_template": args.scenes, "templates": total, "seed": args.seed,
        "success_per_template": per_template, "failures": dict(failures), "grasp_failures": grasp,
        "min_success_excluding_grasp_failures": min(without_grasp.values()) if without_grasp else 0.0,
        "seconds": round(time.perf_counter() - start, 1),
    }))


if __name__ == "__main__":
    main()
