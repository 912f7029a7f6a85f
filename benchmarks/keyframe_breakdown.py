"""Where a MuJoCo keyframe's render time goes: the RGB pass's shadows, floor reflection and multisampling.

One generated scene, the ``front`` camera at 848x480, the MuJoCo renderer with its defaults (without the mesh
atlas, so that the quality settings reach the model it draws). Each
variant turns one feature of robosuite's world off (or makes the shadow maps smaller), through the renderer's
options where it has them (``shadows``, ``shadow_size``), and is timed over the same frames in the same run; it prints seconds per frame, the ratio to the frame as written, and how many pixels of
the RGB image change (a variant that changes pixels changes what ``muble generate`` writes). The renderer draws
the RGB pass without the floor's reflection where its segmentation pass shows no floor; "reflection drawn unseen"
times it as it was drawn before (``reflection_when_hidden``), and "RGB, no floor reflection" without it always.

    python benchmarks/keyframe_breakdown.py [FRAMES]
"""
from __future__ import annotations

import json
import os
import sys
import time
from contextlib import contextmanager

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")


def scene_env():
    from muble.app.config import compose
    from muble.episode.components import build_components, generated_env

    cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp"])
    return generated_env(cfg, build_components(cfg, renderer=False, task=False), 0)


@contextmanager
def quality(model, **values):
    """Temporarily set ``model.vis.quality`` fields (offsamples)."""
    old = {k: int(getattr(model.vis.quality, k)) for k in values}
    for k, v in values.items():
        setattr(model.vis.quality, k, v)
    try:
        yield
    finally:
        for k, v in old.items():
            setattr(model.vis.quality, k, v)


def timed(env, frames: int, passes: str = "rgb", options: dict | None = None, flags_off: tuple = (),
          **vis) -> tuple[float, np.ndarray]:
    """Seconds per frame of the MuJoCo renderer built with ``options`` (its own: ``shadows``, ``shadow_size``),
    with ``flags_off`` render flags cleared and ``vis`` quality (what it has no option for)."""
    import mujoco

    from muble import get_registry

    rgb = passes in ("rgb", "all")
    seg = passes in ("seg", "all")
    with quality(env.model, **vis):
        renderer = get_registry().create("renderer", "mujoco", {"rgb": rgb, "segmentation": seg, "depth": seg,
                                                                 "reuse_meshes": False, **(options or {})})
        try:
            renderer.setup(env.sync_scene_graph(), env.model)
            update = renderer._update_scene

            def update_without(data, cam):
                update(data, cam)
                for flag in flags_off:
                    renderer._scene.flags[getattr(mujoco.mjtRndFlag, flag)] = 0

            renderer._update_scene = update_without
            frame = renderer.render(env.data, "front")  # warm-up: shaders, textures, buffers
            start = time.perf_counter()
            for _ in range(frames):
                frame = renderer.render(env.data, "front")
            return (time.perf_counter() - start) / frames, frame.rgb
        finally:
            renderer.close()


def main() -> int:
    frames = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    env = scene_env()
    variants = {
        "as written (RGB + segmentation/depth)": dict(passes="all"),
        "segmentation/depth pass only": dict(passes="seg"),
        "RGB pass": dict(),
        "RGB + segmentation/depth, reflection drawn unseen": dict(passes="all", options={"reflection_when_hidden": True}),
        "RGB, no shadows": dict(options={"shadows": False}),
        "RGB, no floor reflection": dict(flags_off=("mjRND_REFLECTION",)),
        "RGB, no multisampling": dict(offsamples=0),
        "RGB, shadow maps 2048": dict(options={"shadow_size": 2048}),
        "RGB, shadow maps 1024": dict(options={"shadow_size": 1024}),
        "RGB, none of shadows, reflection, multisampling": dict(options={"shadows": False},
                                                                 flags_off=("mjRND_REFLECTION",), offsamples=0),
    }
    results, reference, written_rgb = {}, None, None
    try:
        for name, kwargs in variants.items():
            seconds, rgb = timed(env, frames, **kwargs)
            if name == "RGB pass":
                reference = rgb.astype(np.int16)
            if name.startswith("as written"):
                written_rgb = rgb.astype(np.int16)
            changed = None
            if reference is not None and kwargs.get("passes", "rgb") == "rgb":
                changed = float((np.abs(rgb.astype(np.int16) - reference).max(axis=2) > 0).mean())
            elif "unseen" in name:  # against the frame as written
                changed = float((np.abs(rgb.astype(np.int16) - written_rgb).max(axis=2) > 0).mean())
            results[name] = {"seconds": round(seconds, 3), "changed_pixels": changed}
    finally:
        env.close()
    written = results["as written (RGB + segmentation/depth)"]["seconds"]
    print(f"{'variant':50s} {'s/frame':>8s} {'ratio':>6s} {'RGB pixels changed':>19s}")
    for name, row in results.items():
        changed = "" if row["changed_pixels"] is None else f"{row['changed_pixels']:.2%}"
        print(f"{name:50s} {row['seconds']:8.3f} {row['seconds'] / written:6.2f} {changed:>19s}")
    print(json.dumps({"benchmark": "keyframe_breakdown", "metric": "seconds per MuJoCo render, by variant",
                      "unit": "s", "frames": frames, "resolution": [848, 480], "variants": results,
                      "cores": os.cpu_count(), "load_average_1min": round(os.getloadavg()[0], 2)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
