"""``muble export``: a generated split's sequences as a LeRobot-style dataset (parquet + images).

Every sequence file is read and checked before anything is written, and the dataset reaches ``--out`` only when
complete: a failed export leaves ``--out`` as it was. An existing export in ``--out`` is replaced.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from muble.core.errors import ConfigError


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="muble export", description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", help="the dataset root written by `muble generate` (with dataset.sequences=true)")
    parser.add_argument("--split", default="val", help="which split (default: val)")
    parser.add_argument("--out", required=True, help="folder for the LeRobot-style dataset")
    parser.add_argument("--robot-type", default="", help="recorded in meta/info.json")
    args = parser.parse_args(argv)
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        parser.error("the LeRobot export needs pyarrow: pip install 'muble[export]'")
    from muble.core.atomic import staged_folder
    from muble.core.layout import check_split_name
    from muble.dataset.lerobot import export_lerobot

    check_split_name(args.split, "--split")
    dataset, out = Path(args.dataset), Path(args.out)
    if not dataset.is_dir():
        raise ConfigError(f"dataset {dataset} " + ("is a file" if dataset.exists() else "does not exist")
                          + "; pass the dataset.root folder of `muble generate`")
    if out.is_dir() and any(out.iterdir()) and not (out / "meta" / "info.json").is_file():
        raise ConfigError(f"--out {out} holds files that are not a LeRobot export; pass a new or empty folder")
    with staged_folder(out, "--out", replace=True) as stage:
        counts = export_lerobot(dataset, args.split, stage, args.robot_type)
    print(f"muble export: {counts['episodes']} episodes, {counts['frames']} frames in {args.out}")
    return 0
