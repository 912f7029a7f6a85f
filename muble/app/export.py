"""``muble export``: a generated split's sequences as a LeRobot dataset, written by the LeRobot library.

Every sequence file is read and checked before anything is written, and the dataset reaches ``--out`` only when
complete: a failed export leaves ``--out`` as it was. An existing export in ``--out`` is replaced. The LeRobot
library is the extra ``muble[lerobot]``; ``LeRobotDataset(REPO_ID, root=OUT)`` loads the result.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from muble.core.errors import ConfigError


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="muble export", description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", help="the dataset root written by `muble generate` (with dataset.sequences=true)")
    parser.add_argument("--split", default="val", help="which split (default: val)")
    parser.add_argument("--out", required=True, help="folder for the LeRobot dataset")
    parser.add_argument("--robot-type", default=None,
                        help="recorded as robot_type in meta/info.json (default: the dataset's robot)")
    parser.add_argument("--repo-id", default="muble/shopvrb2", help="the dataset's LeRobot repo id")
    args = parser.parse_args(argv)
    from muble.dataset.lerobot import check_split, require_lerobot, write_lerobot
    from muble.io.atomic import check_output_folder, staged_folder
    from muble.io.layout import check_split_name

    check_split_name(args.split, "--split")
    dataset, out = Path(args.dataset), Path(args.out)
    if not dataset.is_dir():
        raise ConfigError(f"dataset {dataset} " + ("is a file" if dataset.exists() else "does not exist")
                          + "; pass the dataset.root folder of `muble generate`")
    if out.is_dir() and any(out.iterdir()) and not (out / "meta" / "info.json").is_file():
        raise ConfigError(f"--out {out} holds files that are not a LeRobot export; pass a new or empty folder")
    check_output_folder(out, "--out")
    checked = check_split(dataset, args.split)  # every input, before LeRobot is needed
    require_lerobot()
    with staged_folder(out, "--out", replace=True) as stage:
        written = stage / "lerobot"  # LeRobot creates its root folder itself
        counts = write_lerobot(checked, written, args.robot_type, args.repo_id)
        for entry in written.iterdir():
            os.replace(entry, stage / entry.name)
        written.rmdir()
    print(f"muble export: {counts['episodes']} episodes, {counts['frames']} frames, robot_type "
          f"{counts['robot_type']} in {args.out} (lerobot {counts['lerobot']})")
    return 0
