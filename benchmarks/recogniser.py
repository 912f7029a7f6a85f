"""Per-attribute accuracy of trained attribute recognisers on the object crops of test datasets: the
renderer-to-renderer transfer table (each model on each test set).

    python benchmarks/recogniser.py --model mujoco=runs/rec_mujoco/recogniser.pt \\
        --model blender=runs/rec_blender/recogniser.pt --model both=runs/rec_both/recogniser.pt \\
        --test mujoco=data/v1 --test blender=data/v1_blender [--scenes 300]

A test set is a dataset root written by `muble generate` (e.g. the protocol's test split; with
`renderer=blender` for Blender crops), read with the recogniser's own crop code. ``--scenes`` takes the first N
scenes of each. Prints a table (accuracy per attribute, and ``all``: every attribute of a crop right) and, last,
one JSON object.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def _pairs(items: list[str], flag: str) -> dict[str, str]:
    out = {}
    for item in items:
        label, sep, path = item.partition("=")
        if not sep:
            raise SystemExit(f"{flag} takes LABEL=PATH, got {item!r}")
        out[label] = path
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", action="append", required=True, help="LABEL=recogniser.pt")
    parser.add_argument("--test", action="append", required=True, help="LABEL=dataset root")
    parser.add_argument("--scenes", type=int, default=None, help="first N scenes of each test set")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(argv)

    import torch

    torch.set_num_threads(args.threads)
    from muble_plugins.learned.recogniser import ATTRIBUTES, AttributeRecogniser, accuracy, load_dataset_crops

    models = {label: AttributeRecogniser.load(path) for label, path in _pairs(args.model, "--model").items()}
    tests = _pairs(args.test, "--test")
    crops: dict[tuple[str, int], object] = {}
    results: dict[str, dict[str, dict[str, float]]] = {}
    info: dict[str, dict[str, float]] = {}
    for test_label, root in tests.items():
        for model_label, model in models.items():
            key = (test_label, model.crop_size)
            if key not in crops:
                began = time.perf_counter()
                crops[key] = load_dataset_crops(root, model.crop_size, scenes=args.scenes)
                info[test_label] = {"scenes": crops[key].scenes_read, "crops": len(crops[key]),
                                    "read_seconds": round(time.perf_counter() - began, 1)}
            began = time.perf_counter()
            found = accuracy(model.predict(crops[key]), crops[key])
            found["seconds"] = round(time.perf_counter() - began, 1)
            results.setdefault(model_label, {})[test_label] = found

    columns = ATTRIBUTES + ("all",)
    print(f"{'trained on':<12}{'tested on':<12}" + "".join(f"{c:>10}" for c in columns))
    for model_label, row in results.items():
        for test_label, found in row.items():
            print(f"{model_label:<12}{test_label:<12}" + "".join(f"{100 * found[c]:>9.1f}%" for c in columns))
    for test_label, figures in info.items():
        print(f"test {test_label}: {figures['scenes']} scenes, {figures['crops']} crops ({tests[test_label]})")
    print(json.dumps({"accuracy": results, "tests": info,
                      "models": {k: {"path": p, **models[k].extra.get("data", {})}
                                 for k, p in _pairs(args.model, "--model").items()}}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
