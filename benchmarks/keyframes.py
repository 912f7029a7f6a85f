"""MuJoCo keyframe cost as ``muble generate`` pays it: 848x480 RGB + depth + segmentation, written.

Per episode the worker's renderer, kept open from episode to episode as ``muble generate`` keeps it, is set up
on the episode's model (its GL context's mesh slots refilled); per keyframe it draws RGB and the
segmentation/depth pass, the PNG is encoded (``png_bytes``) and the masks are COCO-RLE encoded as the sequence
file holds them (each object twice, robot and table), plus the scene file's masks from the first keyframe (and
the episode GIF with ``gif`` among the arguments: ``dataset.gif=true``). The cost per keyframe is that total
over the keyframes.

The baseline is the same work with a new renderer and a fresh OpenGL context per episode (what every episode
paid before contexts and renderers were kept), measured in the same run, episodes interleaved so load on a shared
machine hits both alike. Both paths must write the same bytes: the run fails otherwise.

Renderer overrides after the counts (``renderer.shadows=false``, ``renderer.shadow_size=2048``) add a third
path, the same work with a renderer built with them, timed in the same run; its cost is printed as a ratio to
the default's, with what it gives up over every keyframe: the share of RGB pixels it changes (mean and largest),
their mean absolute difference, the lowest SSIM against the default's keyframe, and whether depth and segmentation
are the same.
``before`` in their place is the keyframe as written before 1024² shadow maps and PNG level 1 were the defaults
(``renderer.shadow_size=null``, PNG level 6). ``previous`` is the renderer as it drew before the id pass went first
(``PreviousRenderer``: the RGB pass with the floor's reflection whether seen or not, then the segmentation/depth
pass through the multisampled buffer and its resolve, and the context's contents matched by digests); it must
write the same bytes as the renderer now, and the run fails otherwise.

    python benchmarks/keyframes.py [EPISODES] [KEYFRAMES_PER_EPISODE] [renderer.OPTION=VALUE ... | before | previous] [gif]
"""
from __future__ import annotations

import copy
import hashlib
import json
import logging
import os
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.support: helpers shared with the tests

GOAL_SECONDS = 0.3
BEFORE_PNG_LEVEL = 6  # Pillow's default, what png_bytes wrote before level 1


def previous_renderer_class():
    """The MuJoCo renderer's drawing as it was before the segmentation/depth pass went first (see the docstring)."""
    import hashlib

    import mujoco

    from muble import Frame
    from muble_plugins.renderers.mujoco.atlas import mesh_slot_parts, stage_parts
    from muble_plugins.renderers.mujoco.renderer import MujocoRenderer

    def digest(parts):
        h = hashlib.blake2b(digest_size=16)
        for part in parts:
            h.update(np.ascontiguousarray(part).tobytes())
        return h.digest()

    class PreviousRenderer(MujocoRenderer):
        def __init__(self, **options):
            super().__init__(**{**options, "reflection_when_hidden": True})
            self._stage_key, self._slot_keys = None, []

        def _context_for(self, model) -> None:
            parts = stage_parts(model)
            stage = None if parts is None else digest(parts)
            context = self._context
            if stage is None or context is None or stage != self._stage_key or context.rangeMesh < 2 * model.nmesh:
                self._make_context(model)
                self._stage_key = stage
                self._slot_keys = [digest(mesh_slot_parts(model, i)) for i in range(model.nmesh)] if stage else []
                return
            slots = [digest(mesh_slot_parts(model, i)) for i in range(model.nmesh)]
            changed = [i for i, key in enumerate(slots) if self._slot_keys[i] != key]
            for i in changed:
                mujoco.mjr_uploadMesh(model, context, i)
            self._slot_keys = slots + self._slot_keys[len(slots):]
            self._context_model = model

        def render(self, data, camera: str) -> Frame:
            self._gl.make_current()
            cam = self._camera(camera)
            w, h = self.config.width, self.config.height
            rect = mujoco.MjrRect(0, 0, w, h)
            self._update_scene(data, cam)
            mujoco.mjr_render(rect, self._scene, self._context)
            rgb = np.empty((h, w, 3), dtype=np.uint8)
            mujoco.mjr_readPixels(rgb, None, rect, self._context)
            flags = self._scene.flags
            seg_flag, id_flag = mujoco.mjtRndFlag.mjRND_SEGMENT, mujoco.mjtRndFlag.mjRND_IDCOLOR
            flags[seg_flag], flags[id_flag] = 1, 1
            try:
                mujoco.mjr_render(rect, self._scene, self._context)
                ids = np.empty((h, w, 3), dtype=np.uint8)
                z = np.empty((h, w), dtype=np.float32)
                mujoco.mjr_readPixels(ids, z, rect, self._context)
            finally:
                flags[seg_flag], flags[id_flag] = 0, 0
            return Frame(camera=camera, rgb=np.ascontiguousarray(np.flipud(rgb)),
                         depth=self._metric_depth(np.flipud(z)), segmentation=self._labels_of(np.flipud(ids)))

    return PreviousRenderer


def episode(renderer, env, scene, keyframes: int, png_level: int | None = None, close: bool = True,
            gif: bool = False) -> tuple[float, float, str, list]:
    """Wall and CPU seconds of one episode's keyframes, a digest of everything written and the frames drawn; the
    renderer is closed at the end unless kept (``close=False``, as ``muble generate``'s workers keep theirs)."""
    import mujoco

    from muble.core.types import SEG_ROBOT, SEG_TABLE
    from muble.episode.runner import gif_bytes, png_bytes
    from muble.episode.sequence import encode_rle
    from muble.generation.ground_truth import apply_masks

    digest = hashlib.sha256()
    arm = env.data.qpos[:7].copy()
    start, cpu = time.perf_counter(), time.process_time()
    renderer.setup(env.sync_scene_graph(), env.model)
    camera = env.names.cameras.get("front", "front")
    frames, drawn = [], []
    for k in range(keyframes):
        env.data.qpos[:7] = arm + 0.05 * k * np.sin(np.arange(7) + k)  # the arm moves between keyframes
        mujoco.mj_forward(env.model, env.data)
        frame = renderer.render(env.data, camera)
        digest.update(png_bytes(frame.rgb) if png_level is None else png_bytes(frame.rgb, png_level))
        for obj in scene.objects:
            for _ in ("observations", "observations_gt"):
                digest.update(json.dumps(encode_rle(frame.segmentation == obj.id)).encode())
        for label in (SEG_ROBOT, SEG_TABLE):
            digest.update(json.dumps(encode_rle(frame.segmentation == label)).encode())
        if k == 0:
            masked = copy.deepcopy(scene)
            apply_masks(masked, frame.segmentation)
            digest.update(json.dumps([o.mask.to_dict() for o in masked.objects]).encode())
        frames.append(frame.rgb)
        drawn.append(frame)
    if gif:
        digest.update(gif_bytes(frames))
    if close:
        renderer.close()
    env.data.qpos[:7] = arm
    return time.perf_counter() - start, time.process_time() - cpu, digest.hexdigest(), drawn


def main() -> int:
    from omegaconf import OmegaConf

    import muble_plugins.renderers.mujoco.gl as gl
    from muble.app.config import compose
    from muble.app.run import build_components, scene_generator
    from muble.sim.build import object_models
    from muble.sim.env import TabletopEnv
    from tests.support.image_likeness import ssim

    logging.basicConfig(level=logging.WARNING)
    episodes = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    keyframes = int(sys.argv[2]) if len(sys.argv) > 2 else 6
    overrides = [a for a in sys.argv[3:] if a != "gif"]
    gif = "gif" in sys.argv[3:]
    before = overrides == ["before"]
    previous = overrides == ["previous"]
    if before:
        overrides = ["renderer.shadow_size=null"]
    cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp", "renderer=mujoco"])
    components = build_components(cfg, task=False)
    renderer = components["renderer"]

    def fresh_renderer():
        from muble import get_registry

        options = OmegaConf.to_container(cfg.renderer, resolve=True)
        return get_registry().create("renderer", options["name"], options)

    variant = None
    if previous:
        options = OmegaConf.to_container(cfg.renderer, resolve=True)
        options.pop("name", None)
        variant = previous_renderer_class()(**options)
    elif overrides:
        variant_cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp", "renderer=mujoco", *overrides])
        variant = build_components(variant_cfg, task=False)["renderer"]
    generator = scene_generator(cfg, components["object_set"])
    try:
        scenes = [generator.generate(i) for i in range(episodes)]
    finally:
        generator.close()
    robot = OmegaConf.to_container(cfg.robot, resolve=True)
    kept = gl.MAX_SPARE
    totals = {"fresh": [0.0, 0.0], "kept": [0.0, 0.0], "variant": [0.0, 0.0]}
    mismatches, changed, variant_mismatches = 0, [], 0
    likeness, masks_same = [], True  # per variant keyframe: (mean absolute difference, SSIM); depth and labels
    warm_env = TabletopEnv(scenes[0], object_models(scenes[0], components["object_set"], cfg.objects.name), robot, {})
    episode(renderer, warm_env, scenes[0], 1, close=False)  # imports and the first context, paid once by any process
    if variant is not None:
        episode(variant, warm_env, scenes[0], 1, close=False)
    warm_env.close()
    for i, scene in enumerate(scenes):
        env = TabletopEnv(scene, object_models(scene, components["object_set"], cfg.objects.name), robot, {})
        digests, frames = {}, {}
        modes = ("fresh", "kept", "variant") if variant is not None else ("fresh", "kept")
        for mode in (modes if i % 2 == 0 else modes[::-1]):
            gl.MAX_SPARE = 0 if mode == "fresh" else kept
            if mode == "fresh":
                gl.free_spares()
                drawing = fresh_renderer()
            else:
                drawing = variant if mode == "variant" else renderer
            wall, cpu, digests[mode], frames[mode] = episode(drawing, env, scene, keyframes,
                                                           BEFORE_PNG_LEVEL if before and mode == "variant" else None,
                                                           close=mode == "fresh", gif=gif)
            totals[mode][0] += wall
            totals[mode][1] += cpu
        mismatches += digests["fresh"] != digests["kept"]
        if variant is not None:
            variant_mismatches += digests["variant"] != digests["kept"]
            for ours, theirs in zip(frames["variant"], frames["kept"], strict=True):
                diff = np.abs(ours.rgb.astype(np.int16) - theirs.rgb.astype(np.int16))
                changed.append(float((diff.max(axis=2) > 0).mean()))
                likeness.append((float(diff.mean()), ssim(ours.rgb, theirs.rgb)))
                masks_same &= bool(np.array_equal(ours.segmentation, theirs.segmentation)
                                   and np.array_equal(ours.depth, theirs.depth))
        env.close()
    gl.MAX_SPARE = kept
    renderer.close()
    if variant is not None:
        variant.close()
    n = episodes * keyframes
    per = {mode: {"wall_s": round(t[0] / n, 3), "cpu_s": round(t[1] / n, 3)} for mode, t in totals.items()}
    variant_summary = None
    if variant is not None:
        variant_summary = {"overrides": overrides, "wall_s": per["variant"]["wall_s"],
                           "cpu_s": per["variant"]["cpu_s"],
                           "ratio_to_default": round(totals["variant"][0] / totals["kept"][0], 3),
                           "rgb_pixels_changed": round(float(np.mean(changed)), 5),
                           "rgb_pixels_changed_max": round(float(np.max(changed)), 5),
                           "rgb_mean_abs_diff": round(float(np.mean([d for d, _ in likeness])), 4),
                           "ssim_min": round(float(np.min([s for _, s in likeness])), 5),
                           "depth_and_segmentation_identical": masks_same,
                           "identical_outputs": variant_mismatches == 0}
    ratio = totals["kept"][0] / totals["fresh"][0]
    for mode, label in (("fresh", "renderer and GL context per episode"), ("kept", "renderer kept (now)")):
        print(f"{label:40s}: {per[mode]['wall_s']:.3f} s/keyframe wall, {per[mode]['cpu_s']:.3f} CPU-s/keyframe")
    print(f"ratio now/before (wall): {ratio:.3f}; outputs identical: {mismatches == 0}")
    if variant_summary is not None:
        print(f"{' '.join(overrides):40s}: {variant_summary['wall_s']:.3f} s/keyframe wall, ratio to the default "
              f"{variant_summary['ratio_to_default']:.3f} (CPU {totals['variant'][1] / totals['kept'][1]:.3f}), RGB pixels "
              f"changed {variant_summary['rgb_pixels_changed']:.3%} (at most {variant_summary['rgb_pixels_changed_max']:.3%}"
              f" of a keyframe), mean abs. difference {variant_summary['rgb_mean_abs_diff']:.4f}, SSIM >= "
              f"{variant_summary['ssim_min']:.5f}, depth and segmentation identical: {masks_same}, "
              f"outputs identical: {variant_mismatches == 0}")
        if previous:
            print(f"now/previous (wall): {totals['kept'][0] / totals['variant'][0]:.3f}")
    print(json.dumps({
        "benchmark": "keyframes", "metric": "seconds per MuJoCo keyframe written as by muble generate "
        "(848x480 RGB+depth+segmentation, PNG, masks; setup amortised)", "gif": gif,
        "value": per["kept"]["wall_s"], "unit": "s", "goal": GOAL_SECONDS,
        "baseline": per["fresh"]["wall_s"], "ratio_to_baseline": round(ratio, 3),
        "cpu_seconds": per["kept"]["cpu_s"], "baseline_cpu_seconds": per["fresh"]["cpu_s"],
        "identical_outputs": mismatches == 0, "variant": variant_summary, "episodes": episodes, "keyframes_per_episode": keyframes,
        "resolution": [renderer.config.width, renderer.config.height], "cores": os.cpu_count(),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }))
    return 0 if mismatches == 0 and not (previous and variant_mismatches) else 1


if __name__ == "__main__":
    sys.exit(main())
