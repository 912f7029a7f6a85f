"""``muble render``: render a scene file, or an episode's keyframes, to PNGs plus a GIF and a contact sheet.

    muble render SCENE.json [--keyframes EPISODE_states.npz] [--renderer NAME] [--camera front]
                 [--object-set NAME] [--out DIR] [--set samples=16 --set width=320 …] [--passes]

``EPISODE_states.npz`` is the keyframe state file ``muble run`` writes beside an episode's keyframes
(``keyframes/<episode>_states.npz``, see ``muble.io.keyframe_states``): ``qpos``, an array (keyframes, nq) of
MuJoCo joint positions of the scene's world, one row per keyframe, and the robot, object set and camera the
episode used (the defaults of ``--robot``, ``--object-set`` and ``--camera``). Without it the scene's initial
state is rendered once. The renderer, and an object set that neither the command line nor the keyframe states
name, are the ``render`` config's (``muble_conf/render.yaml``: the run's, with the photoreal renderer). With
``--passes`` each keyframe's depth (16-bit PNG, millimetres) and segmentation (16-bit PNG, label + 3:
0 background, 1 table, 2 robot, 3 + i object i) are written next to its RGB.

Every input is checked before anything is written; the outputs reach ``--out`` only when all keyframes are
rendered, so a failed command leaves no folder or partial files behind.
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

import numpy as np

from muble.core.errors import ConfigError
from muble.core.types import SEG_ROBOT, SEG_TABLE, Frame
from muble.io.image_grid import contact_sheet

log = logging.getLogger(__name__)

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
    parser.add_argument("--keyframes", help="keyframe state file (.npz with 'qpos') that `muble run` writes")
    parser.add_argument("--renderer", default=None,
                        help="renderer plugin name (default: the render config's, muble_conf/render.yaml)")
    parser.add_argument("--camera", default=None, help="MuJoCo camera name (default: the episode's, else front)")
    parser.add_argument("--object-set", default=None,
                        help="object set the scene's objects come from (default: the episode's, else the render "
                        "config's)")
    parser.add_argument("--robot", default=None, help="robosuite robot (default: the episode's, else the "
                        "environment's)")
    parser.add_argument("--out", default="render_out", help="output folder (created)")
    parser.add_argument("--set", dest="options", action="append", default=[], metavar="KEY=VALUE",
                        help="renderer option, repeatable (e.g. --set samples=16 --set width=320)")
    parser.add_argument("--passes", action="store_true", help="also write depth and segmentation PNGs")
    return parser


def configured_plugins() -> tuple[str, str]:
    """(renderer, object set) of the ``render`` config (``muble_conf/render.yaml``), composed as every job's config is,
    plugins' config folders included."""
    from muble.app.config import compose

    cfg = compose("render")
    return cfg.renderer.name, cfg.objects.name


def _check_name(registry: Any, kind: str, name: str, flag: str) -> None:
    from muble.core.errors import unknown_name

    names = registry.names(kind)
    if name not in names:
        raise ConfigError(f"{flag}: " + unknown_name(kind, name, names))


def main(argv: list[str]) -> int:
    from muble.io.atomic import check_output_folder, staged_folder
    from muble.io.keyframe_states import read_keyframe_states
    from muble.io.scene_io import check_input_file, load_scene
    from muble.plugins.registry import get_registry, validate_params

    args = _parser().parse_args(argv)
    # Everything the command line names is checked before the first file is written.
    check_output_folder(args.out, "--out")
    scene = load_scene(args.scene)
    if args.keyframes:
        check_input_file(args.keyframes)  # a FIFO, device or huge file is refused before it is opened
    states = read_keyframe_states(args.keyframes) if args.keyframes else None
    camera = args.camera or (states.camera if states else None) or "front"
    object_set = args.object_set or (states.object_set if states else None)
    if args.renderer is None or object_set is None:
        renderer, configured_set = configured_plugins()
        args.renderer = args.renderer or renderer
        object_set = object_set or configured_set
    robot_name = args.robot or (states.robot if states else None)
    registry = get_registry()
    _check_name(registry, "renderer", args.renderer, "--renderer")
    _check_name(registry, "object_set", object_set, "--object-set")
    options = renderer_options(args.options)
    validate_params("renderer", registry.get("renderer", args.renderer).record, options)
    with staged_folder(args.out, "--out") as stage:
        images = _render(scene, states, args, camera, object_set, robot_name, options, stage)
    print(f"rendered {len(images)} keyframe(s) of {args.scene} to {args.out}")
    return 0


def _render(scene: Any, states: Any, args: argparse.Namespace, camera: str, object_set: str,
            robot_name: str | None, options: dict[str, Any], out: Path) -> list[np.ndarray]:
    import mujoco
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm

    from muble.plugins.registry import get_registry
    from muble.sim.build import env_from_object_set

    env = env_from_object_set(scene, object_set, robot={"name": robot_name} if robot_name else None)
    images: list[np.ndarray] = []
    try:
        env.reset()
        model, data = env.model, env.data
        if states is not None:
            qpos = states.qpos
            if qpos.shape[1] != model.nq:
                raise ConfigError(f"--keyframes {args.keyframes}: 'qpos' has {qpos.shape[1]} columns; the world "
                                  f"of {args.scene} with robot {env.names.robot} and object set {object_set} has "
                                  f"nq={model.nq}: pass the scene and --robot of the episode that wrote the file")
        else:
            qpos = np.asarray(data.qpos, dtype=float)[None]
        mj_camera = env.names.cameras.get(camera, camera)
        cameras = [model.camera(i).name for i in range(model.ncam)]
        if mj_camera not in cameras:
            from muble.core.errors import unknown_name

            valid = sorted(set(env.names.cameras) | set(cameras))
            raise ConfigError("--camera: " + unknown_name("camera", camera, valid))
        renderer = get_registry().create("renderer", args.renderer, options)
        try:
            renderer.setup(scene, model)
            bar = tqdm(qpos, desc="render", unit="keyframe", disable=None)
            with logging_redirect_tqdm():  # log lines are written above the bar, which stays whole
                for k, state in enumerate(bar):
                    data.qpos[:] = state
                    mujoco.mj_forward(model, data)
                    frame = renderer.render(data, mj_camera)
                    write_frame(frame, out, f"keyframe_{k:04d}", args.passes)
                    images.append(frame.rgb)
                    log.info("keyframe %d/%d rendered", k + 1, len(qpos))
        finally:
            renderer.close()
        for path in write_episode_media(images, out):
            log.info("wrote %s", path.name)
    finally:
        env.close()
    return images
