"""``muble export``: a generated split's sequences as a LeRobot-style dataset (parquet + images)."""
from __future__ import annotations

import argparse


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="muble export", description=__doc__)
    parser.add_argument("dataset", help="the dataset root written by `muble generate` (with dataset.sequences=true)")
    parser.add_argument("--split", default="val", help="which split (default: val)")
    parser.add_argument("--out", required=True, help="folder for the LeRobot-style dataset")
    parser.add_argument("--robot-type", default="", help="recorded in meta/info.json")
    args = parser.parse_args(argv)
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        parser.error("the LeRobot export needs pyarrow: pip install 'muble[export]'")
    from muble.dataset.lerobot import export_lerobot

    counts = export_lerobot(args.dataset, args.split, args.out, args.robot_type)
    print(f"muble export: {counts['episodes']} episodes, {counts['frames']} frames in {args.out}")
    return 0
