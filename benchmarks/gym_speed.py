"""Steps per second of ``MuBlE/Tabletop-v0`` at its defaults (128x128 RGB), state-only (``render=False``) and raw
physics (the same environment's control step with no observation built), measured in the same run; the masks
of the default rendering settings against those of the renderer as a keyframe draws them (shadows, reflection,
multisampling, meshes as modelled), at the environment's image size, as IoU; and ``MuBlE/ShopVRB2-v0``'s reset.

Each figure is given in steps per wall-second and per CPU-second of this process (the GL rasteriser runs in
it): on a loaded machine the wall figure falls with the load and the CPU figure much less. Run with one
rasteriser thread, as on one core:

    LP_NUM_THREADS=1 MUJOCO_GL=egl python benchmarks/gym_speed.py [STEPS] [RESETS]
"""
from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("LP_NUM_THREADS", "1")

from muble.core import streams  # noqa: E402

# Seeded as before named streams (muble.core.streams.legacy_stream): the figures docs/ reports were measured so.
ACTIONS = streams.declare_legacy("bench.gym_speed.actions", "the random actions timed and stepped between the mask "
                                 "comparisons (0: timed, 1: masks)")

SEEDS = (0, 1)
# Scenes whose masks are compared (eight states each, five random steps apart): the arm over the objects, its
# gripper in front of them, objects partly hidden.
MASK_SEEDS = (0, 1, 2, 3, 4, 5)
# The renderer as a keyframe is drawn (muble generate's settings before the environment's fast defaults).
KEYFRAME_SETTINGS = {"shadows": True, "shadow_size": None, "reflection": True, "multisamples": None,
                     "mesh_tolerance": None}


def timed_steps(env, steps: int, step, seed: int) -> dict[str, float]:
    """Steps per second of ``step`` (returning gymnasium's five values) under random actions; an episode that
    ends (random actions can knock an object off the table, a physics fault) is reset with the next seed, the
    reset left out of the time."""
    rng = streams.legacy_stream(ACTIONS, 0)
    actions = rng.uniform(-0.3, 0.3, size=(steps, 7)).astype(np.float32)
    wall = cpu = 0.0
    resets = 0
    for action in actions:
        w, c = time.perf_counter(), time.process_time()
        ended = any(step(action)[2:4])
        wall, cpu = wall + time.perf_counter() - w, cpu + time.process_time() - c
        if ended:
            resets += 1
            env.reset(seed=seed + 1000 * resets)
    return {"steps_per_s": steps / wall, "steps_per_cpu_s": steps / cpu, "episodes_ended": resets}


def tabletop_speed(steps: int, render: bool) -> tuple[dict, dict | None]:
    """(the environment's figures, raw physics in the same environment: only with ``render=False``)."""
    import gymnasium

    env = gymnasium.make("MuBlE/Tabletop-v0", render=render)
    try:
        figures, raw = [], []
        for seed in SEEDS:
            env.reset(seed=seed)
            for _ in range(3):  # warm-up: first frames compile shaders
                env.step(np.zeros(7, dtype=np.float32))
            figures.append(timed_steps(env, steps, env.step, seed))
            if not render:
                env.reset(seed=seed)
                raw.append(timed_steps(env, steps,
                                       lambda a: env.unwrapped.env.step(np.asarray(a, dtype=np.float64)), seed))
        mean = lambda rows: {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}  # noqa: E731
        return mean(figures), (mean(raw) if raw else None)
    finally:
        env.close()


def mask_iou(states: int) -> dict[str, float]:
    """Least IoU over the states, for the robot and for any object, of the default settings' masks against the
    keyframe settings' (both at the environment's image size)."""
    import gymnasium

    from muble import SEG_ROBOT, get_registry
    from muble.gym.tabletop import FAST_MUJOCO_OVERRIDES

    env = gymnasium.make("MuBlE/Tabletop-v0")
    size = {"width": 128, "height": 128, "rgb": False, "depth": False, "segmentation": True}
    fast = {o.split("=")[0].split(".")[1]: json.loads(o.split("=")[1]) for o in FAST_MUJOCO_OVERRIDES}
    renderers = [get_registry().create("renderer", "mujoco", {**size, **KEYFRAME_SETTINGS}),
                 get_registry().create("renderer", "mujoco", {**size, **fast})]
    robot, objects = [], []
    try:
        rng = streams.legacy_stream(ACTIONS, 1)
        for seed in MASK_SEEDS:
            env.reset(seed=seed)
            inner = env.unwrapped.env
            camera = inner.names.cameras["front"]
            for r in renderers:
                r.setup(inner.sync_scene_graph(), inner.model)
            ended = False
            for _ in range(states):
                if ended:
                    break  # the episode ended (random actions knocked an object off): the next seed's scene
                today, ours = (r.render(inner.data, camera).segmentation for r in renderers)
                for label in np.unique(today):
                    a, b = today == label, ours == label
                    iou = float((a & b).sum() / (a | b).sum())
                    if label == SEG_ROBOT:
                        robot.append(iou)
                    elif label >= 0:
                        objects.append(iou)
                for _ in range(5):
                    ended = any(env.step(rng.uniform(-1, 1, 7).astype(np.float32))[2:4])
                    if ended:
                        break
    finally:
        for r in renderers:
            r.close()
        env.close()
    return {"robot": min(robot), "objects": min(objects), "masks_compared": len(robot) + len(objects)}


def _fresh_per_episode_env():
    """``MuBlE/ShopVRB2-v0`` as it ran before episodes shared a worker thread and a renderer: a thread, a GL
    context and a renderer (meshes uploaded anew) per episode. The baseline."""
    from muble.episode.stepped import SteppedEpisode
    from muble.gym.shopvrb2 import ShopVRB2Env

    class FreshPerEpisode(ShopVRB2Env):
        def _start(self, spec):
            self._end_episode()
            self.episode = SteppedEpisode(self.factory.runner(), spec.scene, spec.instruction, spec.task)
            return self.episode.start()

    return FreshPerEpisode()


def shopvrb2_reset(resets: int, warm: int = 8) -> dict[str, dict[str, float]]:
    """Seconds (wall and CPU) per reset of the environment against the baseline, interleaved reset by reset on the
    same seeds after ``warm`` resets each (the kept renderer's meshes cover the object set's models by then); the
    first images of every measured reset must be the same in both."""
    import gymnasium

    envs = {"kept": gymnasium.make("MuBlE/ShopVRB2-v0").unwrapped, "fresh": _fresh_per_episode_env()}
    times: dict[str, dict[str, list[float]]] = {k: {"wall": [], "cpu": []} for k in envs}
    try:
        for seed in range(100, 100 + warm):
            for env in envs.values():
                env.reset(seed=seed)
        for seed in range(resets):
            seen = []
            for name, env in envs.items():
                wall, cpu = time.perf_counter(), time.process_time()
                observation, _ = env.reset(seed=seed)
                times[name]["cpu"].append(time.process_time() - cpu)
                times[name]["wall"].append(time.perf_counter() - wall)
                seen.append(observation["images"]["front"])
            if not np.array_equal(seen[0], seen[1]):
                raise SystemExit(f"seed {seed}: the kept renderer's first image differs from a fresh one's")
    finally:
        for env in envs.values():
            env.close()
    return {name: {"median_s": float(np.median(t["wall"])), "median_cpu_s": float(np.median(t["cpu"])),
                   "max_s": float(np.max(t["wall"]))} for name, t in times.items()}


def main() -> int:
    import muble.gym  # noqa: F401 - registers the ids

    steps = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    resets = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    images, _ = tabletop_speed(steps, render=True)
    state, raw = tabletop_speed(steps, render=False)
    iou = mask_iou(states=8)
    reset = shopvrb2_reset(resets)
    rows = {"Tabletop defaults (128x128 RGB)": images, "Tabletop state-only (render=False)": state,
            "raw physics (control step, no observation)": raw}
    print(f"{'':45s} {'steps/s':>9s} {'ratio':>6s} {'steps/CPU-s':>12s} {'ratio':>6s}")
    for name, row in rows.items():
        print(f"{name:45s} {row['steps_per_s']:9.1f} {row['steps_per_s'] / raw['steps_per_s']:6.2f} "
              f"{row['steps_per_cpu_s']:12.1f} {row['steps_per_cpu_s'] / raw['steps_per_cpu_s']:6.2f}")
    print(f"mask IoU against the keyframe settings at 128x128: robot {iou['robot']:.4f}, objects (least) "
          f"{iou['objects']:.4f} over {iou['masks_compared']} masks")
    kept, fresh = reset["kept"], reset["fresh"]
    print(f"ShopVRB2-v0 reset: median {kept['median_s']:.2f} s ({kept['median_cpu_s']:.2f} CPU-s), max "
          f"{kept['max_s']:.2f} s over {resets}; a context and renderer per episode (before): median "
          f"{fresh['median_s']:.2f} s ({fresh['median_cpu_s']:.2f} CPU-s); ratio {kept['median_s'] / fresh['median_s']:.2f} "
          f"(CPU {kept['median_cpu_s'] / fresh['median_cpu_s']:.2f}); the same first images")
    print(json.dumps({
        "benchmark": "gym_speed", "metric": "Tabletop-v0 steps per second at its defaults (128x128 RGB)",
        "value": round(images["steps_per_s"], 1), "unit": "steps/s", "goal": 100,
        "steps_per_cpu_s": round(images["steps_per_cpu_s"], 1),
        "state_only": {k: round(v, 1) for k, v in state.items()}, "state_only_goal": 200,
        "raw_physics": {k: round(v, 1) for k, v in raw.items()},
        "ratio_to_raw": round(images["steps_per_s"] / raw["steps_per_s"], 3),
        "state_only_ratio_to_raw": round(state["steps_per_s"] / raw["steps_per_s"], 3),
        "mask_iou": {k: round(v, 4) if isinstance(v, float) else v for k, v in iou.items()}, "mask_iou_goal": 0.95,
        "shopvrb2_reset_s": {name: {k: round(v, 2) for k, v in r.items()} for name, r in reset.items()},
        "shopvrb2_reset_goal_s": 1.0,
        "steps": steps, "lp_num_threads": os.environ.get("LP_NUM_THREADS"), "cores": os.cpu_count(),
        "load_average_1min": round(os.getloadavg()[0], 2)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
