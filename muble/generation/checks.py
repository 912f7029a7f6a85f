"""The two physical checks of a layout: what the task camera sees, and whether the objects rest.

Both build MuJoCo models from the object models: a light one (visual meshes, table, camera) for the renderer,
and a full one (convex collision parts, exact masses, contact stiffness from ``muble.sim.object_mjcf``) that is
stepped for ``settle_time`` seconds.
"""
from __future__ import annotations

import numpy as np

from muble.core.objects import ObjectModel
from muble.stage.camera import CameraParams
from muble.stage.layout import Placement

CAMERA_NAME = "front"
TABLE_THICKNESS = 0.05


def _table_geom_args(table_x, table_y) -> dict:
    import mujoco

    hx, hy = (table_x[1] - table_x[0]) / 2.0, (table_y[1] - table_y[0]) / 2.0
    centre = [(table_x[0] + table_x[1]) / 2.0, (table_y[0] + table_y[1]) / 2.0, -TABLE_THICKNESS / 2.0]
    return dict(name="table", type=mujoco.mjtGeom.mjGEOM_BOX, size=[hx, hy, TABLE_THICKNESS / 2.0], pos=centre,
                rgba=[0.6, 0.5, 0.4, 1.0], group=1)  # drawn with the visual groups (1: scenery, 2: objects)


def view_model(models: list[ObjectModel], placements: list[Placement], camera: CameraParams, table_x, table_y):
    """A render-only MuJoCo model: the table top at z = 0, object ``i`` as body ``obj{i}``, camera ``front``."""
    import mujoco

    spec = mujoco.MjSpec()
    spec.visual.global_.offwidth = int(camera.width)
    spec.visual.global_.offheight = int(camera.height)
    spec.worldbody.add_light(pos=[0.4, 0.0, 3.0], dir=[0.0, 0.0, -1.0])
    spec.worldbody.add_geom(**_table_geom_args(table_x, table_y))
    for i, (model, placement) in enumerate(zip(models, placements)):
        spec.add_mesh(name=f"obj{i}_visual_mesh", uservert=np.asarray(model.visual.vertices, float).ravel().tolist(),
                      userface=np.asarray(model.visual.faces, np.int32).ravel().tolist())
        body = spec.worldbody.add_body(name=f"obj{i}", pos=placement.position.tolist(), quat=placement.quat.tolist())
        body.add_geom(name=f"obj{i}_visual", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"obj{i}_visual_mesh",
                      contype=0, conaffinity=0, density=0, rgba=list(model.rgba), group=2)
    spec.worldbody.add_camera(name=CAMERA_NAME, pos=camera.position.tolist(), quat=camera.mujoco_quat.tolist(),
                              fovy=camera.fovy_deg)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def visible_pixels(segmentation: np.ndarray, n_objects: int) -> np.ndarray:
    """Pixels per object id 0 … n-1."""
    labels = segmentation[segmentation >= 0]
    return np.bincount(labels, minlength=n_objects)[:n_objects]


def physics_world_xml(models: list[ObjectModel], placements: list[Placement], table_x, table_y,
                      timestep: float) -> str:
    """The objects (``muble.sim.object_mjcf``) on a table box, with robosuite's contact options."""
    from muble.sim.object_mjcf import object_mjcf

    assets, bodies = [], []
    for i, (model, placement) in enumerate(zip(models, placements)):
        mjcf = object_mjcf(model, i, placement.position, placement.quat)
        assets.append(mjcf.asset_xml)
        bodies.append(mjcf.body_xml)
    t = _table_geom_args(table_x, table_y)
    return (
        '<mujoco model="settling">'
        f'<option timestep="{timestep}" impratio="20" cone="elliptic"/>'
        f'<asset>{"".join(assets)}</asset><worldbody>'
        f'<geom name="table" type="box" size="{" ".join(map(str, t["size"]))}" '
        f'pos="{" ".join(map(str, t["pos"]))}" friction="1 0.005 0.0001"/>'
        f'{"".join(bodies)}</worldbody></mujoco>'
    )


def settle(models: list[ObjectModel], placements: list[Placement], table_x, table_y, timestep: float,
           settle_time: float) -> np.ndarray:
    """How far (m) each object's base centre and centre of mass moved in ``settle_time`` seconds of physics."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(physics_world_xml(models, placements, table_x, table_y, timestep))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bodies = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"obj{i}") for i in range(len(models))]
    origin0, com0 = data.xpos[bodies].copy(), data.xipos[bodies].copy()
    mujoco.mj_step(model, data, nstep=max(1, int(round(settle_time / timestep))))
    if not np.all(np.isfinite(data.qpos)):
        return np.full(len(models), np.inf)
    moved = np.maximum(np.linalg.norm(data.xpos[bodies] - origin0, axis=1),
                       np.linalg.norm(data.xipos[bodies] - com0, axis=1))
    return moved


# A stack the ground truth builds must stand: the upper object, let go centred over its base as ``lower`` lets it
# go, comes to rest in contact with the base, leaning at most ``muble.stage.rest.STACK_LEAN_DEG`` further.
STACK_DROP = 0.003  # m between the upper object's bottom and the base under it when let go
STACK_SETTLE = 1.0  # s of physics after each put-down
# The way down: the upper object, lowered straight onto its release pose from this far above (m), keeps at least
# STACK_CLEARANCE (m) from every object but those of its stack (``lower`` descends straight onto its target).
STACK_SWEEP = 0.2
STACK_CLEARANCE = 0.005


def stacks_stand(models: list[ObjectModel], placements: list[Placement], pairs: list[tuple[int, int]], table_x,
                 table_y, timestep: float, settle_time: float = STACK_SETTLE) -> str | None:
    """``None`` when every (top, base) pair of ``pairs`` (bottom pair first, as a stack is built) stands: the top
    object, set down centred over its base from ``STACK_DROP`` above the highest point of the base under its
    footprint, comes to rest touching the base and leaning at most ``STACK_LEAN_DEG`` (``muble.stage.rest``) further
    than when it was let go, and
    every object stacked before it still does; and on its way down onto that pose (``STACK_SWEEP`` straight down)
    it keeps ``STACK_CLEARANCE`` from every object outside its stack. Else why not (the first pair that fails).

    The objects start as placed on the table; each top object keeps its turn about the vertical, and its loose
    contents (``ObjectModel.contents_mass``) go with it. A bowl too small for a mug's base, a can on a bowl's
    sloping wall, a glass on a tray's rim: the physics of the built models says, not the objects' categories.
    """
    import mujoco

    from muble.stage.rest import STACK_LEAN_DEG, leaned_over, resting_height

    model = mujoco.MjModel.from_xml_string(physics_world_xml(models, placements, table_x, table_y, timestep))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bodies = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"obj{i}") for i in range(len(models))]
    # Each object's free bodies: its own and, in a closed container, its loose contents' (``muble.sim.object_mjcf``).
    parts = [[b, *[c for c in [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"obj{i}_contents")] if c >= 0]]
             for i, b in enumerate(bodies)]
    steps = max(1, int(round(settle_time / timestep)))

    def place(i: int, origin) -> None:
        """Object ``i`` moved, unturned and at rest, so that its origin is at ``origin``; its contents go along."""
        shift = None
        for b in parts[i]:
            q, v = model.jnt_qposadr[model.body_jntadr[b]], model.jnt_dofadr[model.body_jntadr[b]]
            if shift is None:  # the object's own body: exactly at ``origin``
                shift = np.asarray(origin, float) - data.qpos[q:q + 3]
                data.qpos[q:q + 3] = origin
            else:
                data.qpos[q:q + 3] += shift
            data.qvel[v:v + 6] = 0.0
        mujoco.mj_forward(model, data)

    placed: list[tuple[int, int, np.ndarray]] = []  # (top, base, the top's orientation when let go)
    for top, base in pairs:
        tb, bb = bodies[top], bodies[base]
        rot = data.xmat[tb].reshape(3, 3)
        verts = np.vstack([np.asarray(p.vertices, float) for p in models[top].collision_parts]) @ rot.T
        depth = -float(verts[:, 2].min())  # the top's bottom below its origin
        shape = verts[:, :2]
        centre = data.xpos[bb][:2]
        points = np.vstack([np.zeros((1, 2)), shape, 0.5 * shape]) + centre
        start_z = float(data.xpos[bb][2]) + float(np.ptp(np.vstack(
            [np.asarray(p.vertices, float) for p in models[base].collision_parts])[:, 2])) * 2 + 0.05
        height = resting_height(model, data, bb, points, start_z, tb)
        if height is None:
            return f"object {top} has nothing of object {base} under it when centred over it"
        release = height + depth + STACK_DROP
        stack = {p for _, b, _ in placed for p in parts[b]} | set(parts[base]) | set(parts[top])
        blocked = _in_the_way(model, data, lambda origin, top=top: place(top, origin), tb, stack,
                              [centre[0], centre[1], release])
        if blocked is not None:
            return (f"object {top} set down on object {base} comes within {STACK_CLEARANCE * 1000:.0f} mm of object "
                    f"{next(i for i, p in enumerate(parts) if blocked in p)} on the way")
        place(top, [centre[0], centre[1], release])
        placed.append((top, base, data.xquat[tb].copy()))
        mujoco.mj_step(model, data, nstep=steps)
        if not np.all(np.isfinite(data.qpos)):
            return f"object {top} on object {base}: the physics diverged"
        for t, b, quat in placed:
            lean = leaned_over(data.xquat[bodies[t]], quat, STACK_LEAN_DEG)
            if lean is not None:
                return f"object {t} on object {b} comes to rest leaning {lean:.0f} degrees"
            if not _touching(model, data, bodies[t], bodies[b]):
                return f"object {t} does not stay on object {b}"
    return None


def _in_the_way(model, data, place, body: int, allowed: set[int], release) -> int | None:
    """The first body other than ``allowed`` that ``body``, lowered straight down onto ``release`` (its origin, where
    ``place(origin)`` puts it) from ``STACK_SWEEP`` above, comes within ``STACK_CLEARANCE`` of; ``None`` when the
    way is clear. The body's pose is left at the last height tried."""

    geoms = np.flatnonzero(model.geom_bodyid == body)
    margins = model.geom_margin[geoms].copy()
    model.geom_margin[geoms] = STACK_CLEARANCE
    try:
        for dz in np.linspace(STACK_SWEEP, 0.0, int(round(STACK_SWEEP / 0.02)) + 1):
            place([release[0], release[1], release[2] + dz])
            for k in range(data.ncon):
                c = data.contact[k]
                pair = (int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2]))
                if body in pair and c.dist < STACK_CLEARANCE:
                    other = pair[1] if pair[0] == body else pair[0]
                    if other not in allowed and model.body_jntnum[other] > 0:  # an object, not the table
                        return other
        return None
    finally:
        model.geom_margin[geoms] = margins


def _touching(model, data, a: int, b: int) -> bool:
    for k in range(data.ncon):
        c = data.contact[k]
        pair = {int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])}
        if pair == {a, b}:
            return True
    return False
