"""The Blender renderer: builds a scene once from the MuJoCo model, then renders keyframes with GT passes."""
from __future__ import annotations

import logging
import os
import shutil
import tempfile
import time
import weakref
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from muble.core import streams
from muble.core.errors import RenderError, unknown_name
from muble.core.interfaces import Renderer
from muble.core.ranges import configured
from muble.core.types import SEG_BACKGROUND, SEG_TABLE, Frame

from .config import BlenderRendererConfig
from .console import blender_console_silenced
from .exr import read_exr
from .geometry import geom_mesh, geom_rgba
from .labels import drawn_geoms, geom_labels, labels_from_pass, pass_index
from .materials import MaterialLibrary, material_class
from .stage import build_lights, build_scene_lamps, build_world, check_config, configure_engine, set_passes

if TYPE_CHECKING:  # pragma: no cover
    import mujoco

    from muble.core.scene import SceneGraph

log = logging.getLogger(__name__)

TABLE_RINGS = 120.0  # growth rings per metre across the table's grain
# The light rig's jitter of a scene without lamps of its own, seeded as before named streams (legacy_stream): the
# material classes' measured looks (tests/render_blender) and the reference sheet were drawn under these lights.
LIGHT_RIG_STREAM = streams.declare_legacy("render.blender_light_rig", "the jitter of the Blender renderer's key, "
                                          "fill and back lights for a scene without lamps of its own (renderer "
                                          "seed, image index)")
# The table is drawn this much lower than it stands. An object resting on it has its base in the table's top
# face, and rays leaving a glass base there skip or double-hit the coplanar faces: a dark pool under every glass.
# A quarter of a pixel at the SHOP-VRB2 camera's distance parts them.
TABLE_DRAWN_LOWER = 0.0005  # metres
SHARP_EDGE_ANGLE = np.radians(35.0)  # edges sharper than this stay crisp under smooth shading
BACKGROUND_DEPTH = 1e9
# Pass names in the EXR: Blender 5 writes the long names, older releases the short ones.
PASS_NAMES = {"Combined": ("Combined",), "Depth": ("Depth",), "IndexOB": ("Object Index", "IndexOB"),
              "Normal": ("Normal",)}  # Cycles' depth of rays that hit nothing is ~1e10


def _linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    linear = np.clip(linear, 0.0, 1.0)
    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)
    return np.round(srgb * 255.0).astype(np.uint8)


def _pass_dir() -> Path:
    shm = Path("/dev/shm")
    base = shm if shm.is_dir() and os.access(shm, os.W_OK) else Path(tempfile.gettempdir())
    return Path(tempfile.mkdtemp(prefix="muble_blender_", dir=base))


class BlenderRenderer(Renderer):
    """Photoreal keyframes with Blender in-process; RGB, depth and segmentation from one render.

    Built from a ``BlenderRendererConfig`` and/or keyword overrides of its fields (``BlenderRenderer(width=160,
    samples=4)``), checked against the schema's types and bounds.

    Blender's data is process-global: one ``BlenderRenderer`` owns its own Blender scene, and ``setup``
    replaces whatever the previous ``setup`` built (orphan data is purged, so memory stays flat).
    """

    def __init__(self, config: BlenderRendererConfig | None = None, **options: Any) -> None:
        self.config = configured(BlenderRendererConfig, config, options, owner="renderer 'blender'")
        check_config(self.config)
        self._bscene: Any | None = None  # the Blender scene (bpy ships no types); None until the first setup
        self._geoms: np.ndarray = np.empty(0, dtype=int)
        self._objects: list[Any] = []  # Blender objects, parallel to self._geoms
        self._table_geoms: np.ndarray = np.empty(0, dtype=bool)  # which of self._geoms are the table's
        self._model: "mujoco.MjModel | None" = None
        self._set_up_with: tuple | None = None  # (scene graph, model) of the last setup
        self._pass_dir: Path | None = None
        self._materials = MaterialLibrary()
        self.last_build_s = 0.0
        self.last_render_s = 0.0

    # -- scene building -------------------------------------------------------------------------------

    def setup(self, scene: "SceneGraph", model: "mujoco.MjModel") -> None:
        if self._set_up_with is not None and self._set_up_with[0] is scene and self._set_up_with[1] is model:
            return  # already built for these: rendering only moves transforms
        import bpy

        start = time.perf_counter()
        self._clear()
        cfg = self.config
        if self._bscene is None:
            self._bscene = bpy.data.scenes.new("muble")
            self._pass_dir = _pass_dir()
            # Remove the pass folder even when close() is never called.
            weakref.finalize(self, shutil.rmtree, str(self._pass_dir), True)
        bscene = self._bscene
        with blender_console_silenced():  # Cycles probes GPU libraries and reports each missing one
            configure_engine(bscene, cfg)
        set_passes(bscene.view_layers[0], cfg.depth, cfg.segmentation, cfg.normals)
        bscene.world = build_world(cfg)
        self._model = model
        labels = geom_labels(model, scene)
        self._geoms = drawn_geoms(model, labels, cfg.geom_groups, world=cfg.floor, walls=cfg.walls)
        self._table_geoms = np.asarray(labels)[self._geoms] == SEG_TABLE
        classes = self._object_classes(scene)
        meshes: dict[tuple, Any] = {}
        collection = bscene.collection
        for geom in self._geoms:
            label = int(labels[geom])
            key = self._mesh_key(model, int(geom))
            if key not in meshes:
                meshes[key] = self._new_mesh(model, int(geom), f"muble_mesh_{len(meshes)}")
            if label >= 0:
                cls = classes.get(label, "plastic")
            elif label == SEG_TABLE:
                cls = cfg.table_material
            else:
                cls = "painted"
            obj = bpy.data.objects.new(f"muble_geom_{geom}", meshes[key])
            obj.material_slots[0].link = "OBJECT"  # meshes are shared, colours are per geom
            rgba: np.ndarray | tuple[float, ...] = geom_rgba(model, int(geom))
            details: dict[str, float] = {}
            if label == SEG_TABLE:
                if cfg.table_rgb is not None:
                    rgba = (*cfg.table_rgb, 1.0)
                if cls == "wood":  # a desk's boards: straight grain along the table, rings about 1 cm apart
                    details["rings"] = TABLE_RINGS
            linear = label >= 0 and cfg.object_colours == "linear"
            obj.material_slots[0].material = self._materials.get(cls, rgba, linear=linear, **details)
            obj.pass_index = pass_index(label)
            # The world's floor and walls are backdrop: they cast no shadows, so lamps placed outside the
            # room (the scene files' lamps are) still light the table and robot directly.
            obj.visible_shadow = label != SEG_BACKGROUND
            collection.objects.link(obj)
            self._objects.append(obj)
        centre, radius = self._stage_extent(model, labels)
        lamps = getattr(scene, "lamp_params", None)
        if lamps:
            build_scene_lamps(collection, lamps, centre, cfg, scene.extra.get("lamp_energy"))
        else:
            build_lights(collection, centre, radius, cfg, streams.legacy_stream(LIGHT_RIG_STREAM, cfg.seed,
                                                                                int(scene.image_index)))
        camera_data = bpy.data.cameras.new("muble_camera")
        camera_data.sensor_fit = "VERTICAL"
        camera_data.clip_start, camera_data.clip_end = 0.01, 100.0
        camera = bpy.data.objects.new("muble_camera", camera_data)
        collection.objects.link(camera)
        bscene.camera = camera
        self.last_build_s = time.perf_counter() - start
        log.info("Blender scene built: %d geoms, %d meshes in %.2f s", len(self._geoms), len(meshes),
                 self.last_build_s)
        self._set_up_with = (scene, model)

    def _stage_extent(self, model: "mujoco.MjModel", labels: np.ndarray) -> tuple[np.ndarray, float]:
        """Centre and radius of what matters (robot, table, objects) at the model's initial state; the
        floor and walls would make the light rig far too large."""
        import mujoco

        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        mask = labels[self._geoms] != SEG_BACKGROUND
        geoms = self._geoms[mask] if mask.any() else self._geoms
        if len(geoms) == 0:
            return np.zeros(3), 1.0
        points = np.asarray(data.geom_xpos)[geoms]
        reach = np.asarray(model.geom_rbound)[geoms]
        low, high = (points - reach[:, None]).min(axis=0), (points + reach[:, None]).max(axis=0)
        return (low + high) / 2, max(float(np.linalg.norm(high - low)) / 2, 0.25)

    @staticmethod
    def _object_classes(scene: "SceneGraph") -> dict[int, str]:
        return {obj.id: material_class(obj.material) for obj in scene.objects}

    @staticmethod
    def _mesh_key(model: "mujoco.MjModel", geom: int) -> tuple:
        kind = int(model.geom_type[geom])
        if kind == 7:  # mesh geoms share their asset
            return (kind, int(model.geom_dataid[geom]))
        return (kind, *np.round(model.geom_size[geom], 6))

    @staticmethod
    def _new_mesh(model: "mujoco.MjModel", geom: int, name: str) -> Any:
        import bpy

        part = geom_mesh(model, geom)
        faces = np.asarray(part.faces, dtype=np.int32)
        mesh = bpy.data.meshes.new(name)
        mesh.vertices.add(len(part.vertices))
        mesh.vertices.foreach_set("co", np.asarray(part.vertices, dtype=np.float32).ravel())
        mesh.loops.add(faces.size)
        mesh.loops.foreach_set("vertex_index", faces.ravel())
        mesh.polygons.add(len(faces))
        mesh.polygons.foreach_set("loop_start", np.arange(0, faces.size, 3, dtype=np.int32))
        mesh.polygons.foreach_set("loop_total", np.full(len(faces), 3, dtype=np.int32))
        mesh.update()
        mesh.shade_smooth()
        mesh.set_sharp_from_angle(angle=float(SHARP_EDGE_ANGLE))
        mesh.materials.append(None)  # one slot, filled per object: geoms share meshes but not colours
        return mesh

    def configure_passes(self, depth: bool, segmentation: bool, normals: bool = False) -> None:
        """Choose the ground-truth passes of the next renders (RGB is always rendered)."""
        self.config.depth, self.config.segmentation, self.config.normals = depth, segmentation, normals
        if self._bscene is not None:
            set_passes(self._bscene.view_layers[0], depth, segmentation, normals)

    # -- keyframes --------------------------------------------------------------------------------------

    def _camera_id(self, camera: str) -> int:
        import mujoco

        model = self._model
        if model is None:
            raise RenderError("render() called before setup(); call setup(scene, model) once per scene")
        cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if cam < 0:
            names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(model.ncam)]
            raise RenderError(unknown_name("camera", camera, names))
        return cam

    def sync(self, data: "mujoco.MjData", camera: str) -> None:
        """Move every geom and the camera to the state in ``data`` (MuJoCo world frame = Blender world frame)."""
        from mathutils import Matrix

        model = self._model
        if model is None or self._bscene is None:
            raise RenderError("render() called before setup(); call setup(scene, model) once per scene")
        cam = self._camera_id(camera)
        xpos = np.asarray(data.geom_xpos)
        xmat = np.asarray(data.geom_xmat).reshape(-1, 3, 3)
        world = np.zeros((len(self._geoms), 4, 4))
        world[:, :3, :3] = xmat[self._geoms]
        world[:, :3, 3] = xpos[self._geoms]
        world[:, 3, 3] = 1.0
        world[self._table_geoms, 2, 3] -= TABLE_DRAWN_LOWER
        for obj, matrix in zip(self._objects, world):
            obj.matrix_world = Matrix(matrix.tolist())
        pose = np.eye(4)
        pose[:3, :3] = np.asarray(data.cam_xmat[cam]).reshape(3, 3)
        pose[:3, 3] = data.cam_xpos[cam]
        camera_obj = self._bscene.camera
        camera_obj.matrix_world = Matrix(pose.tolist())  # both look along -z with +y up
        camera_obj.data.angle_y = float(np.radians(model.cam_fovy[cam]))

    def render(self, data: "mujoco.MjData", camera: str) -> Frame:
        import bpy

        start = time.perf_counter()
        self.sync(data, camera)
        if self._pass_dir is None or self._bscene is None:  # set in setup, which sync has checked
            raise RenderError("render() called before setup(); call setup(scene, model) once per scene")
        path = self._pass_dir / "passes.exr"
        self._bscene.render.filepath = str(path)
        with blender_console_silenced():
            result = bpy.ops.render.render(write_still=True, scene=self._bscene.name)
        if "FINISHED" not in result or not path.exists():
            raise RenderError(f"Blender did not write the render passes to {path} (operator returned {result})")
        frame = self._frame_from_passes(read_exr(path), camera)
        self.last_render_s = time.perf_counter() - start
        return frame

    def _frame_from_passes(self, channels: dict[str, np.ndarray], camera: str) -> Frame:
        def channel(pass_name: str, component: str) -> np.ndarray:
            for name, values in channels.items():
                parts = name.split(".")
                if len(parts) >= 2 and parts[-2] in PASS_NAMES[pass_name] and parts[-1] == component:
                    return values
            raise RenderError(f"render pass {pass_name}.{component} missing; passes written: {sorted(channels)}")

        rgb = np.stack([channel("Combined", c) for c in "RGB"], axis=-1) * 2.0 ** self.config.exposure
        frame = Frame(camera=camera, rgb=_linear_to_srgb(rgb))
        if self.config.depth:
            depth = channel("Depth", "Z").astype(np.float32)
            depth[depth >= BACKGROUND_DEPTH] = np.inf
            frame.depth = depth
        if self.config.segmentation:
            frame.segmentation = labels_from_pass(channel("IndexOB", "X"))
        if self.config.normals:
            frame.normals = np.stack([channel("Normal", c) for c in "XYZ"], axis=-1).astype(np.float32)
        return frame

    # -- memory -----------------------------------------------------------------------------------------

    def _clear(self) -> None:
        """Remove everything the last ``setup`` built and purge orphan data blocks."""
        import bpy

        self._set_up_with = None
        if self._bscene is None:
            return
        for obj in list(self._bscene.collection.objects):
            data = obj.data
            bpy.data.objects.remove(obj, do_unlink=True)
            if data is not None and data.users == 0:
                if isinstance(data, bpy.types.Mesh):
                    bpy.data.meshes.remove(data)
                elif isinstance(data, bpy.types.Light):
                    bpy.data.lights.remove(data)
                elif isinstance(data, bpy.types.Camera):
                    bpy.data.cameras.remove(data)
        self._materials.clear()
        if self._bscene.world is not None:
            world, self._bscene.world = self._bscene.world, None
            bpy.data.worlds.remove(world)
        for mesh in [m for m in bpy.data.meshes if m.users == 0]:
            bpy.data.meshes.remove(mesh)
        bpy.data.orphans_purge(do_local_ids=True, do_linked_ids=True, do_recursive=True)
        for image in [i for i in bpy.data.images if i.users == 0]:
            bpy.data.images.remove(image)
        self._objects, self._geoms, self._model = [], np.empty(0, dtype=int), None

    def close(self) -> None:
        import bpy

        self._clear()
        if self._bscene is not None:
            bpy.data.scenes.remove(self._bscene)
            self._bscene = None
        if self._pass_dir is not None:
            shutil.rmtree(self._pass_dir, ignore_errors=True)
            self._pass_dir = None
