"""``muble site``: a static website of ``muble eval`` runs, to look at what each agent did.

    muble site runs/oracle runs/random runs/llm --out site     # then open site/index.html, or:
    python -m http.server -d site 8000                          # and browse http://127.0.0.1:8000

Each RUN is the output folder of a ``muble eval`` run. The site has a leaderboard (one row per run and split), a
page per run and split (success per task type with intervals, the failure taxonomy, the episodes, filterable) and
a page per episode (instruction, program, every decision with its result and measurement, measurements against
true values, keyframes and their GIF, an LLM's dialogue, the same episode under the other runs). Keyframes are in
the site when the runs wrote them (``evaluation.render=true evaluation.keyframes=true``). Every run is read before
anything is written, and ``--out`` gets the whole site or, on any error, is left as it was.
"""
from __future__ import annotations

import argparse
import time


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="muble site", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n\n".join(__doc__.split("\n\n")[1:]))
    parser.add_argument("runs", nargs="+", metavar="RUN", help="output folder of a `muble eval` run")
    parser.add_argument("--out", default="site", help="folder for the site (default: ./site; its old contents are "
                                                      "replaced)")
    args = parser.parse_args(argv)
    from muble.evaluation.site import build_site

    began = time.perf_counter()
    counts = build_site(args.runs, args.out)
    print(f"muble site: {counts['runs']} run(s), {counts['episodes']} episode pages in {args.out} "
          f"({time.perf_counter() - began:.1f} s); open {args.out}/index.html")
    return 0
