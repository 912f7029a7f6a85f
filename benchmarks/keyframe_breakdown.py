"""Where a MuJoCo keyframe's render time goes: the RGB pass's shadows, floor reflection and multisampling.

One generated scene, the ``front`` camera at 848x480, the MuJoCo renderer with its defaults (without the mesh
atlas, so that the quality settings reach the model it draws). Each
variant turns one feature of robosuite's world off (or makes the shadow maps smaller), through the renderer's
options where it has them (``shadows``, ``shadow_size``), and is timed over the same frames in the same run; it prints seconds per frame, the ratio to the frame as written, and how many pixels of
the RGB image change (a variant that changes pixels changes what ``muble generate`` writes). The renderer draws
the RGB pass without the floor's reflection where its segmentation pass shows no floor; "reflection drawn unseen"
times it as it was drawn before (``reflection_when_hidden``), and "RGB, no floor reflection" without it always.

Before the variants, each GL step of a keyframe is timed on its own, ended by ``glFinish`` (``passes``): the
segmentation/depth pass, the RGB pass, its resolve and read-back, and the RGB pass on an 8x8 viewport (its
per-vertex work, triangle set-up and shadow maps without the lit pixels), with and without shadows.

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


def passes(env, frames: int) -> dict[str, float]:
    """Seconds of each GL step of a keyframe, each ended by ``glFinish`` (llvmpipe rasterises in its own threads;
    without it a step's time shows up in the next): the segmentation/depth pass with its read-back, the RGB pass,
    its resolve and read-back, the RGB pass on an 8x8 viewport (what is left: per-vertex work, triangle set-up
    and the shadow maps, which keep their size), and the RGB pass with shadows, on both viewports."""
    import mujoco
    from OpenGL import GL

    from muble import get_registry

    renderer = get_registry().create("renderer", "mujoco", {"reuse_meshes": False})
    try:
        renderer.setup(env.sync_scene_graph(), env.model)
        renderer.render(env.data, "front")
        w, h = renderer.config.width, renderer.config.height
        rect, tiny = mujoco.MjrRect(0, 0, w, h), mujoco.MjrRect(0, 0, 8, 8)
        scene, context = renderer._scene, renderer._context
        renderer._update_scene(env.data, renderer._camera("front"))
        scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0  # as drawn: robosuite's floor is hidden
        rgb = np.empty((h, w, 3), dtype=np.uint8)
        shadow = mujoco.mjtRndFlag.mjRND_SHADOW

        def no_shadows(draw):
            def step():
                scene.flags[shadow] = 0
                try:
                    draw()
                finally:
                    scene.flags[shadow] = 1
            return step

        steps = {
            "segmentation/depth pass and read-back": lambda: renderer._id_pass(rect),
            "RGB pass (shadow maps, lit passes, 4x MSAA)": lambda: mujoco.mjr_render(rect, scene, context),
            "RGB resolve and read-back": lambda: mujoco.mjr_readPixels(rgb, None, rect, context),
            "RGB pass on an 8x8 viewport": lambda: mujoco.mjr_render(tiny, scene, context),
            "RGB pass without shadows": no_shadows(lambda: mujoco.mjr_render(rect, scene, context)),
            "RGB pass without shadows, 8x8 viewport": no_shadows(lambda: mujoco.mjr_render(tiny, scene, context)),
        }
        seconds = dict.fromkeys(steps, 0.0)
        for k in range(frames + 1):  # the first round warms up
            for name, step in (steps.items() if k % 2 else reversed(steps.items())):
                if name == "RGB resolve and read-back":
                    mujoco.mjr_render(rect, scene, context)
                GL.glFinish()
                start = time.perf_counter()
                step()
                GL.glFinish()
                if k:
                    seconds[name] += (time.perf_counter() - start) / frames
        return {name: round(value, 4) for name, value in seconds.items()}
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
        "RGB, shadow maps 512": dict(options={"shadow_size": 512}),
        "RGB, none of shadows, reflection, multisampling": dict(options={"shadows": False},
                                                                 flags_off=("mjRND_REFLECTION",), offsamples=0),
    }
    results, reference, written_rgb = {}, None, None
    try:
        steps = passes(env, frames)
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
    print(f"\n{'GL step (glFinish after each)':50s} {'s/frame':>8s}")
    for name, value in steps.items():
        print(f"{name:50s} {value:8.3f}")
    print(json.dumps({"benchmark": "keyframe_breakdown", "metric": "seconds per MuJoCo render, by variant",
                      "unit": "s", "frames": frames, "resolution": [848, 480], "variants": results, "gl_steps": steps,
                      "cores": os.cpu_count(), "load_average_1min": round(os.getloadavg()[0], 2)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
