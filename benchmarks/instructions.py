"""Instruction generation throughput on one core, plus the acceptance statistics over 1,000 sampled scenes.

The statistics (words per instruction, ground-truth primitives per plan, oracle success in the symbolic
world) cover every generated instruction.

Run from the repository root: ``python benchmarks/instructions.py [--scenes 1000] [--original CHECKOUT]``.
Timings cover generation only (descriptions with their ambiguity checks, option rejection, text, program with
recorded outputs), on scenes sampled beforehand. The anchor is the original MuBlE generator run on this machine
type on its ten demo scenes repeated 50 times: 4,032 instructions in 1.21 s wall, interpreter start included
(about 3,300/s).

The acceptance compares CPU-seconds on one core with both generators measured in the same run: given a checkout
of the original repository (github.com/michaal94/MuBlE) as ``--original``, its own generator runs on the same demo
scenes x50 in a child process on this process's core (as its demo runs it, interpreter start and JSON output
included, as the anchor was), and ``speed_vs_original`` is this generator's instructions per CPU-second over
the original's.
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from muble import Outcome
from muble.core import streams
from muble.io.scene_io import load_scenes
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.episodes import run_symbolic_episode
from muble_plugins.common.synthetic import sample_scenes
from muble_plugins.tasks.generator import generate_instructions
from muble_plugins.tasks.templates import TEMPLATES

ANCHOR_PER_S = 4032 / 1.21
GOAL_PER_S = 5000
REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "muble-demo" / "NS_AP_demo_scenes.json"


INSTRUCTIONS = streams.declare("bench.instructions", "the instructions generated for a scene (repeat, scene index)")


def throughput(scenes, seed: int, repeats: int = 1) -> tuple[int, float]:
    start = time.perf_counter()
    made = 0
    for r in range(repeats):
        for s in scenes:
            made += len(generate_instructions(s, streams.stream(INSTRUCTIONS, seed, r, s.image_index)))
    return made, time.perf_counter() - start


def original_generator(checkout: Path, scenes_file: Path, repeats: int) -> tuple[int, float]:
    """Instructions made and CPU-seconds (user and system) of the original MuBlE generator on the scenes of
    ``scenes_file`` repeated ``repeats`` times: ``instruction_generation/generate_instructions.py`` of a checkout
    of its repository with the configuration of its demo (its progress lines off), in a child process."""
    folder = checkout / "instruction_generation"
    if not (folder / "generate_instructions.py").is_file():
        raise SystemExit(f"--original {checkout}: no instruction_generation/generate_instructions.py there; give a "
                         "checkout of github.com/michaal94/MuBlE")
    with tempfile.TemporaryDirectory() as tmp:
        data = json.loads(scenes_file.read_text())
        data["scenes"] = data["scenes"] * repeats
        scenes, out = Path(tmp) / "scenes.json", Path(tmp) / "out" / "instructions.json"
        scenes.write_text(json.dumps(data))
        config = json.loads((checkout / "demo" / "configs" / "instruction_generation.json").read_text())
        config.update(input_scene_file=str(scenes), output_instruction_file=str(out), verbose=False)
        (Path(tmp) / "config.json").write_text(json.dumps(config))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run([sys.executable, "generate_instructions.py", "-c", str(Path(tmp) / "config.json")],
                       cwd=folder, check=True, stdout=subprocess.DEVNULL)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        made = len(json.loads(out.read_text())["instructions"])
    return made, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def summary(values: list[int]) -> dict:
    if not values:
        return {}
    return {"min": int(min(values)), "median": float(np.median(values)), "max": int(max(values)),
            "histogram": dict(sorted(collections.Counter(values).items()))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--original", type=Path, default=None,
                        help="a checkout of the original MuBlE repository, to run its generator in the same run")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core

    scenes = sample_scenes(args.seed, args.scenes)
    throughput(scenes[:20], args.seed)  # warm caches and imports
    made, seconds = throughput(scenes, args.seed)
    reference_rate = reference_cpu_rate = original_cpu_rate = None
    if REFERENCE.is_file():
        _, demo = load_scenes(REFERENCE)
        cpu = time.process_time()
        ref_made, ref_seconds = throughput(demo, args.seed, repeats=50)
        reference_rate, reference_cpu_rate = ref_made / ref_seconds, ref_made / (time.process_time() - cpu)
        if args.original is not None:
            original_made, original_cpu = original_generator(args.original, REFERENCE, 50)
            original_cpu_rate = original_made / original_cpu

    # Acceptance statistics over every scene: words, plan lengths, templates per scene, oracle outcomes.
    words: dict[str, list[int]] = collections.defaultdict(list)
    plan_lengths: dict[str, list[int]] = collections.defaultdict(list)
    scenes_with: collections.Counter = collections.Counter()
    oracle: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for s in scenes:
        for ins in generate_instructions(s, streams.stream(INSTRUCTIONS, args.seed, 0, s.image_index)):
            t = ins.template_id
            scenes_with[t] += 1
            words[t].append(len(ins.instruction.split()))
            episode = run_symbolic_episode(ins, s, OracleAgent())
            oracle[t][episode.outcome.value] += 1
            if episode.outcome is Outcome.SUCCESS:
                plan_lengths[t].append(len(episode.actions))
    all_words = [w for v in words.values() for w in v]
    all_plans = [n for v in plan_lengths.values() for n in v]
    success = {t: oracle[t]["success"] / max(1, oracle[t].total()) for t in TEMPLATES}
    for t in TEMPLATES:
        print(f"{t:24s} scenes {scenes_with[t]:5d}  words {summary(words[t]).get('min')}-"
              f"{summary(words[t]).get('max')}  plan {summary(plan_lengths[t]).get('min')}-"
              f"{summary(plan_lengths[t]).get('max')}  oracle {success[t]:.3f} of {oracle[t].total()}")
    print(json.dumps({
        "benchmark": "instructions", "metric": "instructions per second (one core, ambiguity checks on)",
        "value": round(made / seconds, 1), "unit": "instructions/s", "goal": GOAL_PER_S,
        "scenes": len(scenes), "instructions": made, "seconds": round(seconds, 3),
        "reference_scenes_x50_per_s": round(reference_rate, 1) if reference_rate else None,
        "anchor_original_per_s": round(ANCHOR_PER_S, 1),
        "reference_scenes_x50_per_cpu_s": round(reference_cpu_rate, 1) if reference_cpu_rate else None,
        "original_scenes_x50_per_cpu_s": round(original_cpu_rate, 1) if original_cpu_rate else None,
        "speed_vs_original": round(reference_cpu_rate / original_cpu_rate, 3) if original_cpu_rate else None,
        "scenes_with_template": dict(scenes_with),
        "words": summary(all_words), "plan_primitives": summary(all_plans),
        "plan_primitives_by_template": {t: {k: v for k, v in summary(plan_lengths[t]).items() if k != "histogram"}
                                        for t in TEMPLATES},
        "oracle_symbolic_success": success,
    }))


if __name__ == "__main__":
    main()
