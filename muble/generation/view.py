"""A render model kept across scenes: every distinct visual mesh compiled once, objects posed by slots.

Compiling a MuJoCo model per layout and handing it to the renderer costs several milliseconds, and the
catalogue is small, so the generator keeps one model that holds each visual mesh it has met in a hidden
``mesh_store`` body, plus one mocap body ``obj{i}`` per object slot with a single mesh geom. A layout is drawn
by pointing slot ``i``'s geom at object ``i``'s mesh (its id, and the offset MuJoCo gave the centred mesh),
setting its colour and pose, and hiding unused slots. Only a mesh never seen before recompiles the model.

What is drawn for a layout does not depend on which meshes were met before: the slots draw the same triangles
in object order, and the depth range (``stat.extent``) is fixed from the table, not from the stored meshes.
A scene whose camera was jittered (``GeneratorConfig.camera_jitter_m``/``camera_jitter_deg``) is drawn by the
same model with its camera moved there; the next layout without one puts the compiled camera back.
"""
from __future__ import annotations

import threading
from typing import TYPE_CHECKING

import numpy as np

from muble.core.objects import ObjectModel
from muble.generation.checks import CAMERA_NAME, _table_geom_args
from muble.generation.mesh_keys import mesh_key
from muble.stage.camera import CameraParams
from muble.stage.layout import Placement

if TYPE_CHECKING:
    import mujoco

OBJECT_GROUP = 2  # drawn by the mujoco renderer (groups 1 and 2)
HIDDEN_GROUP = 5  # never drawn
PARKED = np.array([0.0, 0.0, -10.0])  # unused slots, far under the table


class ViewScene:
    """The reusable render model for one camera and table; ``pose()`` loads a layout into it."""

    def __init__(self, camera: CameraParams, table_x, table_y, slots: int, max_meshes: int = 1024):
        self.camera = camera
        self.table_x, self.table_y = tuple(table_x), tuple(table_y)
        self.slots = int(slots)
        self.max_meshes = max_meshes
        self._index: dict[bytes, int] = {}
        self._meshes: list[tuple[np.ndarray, np.ndarray]] = []
        self.model: mujoco.MjModel | None = None  # compiled at the first pose()
        self.data: mujoco.MjData | None = None
        self.version = 0  # bumped on every recompile: a renderer must be set up again
        self._extent = self._table_extent()

    def _spec(self):
        import mujoco

        spec = mujoco.MjSpec()
        spec.visual.global_.offwidth = int(self.camera.width)
        spec.visual.global_.offheight = int(self.camera.height)
        # Labels are drawn with multisampling off anyway, so a multisampled buffer only costs fill time (5x here).
        spec.visual.quality.offsamples = 0
        spec.worldbody.add_light(pos=[0.4, 0.0, 3.0], dir=[0.0, 0.0, -1.0])
        spec.worldbody.add_geom(**_table_geom_args(self.table_x, self.table_y))
        spec.worldbody.add_camera(name=CAMERA_NAME, pos=self.camera.position.tolist(),
                                  quat=self.camera.mujoco_quat.tolist(), fovy=self.camera.fovy_deg)
        return spec

    def _table_extent(self) -> float:
        return float(self._spec().compile().stat.extent)

    def _compile(self) -> None:
        import mujoco

        spec = self._spec()
        store = spec.worldbody.add_body(name="mesh_store")
        for j, (verts, faces) in enumerate(self._meshes):
            spec.add_mesh(name=f"stored_mesh_{j}", uservert=verts.ravel().tolist(), userface=faces.ravel().tolist())
            store.add_geom(name=f"stored_{j}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"stored_mesh_{j}",
                           contype=0, conaffinity=0, density=0, group=HIDDEN_GROUP)
        for i in range(self.slots):
            body = spec.worldbody.add_body(name=f"obj{i}", mocap=True, pos=PARKED.tolist())
            body.add_geom(name=f"obj{i}_visual", type=mujoco.mjtGeom.mjGEOM_MESH, meshname="stored_mesh_0",
                          contype=0, conaffinity=0, density=0, group=HIDDEN_GROUP)
        model = spec.compile()
        model.stat.extent = self._extent  # near/far planes from the table alone, whatever the store holds
        self._store_geom = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"stored_{j}")
                                     for j in range(len(self._meshes))])
        self._slot_geom = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"obj{i}_visual")
                                    for i in range(self.slots)])
        self._slot_mocap = np.array([model.body_mocapid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"obj{i}")]
                                     for i in range(self.slots)])
        model.geom_sameframe[self._slot_geom] = 0  # the geom offset changes with the mesh it draws
        self._camera_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA_NAME)
        self._compiled_camera = (model.cam_pos[self._camera_id].copy(), model.cam_quat[self._camera_id].copy())
        self.model = model
        self.data = mujoco.MjData(model)
        self.version += 1

    def _mesh_ids(self, models: list[ObjectModel]) -> list[int]:
        keys = [mesh_key(m) for m in models]
        missing = [(k, m) for k, m in zip(keys, models) if k not in self._index]
        if missing or self.model is None:
            if len(self._index) + len(missing) > self.max_meshes:
                self._index.clear()
                self._meshes.clear()
                missing = list({k: (k, m) for k, m in zip(keys, models)}.values())
            for k, m in missing:
                if k not in self._index:
                    self._index[k] = len(self._meshes)
                    self._meshes.append((np.asarray(m.visual.vertices, np.float64),
                                         np.asarray(m.visual.faces, np.int32)))
            self._compile()
        return [self._index[k] for k in keys]

    def _compiled(self) -> tuple[mujoco.MjModel, mujoco.MjData]:
        """The compiled (model, data); ``_mesh_ids`` compiles them before any layout is loaded."""
        if self.model is None or self.data is None:
            raise RuntimeError("the view has no compiled model: pose() compiles it before loading a layout")
        return self.model, self.data

    def _aim(self, camera: CameraParams | None) -> None:
        """Point the model's camera where ``camera`` stands, or (``None``) where it was compiled."""
        (m, _), cam = self._compiled(), self._camera_id
        if camera is None:
            m.cam_pos[cam], m.cam_quat[cam] = self._compiled_camera
            return
        if not np.isclose(camera.fovy_deg, self.camera.fovy_deg):
            raise ValueError(f"the view was made for a {self.camera.fovy_deg:.3f} degree field of view, not "
                             f"{camera.fovy_deg:.3f}: only the camera's pose can change")
        quat = camera.mujoco_quat
        m.cam_pos[cam] = camera.position
        m.cam_quat[cam] = quat / np.linalg.norm(quat)

    def pose(self, models: list[ObjectModel], placements: list[Placement], camera: CameraParams | None = None):
        """Load a layout (at most ``slots`` objects), seen from ``camera``'s pose (``None``: the view's own
        camera); returns the (model, data) to render."""
        import mujoco

        if len(models) > self.slots:
            raise ValueError(f"{len(models)} objects but the view has {self.slots} slots")
        ids = self._mesh_ids(models)
        self._aim(camera)
        m, d = self._compiled()
        n = len(models)
        slot_geom, store_geom = self._slot_geom, self._store_geom[ids]
        m.geom_dataid[slot_geom[:n]] = m.geom_dataid[store_geom]
        for field in ("geom_pos", "geom_quat", "geom_size", "geom_rbound", "geom_aabb"):
            getattr(m, field)[slot_geom[:n]] = getattr(m, field)[store_geom]
        m.geom_rgba[slot_geom[:n]] = np.array([model.rgba for model in models], float)
        m.geom_group[slot_geom[:n]] = OBJECT_GROUP
        m.geom_group[slot_geom[n:]] = HIDDEN_GROUP
        mocap = self._slot_mocap
        d.mocap_pos[mocap[:n]] = np.array([p.position for p in placements])
        d.mocap_quat[mocap[:n]] = np.array([p.quat for p in placements])
        d.mocap_pos[mocap[n:]] = PARKED
        d.mocap_quat[mocap[n:]] = (1.0, 0.0, 0.0, 0.0)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        return m, d


_SHARED = threading.local()


def shared_view(camera: CameraParams, table_x, table_y, slots: int) -> ViewScene:
    """The ``ViewScene`` for this camera, table and slot count, shared by the generators of this thread.

    Generators that share a renderer then also share its model, so neither sets the renderer up again, and a
    second generator starts with the meshes the first has met. Views are per thread: a MuJoCo model re-posed
    from two threads at once would mix layouts.
    """
    views = _SHARED.__dict__.setdefault("views", {})
    key = (np.asarray(camera.position, float).tobytes(), np.asarray(camera.rotation, float).tobytes(),
           camera.width, camera.height, float(camera.fovy_deg), tuple(table_x), tuple(table_y), int(slots))
    view = views.get(key)
    if view is None:
        view = views[key] = ViewScene(camera, table_x, table_y, slots)
    return view
