"""``muble verify RUN``: replay an evaluation run's recorded decisions (no agent, no endpoint) and report, per
episode, the first primitive after which the world's fingerprint differs from the recorded one beyond the
tolerance, and whether the outcome changed (docs/evaluation.md, "Verifying a run")."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from muble.episode.fingerprint import ANGLE_UNIT, POSITION_UNIT, TOLERANCE


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="muble verify", description=__doc__)
    p.add_argument("run", help="the folder of a `muble eval` run (it holds eval_run.json and episodes_<split>.jsonl)")
    p.add_argument("--split", help="only this split (default: every split the run evaluated)")
    p.add_argument("--limit", type=int, default=0, help="only the first N episodes of each split (0: all)")
    p.add_argument("--workers", type=int, default=2, help="processes replaying episodes (default 2)")
    p.add_argument("--tolerance", type=int, default=TOLERANCE,
                   help=f"units a fingerprint value may differ by ({POSITION_UNIT * 1000:g} mm, {ANGLE_UNIT:g} "
                        f"degree each; default {TOLERANCE})")
    p.add_argument("--out", help="write the full report (every episode) as JSON here")
    return p


def main(argv: list[str]) -> int:
    from muble.core.errors import ConfigError
    from muble.evaluation.verify import verify_run

    args = parser().parse_args(argv)
    if args.limit < 0 or args.workers < 1 or args.tolerance < 0:
        raise ConfigError("--limit and --tolerance must be >= 0 and --workers >= 1")
    run = Path(args.run)
    if not run.is_dir():
        raise ConfigError(f"{run} is not a folder: give the folder of a `muble eval` run")
    report = verify_run(run, args.split, args.limit, args.workers, args.tolerance)
    differ = 0
    for split, s in report["splits"].items():
        print(f"{split}: {s['episodes']} episodes replayed; fingerprints agree in {s['agree']} "
              f"({s['identical']} identical), differ in {s['differ']}; outcomes changed in {s['outcomes_changed']}; "
              f"largest difference {s['largest_difference']} units")
        for e in s["episodes_detail"]:
            if e["first_difference"] is not None or e["outcome_changed"]:
                where = e["first_difference"] or {}
                print(f"  {split} {e['index']} ({e['template']}): first differs after primitive "
                      f"{where.get('fingerprint')} ({where.get('after')}), largest {e['largest_difference']} units; "
                      f"outcome {e['outcome']} -> {e['replayed_outcome']}")
        differ += s["differ"] + s["outcomes_changed"]
    if args.out:
        from muble.io.atomic import write_bytes_atomic

        write_bytes_atomic(Path(args.out), json.dumps(report, indent=1).encode())
    return 1 if differ else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main(sys.argv[1:]))
