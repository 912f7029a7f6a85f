"""Draw the wrist force/torque sensor during each hidden-property measurement of docs/physical_properties.md, from
real runs: the ``push``, ``balance`` and ``shake`` primitives on the Panda (its own gripper) on SHOP-VRB2 objects
alone on the table, picked, lifted and weighed as ``benchmarks/physical_properties.py`` does.

    python scripts/probing_plots.py            # writes docs/images/probing_push.svg, _balance.svg, _shake.svg

The primitives run unchanged. ``WristRecording`` reads the simulation after every physics step of the measurement
(``TabletopEnv.advance``'s ``on_physics``) and changes nothing in it: the readings are those of an unrecorded run
(``tests/sim/test_sim_probing_plots.py``). The runs are seeded and the SVGs carry no date, so a rerun draws the same
pictures. A few seconds on one core.
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # tests.support.scenes: the one-object scene the benchmark and the tests use
IMAGES = ROOT / "docs" / "images"

SEED = 0
POSITION = (0.5, 0.0)  # m on the table, in reach and clear of the robot's base
# The objects and the values they are given: a soda can for each measurement, the same one shaken with and
# without contents (a soda can is a closed container, ``ObjectModel.closed``).
PUSH_OBJECT, PUSH_FRICTION = "soda can", 0.6
BALANCE_OBJECT, BALANCE_OFFSET = "soda can", (0.012, -0.008)  # m, object frame
SHAKE_OBJECT, SHAKE_CONTENTS_G = "soda can", 25.0
# Samples drawn per line at most (the files stay small): every sample of a push stroke or a shake is drawn as the
# largest of its stride, so no spike is lost; the running means are smooth and need fewer.
MAX_POINTS = 1400
MEAN_POINTS = 300
# s of the running mean drawn over the push's forces: one control period (20 Hz), over which the pulses of the
# table's contact average out.
PUSH_MEAN_WINDOW = 0.05


@dataclasses.dataclass
class Segment:
    """What the sensors gave at every physics step of one ``advance`` call: simulated time (s); the wrist force
    and torque less the hand's own weight (``env.load_wrench()``: N, N·m about the sensor's site, world frame);
    the raw wrist force (N, world frame); the hand's position (m; ``start``: before the call); the spatial
    accelerations of the hand's site and of the held body (``handling.shake``'s regressors, 12 a row); the force
    sensor's site (m) and the held object's pose (position, quaternion w x y z: what a camera tracking it sees)."""

    start: np.ndarray
    t: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    wrist_force: np.ndarray
    hand: np.ndarray
    acceleration: np.ndarray
    site: np.ndarray
    held_pose: np.ndarray


class WristRecording:
    """Within ``with``: every ``env.advance`` made while the primitive's reading
    ``muble_plugins.primitives.handling.<measurement>`` runs is recorded, one ``Segment`` a call, into
    ``segments``. It wraps this one environment's ``advance`` and the reading (both restored on leaving) and only
    reads the simulation: a hold without ``on_physics`` steps the physics one call per step instead of
    ``n_substeps`` at once, the same computation."""

    def __init__(self, env, measurement: str):
        self.env, self.measurement = env, measurement
        self.segments: list[Segment] = []
        self._active = False

    def __enter__(self) -> "WristRecording":
        from muble_plugins.primitives import handling

        env = self.env
        advance, method = env.advance, getattr(handling, self.measurement)
        self._reading = method

        def recorded_advance(duration, on_control=None, on_physics=None):
            if not self._active:
                return advance(duration, on_control, on_physics)
            start, rows = env.data.site_xpos[env.ee_site_id].copy(), []

            def sample():
                if on_physics is not None:
                    on_physics()
                rows.append(self._read())

            advance(duration, on_control, sample)
            self.segments.append(Segment(start, *(np.array(column) for column in zip(*rows))))

        def recorded_method(*args, **kwargs):
            self._active = True
            try:
                return method(*args, **kwargs)
            finally:
                self._active = False

        env.advance = recorded_advance
        setattr(handling, self.measurement, recorded_method)  # the primitive looks it up there when it reads
        return self

    def __exit__(self, *exc) -> None:
        from muble_plugins.primitives import handling

        del self.env.advance  # the instance attribute goes; the class's method shows through again
        setattr(handling, self.measurement, self._reading)

    def _read(self) -> tuple:
        import mujoco

        env = self.env
        force, torque = env.load_wrench()
        hand, held, pose = np.zeros(6), np.zeros(6), np.full(7, np.nan)
        mujoco.mj_objectAcceleration(env.model, env.data, mujoco.mjtObj.mjOBJ_SITE, env.ee_site_id, hand, 0)
        if env.held_object is not None:
            body = env.model.body(env.names.objects[env.held_object]).id
            mujoco.mj_objectAcceleration(env.model, env.data, mujoco.mjtObj.mjOBJ_BODY, body, held, 0)
            pose = np.concatenate([env.data.xpos[body], env.data.xquat[body]])
        return (float(env.data.time), force, torque, env.wrist_wrench()[0].copy(),
                env.data.site_xpos[env.ee_site_id].copy(), np.concatenate([hand, held]),
                env.data.site_xpos[env.ft_site_id].copy(), pose)


@dataclasses.dataclass
class Run:
    """One measurement: the primitive's result, the object's spec, the modelled value, the recorded segments and
    the environment after it."""

    result: object
    spec: object
    truth: object
    segments: list[Segment]
    env: object


def _act(env, name: str, **params):
    from muble import get_registry

    return get_registry().create("primitive", name, params).execute(env)


def _object(category: str, seed: int, **changes):
    """A SHOP-VRB2 object of ``category``, sampled with ``seed``, with ``changes`` to its model."""
    from muble import get_registry

    from muble.core import streams

    # Seeded as before named streams (legacy_stream): the pictures in docs/images were drawn from these objects.
    purpose = streams.declare_legacy("script.probing_plots.object", "the sampled object a picture measures (seed)")
    objects = get_registry().create("object_set", "shopvrb2")
    spec = objects.sample(streams.legacy_stream(purpose, seed), category)
    return spec, dataclasses.replace(objects.build(spec), **changes)


def measure(measurement: str, category: str, seed: int = SEED, record: bool = True, **changes) -> Run:
    """Pick the object, lift it and weigh it, then ``measurement`` (``push``: set back where it stood first, as
    the benchmark does): the run, recorded unless ``record`` is False."""
    from muble import get_registry
    from muble.sim.env import TabletopEnv
    from tests.support.scenes import simple_scene

    spec, model = _object(category, seed, **changes)
    env = TabletopEnv(simple_scene([POSITION], [model]), {0: model}, robot={"name": "Panda", "gripper": None},
                      visual=False)
    env.planner = get_registry().create("planner", "ompl", {})
    for name in ("move", "approach", "close_gripper"):
        result = _act(env, name, target=0)
        if not result.success:
            raise RuntimeError(f"{name} {category}: {result.failure_reason}")
    standing = env.snapshot()
    for name in ("lift", "weigh"):
        result = _act(env, name)
        if not result.success:
            raise RuntimeError(f"{name} {category}: {result.failure_reason}")
    if measurement == "push":
        env.restore(standing)  # held where it stands again; the measured weight is kept
    if record:  # the primitive and the environment's method that reads the sensor share the name
        with WristRecording(env, measurement) as recording:
            result = _act(env, measurement)
        segments = recording.segments
    else:
        result, segments = _act(env, measurement), []
    if not result.success:
        raise RuntimeError(f"{measurement} {category}: {result.failure_reason}")
    truth = {"push": model.friction_coefficient, "balance": model.com_offset,
             "shake": model.contents_mass}[measurement]
    return Run(result, spec, truth, segments, env)


# ------------------------------------------------------------------------------------------------- the series
def push_series(run: Run) -> dict:
    """The push's two strokes (the last two segments: a set-down before them is a segment too): time (s), the
    force along each stroke's direction (N) and the normal force the table carries (N, measured weight less the
    wrist's vertical force), and which samples lie in the steady stretch the reading averages; ``friction``: the
    reading computed from these samples as ``handling.push`` does."""
    from muble.core.environment import GRAVITY
    from muble_plugins.primitives.probing import PUSH_DISTANCE, PUSH_SLOW_DOWN, PUSH_SPEED_UP

    env, info = run.env, run.result.info
    weight = env.measurements[info["object"]]["weight"] / 1000.0 * GRAVITY
    direction = np.array([*info["direction"], 0.0])
    steady = (PUSH_SPEED_UP, PUSH_DISTANCE - PUSH_SLOW_DOWN)  # the primitive's defaults, as it ran here
    t, along, normal, kept = [], [], [], []
    strokes = run.segments[-2:]
    for segment, d in zip(strokes, (direction, -direction)):
        travel = (segment.hand - segment.start) @ d
        t.append(segment.t)
        along.append(segment.force @ d)
        normal.append(weight - segment.force[:, 2])
        kept.append((travel >= steady[0]) & (travel <= steady[1]))
    t, along, normal, kept = (np.concatenate(x) for x in (t, along, normal, kept))
    friction = float(np.mean(along[kept])) / float(np.mean(normal[kept]))
    return {"t": t, "along": along, "normal": normal, "steady": kept, "friction": friction,
            "stroke_start": strokes[1].t[0]}


def _default(name: str) -> float:
    """A default of the probing primitives (``muble_plugins.primitives.probing``), as they ran here."""
    from muble_plugins.primitives import probing

    return getattr(probing, name)


def balance_series(run: Run) -> dict:
    """The held-still part of ``balance`` (settling, then the window it averages): time (s), the load's torque about
    the sensor's site (N·m), the weight it carries (N), which samples the reading averages, and ``offset``: the
    horizontal centre of mass (m, object frame) that each sample alone gives, as ``handling.balance`` reads it from
    the mean (the vertical line through the centre of mass, ``r_x = -τ_y / W``, ``r_y = τ_x / W``, met at half the
    object's height)."""
    import mujoco

    settle, window = run.segments[0], run.segments[1]
    torque = np.vstack([settle.torque, window.torque])
    weight = np.concatenate([settle.force[:, 2], window.force[:, 2]])
    site = np.vstack([settle.site, window.site])
    pose = np.vstack([settle.held_pose, window.held_pose])
    height = 0.5 * float(run.env.object_models[run.result.info["object"]].extents[2])
    offset = np.empty((len(weight), 2))
    rot = np.empty(9)
    for i in range(len(weight)):
        mujoco.mju_quat2Mat(rot, pose[i, 3:])
        r = rot.reshape(3, 3)
        line = site[i, :2] + np.array([-torque[i, 1], torque[i, 0]]) / weight[i]
        offset[i] = np.linalg.solve(r[:2, :2], line - pose[i, :2] - r[:2, 2] * height)
    return {"t": np.concatenate([settle.t, window.t]), "torque": torque, "weight": weight, "offset": offset,
            "window": np.concatenate([np.zeros(len(settle.t), bool), np.ones(len(window.t), bool)])}


def shake_series(run: Run) -> dict:
    """The shake: time (s), the raw wrist force along the swing (N) and, at every sample, the largest force along
    any axis that the rigid motion leaves unexplained (N: the residual of ``handling.shake``'s least-squares fit);
    ``peak``: its largest, the reading's ``peak_force``."""
    segment = run.segments[-1]
    direction = np.array([*run.result.info["direction"], 0.0])
    design = np.column_stack([segment.acceleration, np.ones(len(segment.t))])
    fit = np.linalg.lstsq(design, segment.wrist_force, rcond=None)[0]
    residual = np.abs(segment.wrist_force - design @ fit).max(axis=1)
    return {"t": segment.t - segment.t[0], "along": segment.wrist_force @ direction, "residual": residual,
            "peak": float(residual.max())}


# --------------------------------------------------------------------------------------------------- pictures
def _thin(x: np.ndarray, *ys: np.ndarray, points: int = MAX_POINTS) -> tuple[np.ndarray, ...]:
    """At most ``points`` points of a line: of every ``k`` samples, the one farthest from zero (so no spike is
    lost)."""
    k = max(1, int(np.ceil(len(x) / points)))
    if k == 1:
        return (x, *ys)
    n = len(x) // k * k
    out = [x[:n].reshape(-1, k)[:, 0]]
    for y in ys:
        blocks = y[:n].reshape(-1, k)
        out.append(blocks[np.arange(len(blocks)), np.abs(blocks).argmax(axis=1)])
    return tuple(out)


def _running_mean(y: np.ndarray, samples: int) -> np.ndarray:
    """Mean over ``samples`` centred on each sample (fewer at the ends)."""
    kernel = np.ones(samples)
    return np.convolve(y, kernel, "same") / np.convolve(np.ones_like(y), kernel, "same")


def _figure(rows: int):
    import matplotlib

    matplotlib.use("svg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"svg.fonttype": "none", "svg.hashsalt": "muble", "font.size": 9})
    return plt.subplots(rows, 1, figsize=(7.0, 2.3 * rows + 0.7), sharex=True, squeeze=False)


def _save(fig, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, format="svg", metadata={"Date": None, "Creator": None})
    plt.close(fig)


def _shade(ax, t: np.ndarray, mask: np.ndarray, label: str) -> None:
    """Shade the stretches of ``t`` where ``mask`` holds."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    for i, (a, b) in enumerate(zip(edges[::2], edges[1::2])):
        ax.axvspan(t[a], t[b - 1], color="0.92", zorder=0, label=label if i == 0 else None)


def _name(spec) -> str:
    return f"{spec.category} ({spec.model}, {spec.weight_g:.0f} g)"


def plot_push(run: Run, path: Path) -> None:
    """The force along the push and the normal force, every physics step (pale) and their running means."""
    s = push_series(run)
    t = s["t"] - s["t"][0]
    fig, axes = _figure(2)
    for ax in axes[:, 0]:
        _shade(ax, t, s["steady"], "steady stretch (averaged)")
        ax.axvline(s["stroke_start"] - s["t"][0], color="0.4", lw=0.8, ls="--")
    window = int(round(PUSH_MEAN_WINDOW / run.env.model.opt.timestep))
    normal, along = _running_mean(s["normal"], window), _running_mean(s["along"], window)
    for ax, raw, mean, colour, name in ((axes[0, 0], s["normal"], normal, "tab:blue", "normal force N = W - F_z"),
                                        (axes[1, 0], s["along"], along, "tab:red", "force along the push F·d")):
        ax.plot(*_thin(t, raw), color=colour, lw=0.5, alpha=0.35, label=f"{name}, every physics step")
        ax.plot(*_thin(t, mean, points=MEAN_POINTS), color=colour, lw=1.5,
                label=f"its mean over {1000 * PUSH_MEAN_WINDOW:.0f} ms")
        ax.set_ylabel("force (N)")
    axes[1, 0].plot(*_thin(t, run.truth * normal, points=MEAN_POINTS), color="k", lw=1.0, ls=":",
                    label="true coefficient × mean N")
    for ax, where in ((axes[0, 0], 0.0), (axes[0, 0], s["stroke_start"] - s["t"][0])):
        ax.annotate("there" if where == 0.0 else "back", (where, 1.0), xycoords=("data", "axes fraction"),
                    xytext=(3, -3), textcoords="offset points", va="top", fontsize=8, color="0.3")
    for ax in axes[:, 0]:
        ax.set_ylim(bottom=min(0.0, ax.get_ylim()[0]))
        ax.legend(loc="upper right", fontsize=7, framealpha=0.9)
    axes[1, 0].set_xlabel("simulated time (s)")
    axes[0, 0].set_title(f"push: {_name(run.spec)}, {100 * _default('PUSH_DISTANCE'):.0f} cm there and back at "
                         f"{100 * _default('PUSH_SPEED'):.0f} cm/s\nfriction read {run.result.measurement:.3f} "
                         f"(mean F·d / mean N over the steady stretches), true {run.truth:.3f}")
    _save(fig, path)


def plot_balance(run: Run, path: Path) -> None:
    """The torque components held still, and the centre of mass each sample gives against the true one."""
    s = balance_series(run)
    t = s["t"] - s["t"][0]
    fig, axes = _figure(2)
    top, bottom = axes[0, 0], axes[1, 0]
    for ax in (top, bottom):
        _shade(ax, t, s["window"], "averaged")
    for values, name, colour in zip(1000.0 * s["torque"].T, ("τ_x", "τ_y", "τ_z"),
                                    ("tab:red", "tab:green", "tab:blue")):
        top.plot(*_thin(t, values), lw=1.2, color=colour, label=name)
    top.set_ylabel("load torque (mN·m)")
    top.legend(loc="center right", fontsize=7.5, ncol=4, framealpha=0.9)
    true = 1000.0 * np.asarray(run.truth, dtype=float)[:2]
    for values, axis, colour, value in zip(1000.0 * s["offset"].T, "xy", ("tab:purple", "tab:orange"), true):
        bottom.plot(*_thin(t, values), lw=1.2, color=colour, label=f"{axis} from each sample")
        bottom.axhline(value, color=colour, lw=0.8, ls=":", label=f"{axis} true")
    bottom.set_ylabel("centre of mass\n(mm, object frame)")
    bottom.set_ylim(min(-1.0, *true) - 4.0, max(1.0, *true) + 4.0)
    bottom.legend(loc="center right", fontsize=7.5, ncol=2, framealpha=0.9)
    bottom.set_xlabel("simulated time held still (s)")
    read = run.result.measurement
    top.set_title(f"balance: {_name(run.spec)} held still, carrying W = {float(np.mean(s['weight'])):.3f} N\n"
                  f"centre of mass read [{read[0]:.2f}, {read[1]:.2f}] mm, true [{true[0]:.2f}, {true[1]:.2f}] mm")
    _save(fig, path)


def plot_shake(loose: Run, solid: Run, path: Path) -> None:
    """The wrist force along the swing and what the rigid motion leaves of it, with contents and without."""
    from muble_plugins.primitives.handling import RATTLE_FORCE

    fig, axes = _figure(2)
    top, bottom = axes[0, 0], axes[1, 0]
    for run, name, colour in ((solid, "empty", "tab:blue"),
                              (loose, f"{1000 * loose.truth:.0f} g loose inside", "tab:red")):
        s = shake_series(run)
        verdict = "rattles" if run.result.measurement else "solid"
        top.plot(*_thin(s["t"], s["along"]), lw=0.8, color=colour, label=f"{name}: {verdict}")
        bottom.plot(*_thin(s["t"], s["residual"]), lw=0.8, color=colour, label=f"{name}: peak {s['peak']:.3f} N")
    bottom.axhline(RATTLE_FORCE, color="k", ls="--", lw=0.8, label=f"threshold {RATTLE_FORCE} N")
    top.set_ylabel("wrist force along\nthe swing (N)")
    top.legend(loc="lower right", fontsize=7.5, framealpha=0.9)
    bottom.set_ylabel("force the rigid motion\nleaves unexplained (N)")
    bottom.set_xlabel("simulated time (s)")
    bottom.legend(loc="upper right", fontsize=7.5, framealpha=0.9)
    amplitude, period, cycles = (_default(n) for n in ("SHAKE_AMPLITUDE", "SHAKE_PERIOD", "SHAKE_CYCLES"))
    top.set_title(f"shake: {_name(loose.spec)}, with and without loose contents\n"
                  f"±{100 * amplitude:.0f} cm, {period} s a swing, {cycles} swings")
    _save(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=IMAGES, help="folder for the SVGs")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    args.out.mkdir(parents=True, exist_ok=True)
    plot_push(measure("push", PUSH_OBJECT, friction_coefficient=PUSH_FRICTION), args.out / "probing_push.svg")
    plot_balance(measure("balance", BALANCE_OBJECT, com_offset=np.array(BALANCE_OFFSET)),
                 args.out / "probing_balance.svg")
    plot_shake(measure("shake", SHAKE_OBJECT, contents_mass=SHAKE_CONTENTS_G / 1000.0),
               measure("shake", SHAKE_OBJECT, contents_mass=0.0), args.out / "probing_shake.svg")
    for name in ("push", "balance", "shake"):
        path = args.out / f"probing_{name}.svg"
        print(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}: {path.stat().st_size // 1024} kB")


if __name__ == "__main__":
    main()
