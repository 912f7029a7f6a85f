"""``muble render``: render a scene file, or an episode's keyframes, to PNGs plus a GIF and a contact sheet.

    muble render SCENE.json [--keyframes EPISODE.npz] [--renderer blender] [--camera front]
                 [--object-set shopvrb2] [--out DIR] [--set samples=16 --set width=320 …] [--passes]

``EPISODE.npz`` holds ``qpos``, an array (keyframes, nq) of MuJoCo joint positions of the scene's world, one
row per keyframe. Without it the scene's initial state is rendered once. With ``--passes`` each keyframe's
depth (16-bit PNG, millimetres) and segmentation (16-bit PNG, label + 3: 0 background, 1 table, 2 robot,
3 + i object i) are written next to its RGB.
"""
from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path
from typing import Any

import numpy as np

from muble.core.errors import ConfigError
from muble.core.types import SEG_ROBOT, SEG_TABLE, Frame

log = logging.getLogger(__name__)

SHEET_COLUMNS = 4
SHEET_THUMB_WIDTH = 320
GIF_FRAME_MS = 600


def _parse_value(text: str) -> Any:
    import yaml

    return yaml.safe_load(text)


def renderer_options(pairs: list[str]) -> dict[str, Any]:
    """``["samples=8", "denoise=false"]`` -> ``{"samples": 8, "denoise": False}``."""
    options = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ConfigError(f"renderer option '{pair}' is not KEY=VALUE, e.g. --set samples=16")
        options[key.strip()] = _parse_value(value)
    return options


def contact_sheet(images: list[np.ndarray], columns: int = SHEET_COLUMNS, width: int = SHEET_THUMB_WIDTH,
                  labels: list[str] | None = None) -> np.ndarray:
    """The images side by side in rows of ``columns``, each scaled to ``width`` pixels, with a caption."""
    from PIL import Image, ImageDraw

    if not images:
        raise ConfigError("a contact sheet needs at least one image")
    h, w = images[0].shape[:2]
    height = round(h * width / w)
    rows = math.ceil(len(images) / columns)
    cols = min(columns, len(images))
    sheet = Image.new("RGB", (cols * width + (cols + 1) * 4, rows * height + (rows + 1) * 4), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, image in enumerate(images):
        x, y = 4 + (i % columns) * (width + 4), 4 + (i // columns) * (height + 4)
        sheet.paste(Image.fromarray(image).resize((width, height), Image.LANCZOS), (x, y))
        caption = labels[i] if labels else str(i)
        draw.rectangle([x, y, x + 8 * len(caption) + 6, y + 14], fill=(0, 0, 0))
        draw.text((x + 3, y + 1), caption, fill=(255, 255, 255))
    return np.asarray(sheet)


def write_frame(frame: Frame, out: Path, stem: str, passes: bool) -> None:
    from PIL import Image

    Image.fromarray(frame.rgb).save(out / f"{stem}.png")
    if passes and frame.depth is not None:
        depth_mm = np.where(np.isfinite(frame.depth), np.clip(frame.depth * 1000.0, 0, 65535), 0)
        Image.fromarray(depth_mm.astype(np.uint16)).save(out / f"{stem}_depth.png")
    if passes and frame.segmentation is not None:
        seg = frame.segmentation
        code = np.where(seg >= 0, seg + 3, 0)
        code[seg == SEG_TABLE], code[seg == SEG_ROBOT] = 1, 2
        Image.fromarray(code.astype(np.uint16)).save(out / f"{stem}_seg.png")


def write_episode_media(images: list[np.ndarray], out: Path) -> list[Path]:
    """``episode.gif`` (when there is more than one keyframe) and ``contact_sheet.png``."""
    from PIL import Image

    written = []
    if len(images) > 1:
        frames = [Image.fromarray(im) for im in images]
        gif = out / "episode.gif"
        frames[0].save(gif, save_all=True, append_images=frames[1:], duration=GIF_FRAME_MS, loop=0)
        written.append(gif)
    sheet = out / "contact_sheet.png"
    Image.fromarray(contact_sheet(images)).save(sheet)
    written.append(sheet)
    return written


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="muble render", description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", help="SHOP-VRB2 scene JSON file")
    parser.add_argument("--keyframes", help=".npz with 'qpos' (keyframes, nq): the episode's states")
    parser.add_argument("--renderer", default="blender", help="renderer plugin name (default: blender)")
    parser.add_argument("--camera", default="front", help="MuJoCo camera name (default: front)")
    parser.add_argument("--object-set", default="shopvrb2", help="object set the scene's objects come from")
    parser.add_argument("--robot", default=None, help="robosuite robot (default: the environment's)")
    parser.add_argument("--out", default="render_out", help="output folder (created)")
    parser.add_argument("--set", dest="options", action="append", default=[], metavar="KEY=VALUE",
                        help="renderer option, repeatable (e.g. --set samples=16 --set width=320)")
    parser.add_argument("--passes", action="store_true", help="also write depth and segmentation PNGs")
    return parser


def main(argv: list[str]) -> int:
    import mujoco

    from muble.core.scene_io import load_scene
    from muble.plugins.registry import get_registry
    from muble.sim.build import env_from_object_set

    args = _parser().parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    scene = load_scene(args.scene)
    robot = {"name": args.robot} if args.robot else None
    env = env_from_object_set(scene, args.object_set, robot=robot)
    try:
        env.reset()
        model, data = env.model, env.data
        if args.keyframes:
            states = np.load(args.keyframes)["qpos"]
            if states.ndim != 2 or states.shape[1] != model.nq:
                raise ConfigError(f"{args.keyframes}: 'qpos' has shape {states.shape}; this scene's world needs "
                                  f"(keyframes, {model.nq})")
        else:
            states = np.asarray(data.qpos, dtype=float)[None]
        renderer = get_registry().create("renderer", args.renderer, renderer_options(args.options))
        images = []
        try:
            renderer.setup(scene, model)
            for k, qpos in enumerate(states):
                data.qpos[:] = qpos
                mujoco.mj_forward(model, data)
                frame = renderer.render(data, args.camera)
                write_frame(frame, out, f"keyframe_{k:04d}", args.passes)
                images.append(frame.rgb)
                log.info("keyframe %d/%d rendered", k + 1, len(states))
        finally:
            renderer.close()
        for path in write_episode_media(images, out):
            log.info("wrote %s", path)
    finally:
        env.close()
    print(f"rendered {len(images)} keyframe(s) of {args.scene} to {out}")
    return 0
