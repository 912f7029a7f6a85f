"""How much the original MuBlE demo scenes rendered here look like the original's own frames.

Each reference scene (``NS_AP_demo_scenes.json`` of the original release, with its frame in ``images/``) is
built with the environment as ``muble render --passes`` builds a scene file and rendered once by the Blender
renderer at its defaults (or the overrides given). Against the file and its frame it scores:

- per-object mask IoU: our segmentation of each object against the file's COCO mask of it; the table's and the
  robot's the same way;
- whole-frame SSIM of our RGB against the original frame;
- per-object CIEDE2000 between the mean L*a*b* colour of the original frame and of ours inside the file's mask.

It prints one line per scene, a summary, and a JSON last line with the figures beside the goals of issue 35
(object IoU >= 0.85 each and median >= 0.9; table >= 0.9; robot >= 0.8; mean SSIM >= 0.85; median CIEDE2000
<= 6). ``--sheet`` writes a contact sheet, the original frame beside ours, one scene a row; ``--save`` keeps
our frames and segmentations for a closer look.

    python benchmarks/original_look.py [--reference DIR] [--scenes 0,1,2] [--scale S] [--samples N]
                                       [--set KEY=VALUE ...] [--sheet PATH] [--save DIR]
                                       [--object-set NAME]

``--scale`` renders a fraction of the 848x480 frame (the file's masks and the original frame are resized to
match) and ``--samples`` overrides the renderer's samples, for a quick run; the JSON says what was run.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.support: helpers shared with the tests

DEFAULT_REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "muble-demo"
SCENES_FILE = "NS_AP_demo_scenes.json"
GOALS = {"object_iou_min": 0.85, "object_iou_median": 0.9, "table_iou": 0.9, "robot_iou": 0.8,
         "mean_ssim": 0.85, "ciede2000_median": 6.0}


class MissingReference(Exception):
    """The reference folder or a scene asked for is not there."""


def reference_scenes(folder: Path, wanted: list[int] | None) -> list[tuple[object, Path]]:
    """(scene, original frame) of each wanted scene index (default: every scene whose frame is in ``images/``)."""
    from muble.io.scene_io import load_scenes

    if not folder.is_dir():
        raise MissingReference(f"--reference {folder}: no such folder; it should hold {SCENES_FILE} and images/ "
                              "(the original release's demo input)")
    path = folder / SCENES_FILE
    if not path.is_file():
        raise MissingReference(f"--reference {folder}: {SCENES_FILE} missing")
    _, scenes = load_scenes(path)
    by_index = {s.image_index: s for s in scenes}
    framed = {i: folder / "images" / s.image_filename for i, s in by_index.items()
              if s.image_filename and (folder / "images" / s.image_filename).is_file()}
    if not framed:
        raise MissingReference(f"--reference {folder}: no scene of {SCENES_FILE} has its frame in images/")
    if wanted is None:
        wanted = sorted(framed)
    unknown = [i for i in wanted if i not in framed]
    if unknown:
        raise MissingReference(f"--scenes: no reference frame for scene index {unknown}; scenes with a frame: "
                              f"{sorted(framed)}")
    return [(by_index[i], framed[i]) for i in wanted]


def _resized_mask(mask: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    from PIL import Image

    if mask.shape[::-1] == size:
        return mask
    return np.asarray(Image.fromarray(mask.astype(np.uint8) * 255).resize(size, Image.NEAREST)) > 127


def _original_frame(path: Path, size: tuple[int, int]) -> np.ndarray:
    from PIL import Image

    image = Image.open(path).convert("RGB")
    return np.asarray(image if image.size == size else image.resize(size, Image.LANCZOS))


def compare(scene, original: np.ndarray, rgb: np.ndarray, segmentation: np.ndarray) -> dict:
    """Scores of one rendered frame against the scene file's masks and the original frame (same size)."""
    from muble.core.types import SEG_ROBOT, SEG_TABLE
    from muble.generation.ground_truth import decode_mask
    from tests.support.image_likeness import ciede2000, mask_iou, mean_lab, ssim

    size = (rgb.shape[1], rgb.shape[0])
    objects = []
    for obj in scene.objects:
        if obj.mask is None:
            continue
        mask = _resized_mask(decode_mask(obj.mask), size)
        theirs, ours = mean_lab(original, mask), mean_lab(rgb, mask)
        delta = ciede2000(theirs, ours)
        objects.append({"id": obj.id, "name": obj.name, "material": obj.material, "colour": obj.colour,
                        "iou": round(mask_iou(segmentation == obj.id, mask), 4),
                        "ciede2000": None if np.isnan(delta) else round(float(delta), 2),
                        "lab_original": np.round(theirs, 1).tolist(), "lab_here": np.round(ours, 1).tolist()})
    parts = {}
    for part, label in (("table", SEG_TABLE), ("robot", SEG_ROBOT)):
        record = getattr(scene, part, None) or {}
        if record.get("mask") is not None:
            parts[part] = round(mask_iou(segmentation == label, _resized_mask(decode_mask(record["mask"]), size)), 4)
    return {"objects": objects, "table_iou": parts.get("table"), "robot_iou": parts.get("robot"),
            "ssim": round(ssim(original, rgb), 4)}


def render_scene(scene, object_set: str, options: dict) -> tuple[np.ndarray, np.ndarray, float]:
    """RGB and segmentation of the scene's initial state, built as ``muble render`` builds it; render seconds."""
    from muble.plugins.registry import get_registry
    from muble.sim.build import env_from_object_set

    env = env_from_object_set(scene, object_set)
    try:
        env.reset()
        renderer = get_registry().create("renderer", "blender", options)
        try:
            renderer.setup(scene, env.model)
            start = time.perf_counter()
            frame = renderer.render(env.data, env.names.cameras.get("front", "front"))
            return frame.rgb, frame.segmentation, time.perf_counter() - start
        finally:
            renderer.close()
    finally:
        env.close()


def summary(results: list[dict]) -> dict:
    ious = [o["iou"] for r in results for o in r["objects"]]
    deltas = [o["ciede2000"] for r in results for o in r["objects"] if o["ciede2000"] is not None]
    tables = [r["table_iou"] for r in results if r["table_iou"] is not None]
    robots = [r["robot_iou"] for r in results if r["robot_iou"] is not None]

    def stat(values, fn):
        return round(float(fn(values)), 4) if values else None

    return {"object_iou_min": stat(ious, np.min), "object_iou_median": stat(ious, np.median),
            "table_iou": stat(tables, np.mean), "robot_iou": stat(robots, np.mean),
            "mean_ssim": stat([r["ssim"] for r in results], np.mean),
            "ciede2000_median": stat(deltas, np.median), "ciede2000_max": stat(deltas, np.max)}


def _met(figures: dict) -> dict:
    met = {}
    for key, goal in GOALS.items():
        value = figures.get(key)
        met[key] = None if value is None else (value <= goal if key.startswith("ciede") else value >= goal)
    return met


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference", type=Path, default=DEFAULT_REFERENCE,
                        help=f"folder with {SCENES_FILE} and images/ (default: {DEFAULT_REFERENCE})")
    parser.add_argument("--scenes", default="", help="comma-separated scene indices (default: every framed one)")
    parser.add_argument("--scale", type=float, default=1.0, help="fraction of the 848x480 frame to render")
    parser.add_argument("--samples", type=int, default=None, help="Cycles samples (default: the renderer's)")
    parser.add_argument("--set", dest="options", action="append", default=[], metavar="KEY=VALUE",
                        help="renderer option, repeatable (as muble render --set)")
    parser.add_argument("--object-set", default="shopvrb2")
    parser.add_argument("--sheet", default="", help="write a contact sheet (original | ours) PNG or JPEG here")
    parser.add_argument("--save", type=Path, default=None,
                        help="write each scene's frame here as rendered (ours_N.png, segmentation ours_N_seg.npy)")
    return parser


def main(argv: list[str] | None = None) -> int:
    from muble.app.render import renderer_options
    from muble.core.errors import ConfigError
    from muble.stage.camera import DEFAULT_HEIGHT, DEFAULT_WIDTH

    args = _parser().parse_args(argv)
    try:
        wanted = [int(i) for i in args.scenes.split(",") if i.strip()] or None
    except ValueError:
        print(f"--scenes {args.scenes!r}: expected comma-separated integers, e.g. --scenes 0,2", file=sys.stderr)
        return 2
    if not 0 < args.scale <= 4:
        print(f"--scale {args.scale}: expected a fraction in (0, 4]", file=sys.stderr)
        return 2
    try:
        scenes = reference_scenes(args.reference, wanted)
        options = renderer_options(args.options)
    except (MissingReference, ConfigError) as e:
        print(f"original_look: {e}", file=sys.stderr)
        return 2
    width, height = round(DEFAULT_WIDTH * args.scale), round(DEFAULT_HEIGHT * args.scale)
    options.update(width=width, height=height, segmentation=True)
    if args.samples is not None:
        options["samples"] = args.samples
    start = time.perf_counter()
    results, sheet, labels = [], [], []
    for scene, frame_path in scenes:
        rgb, segmentation, seconds = render_scene(scene, args.object_set, options)
        original = _original_frame(frame_path, (width, height))
        result = {"scene": scene.image_index, **compare(scene, original, rgb, segmentation),
                  "render_seconds": round(seconds, 1)}
        results.append(result)
        if args.save is not None:
            from PIL import Image

            args.save.mkdir(parents=True, exist_ok=True)
            Image.fromarray(rgb).save(args.save / f"ours_{scene.image_index}.png")
            np.save(args.save / f"ours_{scene.image_index}_seg.npy", segmentation)
        ious = [o["iou"] for o in result["objects"]]
        deltas = [o["ciede2000"] for o in result["objects"] if o["ciede2000"] is not None]
        print(f"scene {scene.image_index}: objects IoU {' '.join(f'{v:.2f}' for v in ious)}  "
              f"table {result['table_iou']}  robot {result['robot_iou']}  SSIM {result['ssim']:.3f}  "
              f"CIEDE2000 {' '.join(f'{d:.1f}' for d in deltas)}  ({seconds:.1f} s)", flush=True)
        for o in result["objects"]:
            print(f"    {o['id']} {o['name']:14s} {o['material'] or '':8s} {o['colour'] or '':11s} IoU {o['iou']:.3f}  "
                  f"CIEDE2000 {o['ciede2000']}  L*a*b* {o['lab_original']} -> {o['lab_here']}")
        sheet += [original, rgb]
        labels += [f"original {scene.image_index}", f"here {scene.image_index}"]
    figures = summary(results)
    met = _met(figures)
    print("\n" + "  ".join(f"{k} {v}" for k, v in figures.items()))
    if args.sheet:
        from PIL import Image

        from muble.io.image_grid import contact_sheet

        Image.fromarray(contact_sheet(sheet, columns=2, width=min(424, width), labels=labels)).save(args.sheet)
    print(json.dumps({
        "benchmark": "original_look", "metric": "mean whole-frame SSIM against the original's frames",
        "value": figures["mean_ssim"], "unit": "SSIM", "goal": GOALS["mean_ssim"], **figures, "goals": GOALS,
        "met": met, "scenes": results, "resolution": [width, height], "renderer_options": options,
        "object_set": args.object_set, "cores": os.cpu_count(), "load_average_1min": round(os.getloadavg()[0], 2),
        "seconds": round(time.perf_counter() - start, 1),
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
