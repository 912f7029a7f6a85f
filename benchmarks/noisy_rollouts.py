"""The oracle and its open-loop control on a split's episodes in a noisy symbolic world: what measuring again buys,
what it costs, before an hour of physics.

Each episode of the split runs ``--trials`` times in the symbolic world (``muble_plugins.common.symbolic``) whose
``weigh`` and ``reweigh`` read the true weight plus a Gaussian error of ``--sigma`` grams (the spread one weighing has
with ``noise=wrist_ft``, docs/physical_properties.md), drawn from the stream ``bench.noisy_rollouts`` of (``--seed``,
episode index, trial): the open-loop control (one reading of each object) and the closed-loop oracle (``agent.reading_noise_g``,
``decide_sigmas``, ``max_readings`` and the step budget's bound) get the same draws in the same order as far as their readings go. Printed per
agent: the share of runs solved, and for the oracle the readings and primitives per episode (mean and largest) and
the outcomes other than success; the last line is a JSON object. Physics adds what this leaves out (grasps that
slip, put-downs that fail, the sensor's drift): ``muble eval ... noise=wrist_ft`` measures that.

    python benchmarks/noisy_rollouts.py --split noisy_sensing --trials 5
"""
from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--protocol", default="shopvrb2_v2")
    parser.add_argument("--split", default="noisy_sensing")
    parser.add_argument("--root", default=None, help="a dataset root holding the split (default: the shipped files)")
    parser.add_argument("--trials", type=int, default=5, help="runs of each episode, each with its own draws")
    parser.add_argument("--sigma", type=float, default=9.6, help="sd (g) of one weighing")
    parser.add_argument("--decide-sigmas", type=float, default=None, help="default: the oracle's")
    parser.add_argument("--max-readings", type=int, default=None, help="default: the oracle's")
    parser.add_argument("--max-readings-total", type=int, default=None, help="default: the oracle's (0: no bound)")
    parser.add_argument("--step-reserve", type=int, default=None, help="default: the oracle's")
    parser.add_argument("--step-budget", type=int, default=None,
                        help="the oracle's reading bound by the step budget (default: the episode's); the episode "
                             "still ends at its own")
    parser.add_argument("--limit", type=int, default=0, help="the first N episodes only (0: all)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from muble import ActionResult, Outcome
    from muble.core import streams
    from muble.core.symbolic import ArmState
    from muble.dataset.protocol import load_protocol, shipped_root
    from muble.episode import run_episode
    from muble.io.instructions_io import load_instruction
    from muble.io.scene_io import load_scene
    from muble_plugins.agents.oracle import OracleAgent, OracleConfig
    from muble_plugins.common.success import check
    from muble_plugins.common.symbolic import SymbolicWorld

    class NoisyWorld(SymbolicWorld):
        """The symbolic world whose weighings err by a Gaussian of ``sigma`` grams."""

        def __init__(self, scene, rng: np.random.Generator):
            super().__init__(scene)
            self.rng = rng

        def apply(self, call) -> ActionResult:
            result = super().apply(call)
            if call.name in ("weigh", "reweigh") and result.success:
                held = ArmState.of(self.scene).held_object(self.scene)
                held.weight = float(held.weight_gt + self.rng.normal(0.0, args.sigma))
                result.measurement = held.weight
            return result

    draws = streams.declare("bench.noisy_rollouts", "the errors of one run's weighings (seed, episode index, run)")
    defaults = OracleConfig()
    oracle = OracleConfig(reading_noise_g=args.sigma,
                          decide_sigmas=args.decide_sigmas or defaults.decide_sigmas,
                          max_readings=args.max_readings or defaults.max_readings,
                          max_readings_total=(defaults.max_readings_total if args.max_readings_total is None
                                              else args.max_readings_total),
                          step_reserve=defaults.step_reserve if args.step_reserve is None else args.step_reserve,
                          step_budget=args.step_budget or defaults.step_budget)
    control = OracleConfig(closed_loop=False, reading_noise_g=args.sigma)
    root = Path(args.root) if args.root else shipped_root(load_protocol(args.protocol), args.split)
    files = sorted((root / args.split / "instructions").glob("*.json"))
    if args.limit:
        files = files[:args.limit]
    solved: dict[str, list[bool]] = {"control": [], "oracle": []}
    readings, steps, other = [], [], Counter()
    by_template: dict[str, dict[str, list[bool]]] = {}
    for index, path in enumerate(files):
        scene = load_scene(root / args.split / "scenes" / path.name)
        instruction = load_instruction(path)[1]
        for trial in range(args.trials):
            for name, config in (("control", control), ("oracle", oracle)):
                agent = OracleAgent(config)
                world = NoisyWorld(scene, streams.stream(draws, args.seed, index, trial))
                result = run_episode(instruction, world, agent, check)
                solved[name].append(result.outcome is Outcome.SUCCESS)
                by_template.setdefault(instruction.template_id, {"control": [], "oracle": []})[name].append(
                    result.outcome is Outcome.SUCCESS)
                if name == "oracle":
                    readings.append(agent.stats()["readings"])
                    steps.append(len(result.actions))
                    if result.outcome is not Outcome.SUCCESS:
                        other[result.outcome.value] += 1
    row = {"benchmark": "noisy_rollouts", "protocol": args.protocol, "split": args.split, "episodes": len(files),
           "trials": args.trials, "sigma_g": args.sigma, "decide_sigmas": oracle.decide_sigmas,
           "max_readings": oracle.max_readings, "max_readings_total": oracle.max_readings_total,
           "step_reserve": oracle.step_reserve, "step_budget": oracle.step_budget, "control_success": round(float(np.mean(solved["control"])), 4),
           "oracle_success": round(float(np.mean(solved["oracle"])), 4),
           "oracle_readings_mean": round(float(np.mean(readings)), 2), "oracle_readings_max": int(max(readings)),
           "oracle_primitives_mean": round(float(np.mean(steps)), 2), "oracle_primitives_max": int(max(steps)),
           "oracle_failures": dict(other),
           "by_template": {t: {k: round(float(np.mean(v)), 4) for k, v in runs.items()}
                           for t, runs in sorted(by_template.items())}}
    print(f"{args.protocol} {args.split}: {len(files)} episodes x {args.trials} runs, one weighing errs by "
          f"{args.sigma} g")
    print(f"  open-loop control (one reading each): {row['control_success']:.1%} solved")
    print(f"  oracle ({oracle.decide_sigmas} standard errors, at most {oracle.max_readings} readings each, "
          f"{oracle.max_readings_total or 'no bound'} in all, {oracle.step_reserve} primitives kept back of "
          f"{oracle.step_budget}): "
          f"{row['oracle_success']:.1%} solved, {row['oracle_readings_mean']} readings per episode (at most "
          f"{row['oracle_readings_max']}), {row['oracle_primitives_mean']} primitives (at most "
          f"{row['oracle_primitives_max']}); not solved: {dict(other) or 'none'}")
    for template, rates in row["by_template"].items():
        print(f"  {template}: control {rates['control']:.1%}, oracle {rates['oracle']:.1%}")
    print(json.dumps(row))


if __name__ == "__main__":
    main()
