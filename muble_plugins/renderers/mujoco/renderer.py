"""The MuJoCo renderer plugin: RGB, metric depth and label segmentation from any camera, headless."""
from __future__ import annotations

import logging
from contextlib import nullcontext
from dataclasses import dataclass
from typing import Any

import numpy as np

from muble import Frame, RenderError, Renderer, SceneGraph, bounded
from muble.core.errors import unknown_name
from muble.core.ranges import configured
from muble.stage.camera import DEFAULT_HEIGHT, DEFAULT_WIDTH

from muble_plugins.renderers.mujoco.atlas import ContextContents, MeshAtlas, atlas_compatible
from muble_plugins.renderers.mujoco.labels import geom_labels
from muble_plugins.renderers.mujoco.simplify import SimplifiedMeshes

log = logging.getLogger(__name__)

DEFAULT_SHADOW_SIZE = 1024


@dataclass
class MujocoRendererConfig:
    """Image size and which outputs to draw (RGB is one pass; segmentation and depth share a second one)."""

    width: int = bounded(DEFAULT_WIDTH, ge=1)  # the SHOP-VRB2 camera's image
    height: int = bounded(DEFAULT_HEIGHT, ge=1)
    rgb: bool = True
    depth: bool = True
    segmentation: bool = True
    reuse_meshes: bool = True  # draw untextured models from a shared mesh atlas (no re-upload per scene)
    # Geom groups drawn: robosuite puts visual meshes in group 1 and collision shapes in group 0; object sets put
    # visual meshes in group 2 and convex collision parts in group 3. Sites are never drawn.
    geom_groups: list[int] = bounded(default_factory=lambda: [1, 2], ge=0, le=5, each=True, hint="MuJoCo geom groups")
    # Shadows of the model's shadow-casting lights (robosuite's world has three), each drawn from a square depth
    # map of ``shadow_size`` texels (None: the model's ``visual/quality/shadowsize``, MuJoCo's default 4096).
    # They are most of an RGB frame's cost on a software rasteriser; turning them off or shrinking the maps
    # changes the RGB image (depth and segmentation never carry shadows): benchmarks/keyframe_breakdown.py.
    # 1024: a quarter of the 4096² maps' cost for 0.07 % of a keyframe's pixels, along shadow edges.
    shadows: bool = True
    shadow_size: int | None = bounded(DEFAULT_SHADOW_SIZE, ge=64, le=16384, hint="texels, or null for the model's own")
    # The floor's reflection (robosuite's floor reflects 1 %): drawing it draws the scene a second time.
    reflection: bool = True
    # Where the segmentation/depth pass (drawn first) shows no pixel of a reflecting plane or box (robosuite's stage
    # hides its floor behind the table), the RGB pass is drawn without the reflection: the same pixels for a third
    # less. True draws it whether seen or not (only geometry below the floor could show it unseen).
    reflection_when_hidden: bool = False
    # Multisampling of the RGB pass (None: the model's ``visual/quality/offsamples``, robosuite's 4); 0 turns it off.
    multisamples: int | None = bounded(None, ge=0, le=16, hint="or null for the model's own")
    # Visual meshes of at least a thousand triangles drawn from decimated copies whose surface stays within this
    # many metres of every modelled vertex (None: as modelled); for small images, whose pixels are larger than the
    # tolerance (muble_plugins/renderers/mujoco/simplify.py).
    mesh_tolerance: float | None = bounded(None, gt=0, le=0.05, hint="m, or null for meshes as modelled")


class MujocoRenderer(Renderer):
    """Draws MuJoCo states with MuJoCo's own OpenGL renderer (EGL, else OSMesa).

    Built from a ``MujocoRendererConfig`` (the registry's checked instance) and/or keyword overrides of its fields
    (``MujocoRenderer(width=320, height=240)``), checked against the schema's types and bounds.
    """

    def __init__(self, config: MujocoRendererConfig | None = None, **options: Any):
        self.config = cfg = configured(MujocoRendererConfig, config, options, owner="renderer 'mujoco'")
        if not (cfg.rgb or cfg.depth or cfg.segmentation):
            raise RenderError("nothing to draw: enable at least one of rgb, depth, segmentation")
        self._simplified = None if cfg.mesh_tolerance is None else SimplifiedMeshes(cfg.mesh_tolerance)
        self._gl = None
        self._context = None  # MjrContext
        self._context_model = None  # the model the context was made from, or whose meshes it was refilled with
        self._contents = ContextContents()  # what the context holds from that model, to refill it with another's
        self._atlas = MeshAtlas()
        self._model = None
        self._scene = None  # MjvScene
        self._set_up_with: tuple | None = None  # (scene graph, model) of the last setup
        self._option = None
        self._mesh_remap: np.ndarray | None = None
        self._labels: np.ndarray | None = None

    @property
    def model(self):
        """The MuJoCo model of the last ``setup`` (``None`` before): callers that re-pose one model skip setup."""
        return self._model

    # --- setup ------------------------------------------------------------------------------------------------
    def setup(self, scene: SceneGraph | None, model) -> None:
        if self._set_up_with is not None and self._set_up_with[0] is scene and self._set_up_with[1] is model:
            return  # already set up for these: only the state in ``render``'s data changes
        import mujoco

        from muble_plugins.renderers.mujoco.gl import make_context

        w, h = self.config.width, self.config.height
        if self._gl is None:
            self._gl = make_context(w, h)
        self._gl.make_current()
        self._model = model
        self._labels = geom_labels(model)
        if scene is not None:
            unknown = sorted(set(int(v) for v in self._labels if v >= 0) - set(scene.ids))
            if unknown:
                log.warning("model has object bodies %s that the scene graph does not list", unknown)
        remap = None
        if self.config.reuse_meshes and atlas_compatible(model):
            remap = self._atlas.remap(model)
            if remap is None:
                remap = self._atlas.extend(model, w, h)
                if remap is not None:
                    self._make_context(self._atlas.model)
            elif self._context_model is not self._atlas.model:
                self._make_context(self._atlas.model)
        if remap is None:
            self._context_for(model)
        self._mesh_remap = remap
        self._scene = mujoco.MjvScene(model, maxgeom=max(1000, 2 * model.ngeom + 100))
        self._option = mujoco.MjvOption()
        self._option.geomgroup[:] = 0
        self._option.geomgroup[self.config.geom_groups] = 1
        self._option.sitegroup[:] = 0
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = int(self.config.shadows)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = int(self.config.reflection)
        self._set_up_with = (scene, model)

    def _context_for(self, model) -> None:
        """A context for ``model``: the current one with the mesh slots whose contents differ re-uploaded, where
        it was made for a model of the same stage (``stage_parts``) with as many mesh slots; else a new one. The
        drawing is the same either way: only slots ``model`` uses are drawn, and each holds ``model``'s mesh."""
        import mujoco

        context = self._context
        if context is None or context.rangeMesh < 2 * model.nmesh or not self._contents.same_stage(model):
            self._make_context(model)
            self._contents.reset(model)
            return
        changed = self._contents.changed_slots(model)  # rangeMesh >= 2 * nmesh above
        if changed:
            with self._simplified.drawn_in(model) if self._simplified is not None else nullcontext():
                for i in changed:
                    mujoco.mjr_uploadMesh(model, context, i)
            self._contents.refilled(model, changed)
        self._context_model = model

    def _make_context(self, model) -> None:
        import mujoco

        self._contents.reset()
        if self._context is not None:
            self._context.free()
        # The context sizes its shadow maps, multisampling and offscreen buffer from the model it is made from and
        # uploads that model's meshes; these are set for its making only, and the caller's model is left as it was.
        quality, buffer = model.vis.quality, model.vis.global_
        own = (int(quality.shadowsize), int(quality.offsamples), int(buffer.offwidth), int(buffer.offheight))
        if self.config.shadow_size is not None:
            quality.shadowsize = self.config.shadow_size
        if self.config.multisamples is not None:
            quality.offsamples = self.config.multisamples
        # A buffer the image's size: a larger one only costs clearing and resolving pixels never read.
        buffer.offwidth, buffer.offheight = self.config.width, self.config.height
        try:
            with self._simplified.drawn_in(model) if self._simplified is not None else nullcontext():
                self._context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        finally:
            quality.shadowsize, quality.offsamples, buffer.offwidth, buffer.offheight = own
        self._context_model = model
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        # Read depth as reversed z (far = 0), the mapping _metric_depth undoes.
        self._context.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR

    # --- drawing ----------------------------------------------------------------------------------------------
    def _camera(self, camera: str):
        import mujoco

        cam = mujoco.MjvCamera()
        cam_id = mujoco.mj_name2id(self._model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if cam_id < 0:
            names = [mujoco.mj_id2name(self._model, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(self._model.ncam)]
            raise RenderError(unknown_name("camera", camera, [n for n in names if n]))
        cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        cam.fixedcamid = cam_id
        return cam

    def _update_scene(self, data, cam) -> None:
        import mujoco

        mujoco.mjv_updateScene(self._model, data, self._option, None, cam, mujoco.mjtCatBit.mjCAT_ALL, self._scene)
        if self._mesh_remap is None:
            return
        mesh = int(mujoco.mjtGeom.mjGEOM_MESH)
        for i in range(self._scene.ngeom):
            geom = self._scene.geoms[i]
            if geom.type == mesh and geom.dataid >= 0:
                # dataid is 2 * mesh id (+1 for the convex hull)
                geom.dataid = 2 * int(self._mesh_remap[geom.dataid // 2]) + geom.dataid % 2

    def render(self, data, camera: str) -> Frame:
        import mujoco

        if self._model is None:
            raise RenderError("render() called before setup(scene, model)")
        self._gl.make_current()
        cam = self._camera(camera)
        w, h = self.config.width, self.config.height
        rect = mujoco.MjrRect(0, 0, w, h)
        self._update_scene(data, cam)
        ids = z = None
        if self.config.segmentation or self.config.depth:
            ids, z = self._id_pass(rect)
        if self.config.rgb:
            # A reflection shows only on its plane: where no pixel of one is seen, the pass without it is the same.
            reflection = self.config.reflection and (
                self.config.reflection_when_hidden or ids is None or self._reflector_seen(ids))
            flag = mujoco.mjtRndFlag.mjRND_REFLECTION
            self._scene.flags[flag] = int(reflection)
            try:
                mujoco.mjr_render(rect, self._scene, self._context)
            finally:
                self._scene.flags[flag] = int(self.config.reflection)
        # The id pass is turned into labels and metres while the rasteriser's threads finish the RGB pass.
        seg = self._labels_of(np.flipud(ids)) if self.config.segmentation else None
        depth = self._metric_depth(np.flipud(z)) if z is not None else None
        if self.config.rgb:
            rgb_buf = np.empty((h, w, 3), dtype=np.uint8)
            mujoco.mjr_readPixels(rgb_buf, None, rect, self._context)
            rgb = np.ascontiguousarray(np.flipud(rgb_buf))
        else:
            rgb = np.zeros((h, w, 3), dtype=np.uint8)
        return Frame(camera=camera, rgb=rgb, depth=depth, segmentation=seg)

    def _id_pass(self, rect) -> tuple[np.ndarray, np.ndarray | None]:
        """The segmentation pass (each geom's segid + 1 as its colour, no lighting; rows bottom up) and, with depth
        on, its depth buffer: without lighting and blending depth is exact at the far end.

        Multisampling is off in this pass, so every sample of a pixel holds the same value; where the context has
        a single-sample resolve buffer (``offFBO_r``, there with multisampling) the pass is drawn straight into it
        and read back, saving the multisampled buffer's clearing and the resolve: the same values, read sooner."""
        import mujoco

        w, h = rect.width, rect.height
        ids = np.empty((h, w, 3), dtype=np.uint8)
        z = np.empty((h, w), dtype=np.float32) if self.config.depth else None
        flags, context = self._scene.flags, self._context
        seg_flag, id_flag = mujoco.mjtRndFlag.mjRND_SEGMENT, mujoco.mjtRndFlag.mjRND_IDCOLOR
        flags[seg_flag], flags[id_flag] = 1, 1
        try:
            resolve = int(context.offFBO_r) if context.offSamples else 0
            if resolve:
                from muble_plugins.renderers.mujoco.gl import draw_into, read_pixels

                with draw_into(resolve, lambda: mujoco.mjr_restoreBuffer(context)):
                    mujoco.mjr_render(rect, self._scene, context)
                    read_pixels(resolve, ids, z)
            else:
                mujoco.mjr_render(rect, self._scene, context)
                mujoco.mjr_readPixels(ids, z, rect, context)
        finally:
            flags[seg_flag], flags[id_flag] = 0, 0
        return ids, z

    def _segids(self, image: np.ndarray) -> np.ndarray:
        """Each pixel's scene geom index + 1 (0: nothing drawn) from an id pass image."""
        if self._scene.ngeom < 255:  # every id fits the red channel, so green and blue are zero
            return image[..., 0]
        return image[..., 0].astype(np.int32) | (image[..., 1].astype(np.int32) << 8) | (
            image[..., 2].astype(np.int32) << 16)

    def _reflector_seen(self, image: np.ndarray) -> bool:
        """Whether any geom MuJoCo may draw a reflection in (a plane or box with reflectance) shows in the id pass."""
        import mujoco

        kinds = (int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_BOX))
        n = self._scene.ngeom
        reflectors = [g.segid for g in (self._scene.geoms[i] for i in range(n)) if g.reflectance > 0 and g.type in kinds]
        if not reflectors:
            return False  # nothing reflects: MuJoCo's reflection pass draws nothing
        if min(reflectors) < 0:
            return True  # not in the id pass: it cannot be known unseen
        reflectors = [segid + 1 for segid in reflectors]
        seen = np.bincount(self._segids(image).ravel(), minlength=n + 1)
        return bool(seen[reflectors].any())

    def _metric_depth(self, z: np.ndarray) -> np.ndarray:
        # MuJoCo draws with reversed z; undo its perspective projection in float64 (float32 loses centimetres).
        extent = self._model.stat.extent
        near = np.float32(self._model.vis.map.znear * extent)
        far = np.float32(self._model.vis.map.zfar * extent)
        c = -(far + near) / (far - near)
        d = -(np.float32(2) * far * near) / (far - near)
        c, d = np.float32(-0.5) * c - np.float32(0.5), np.float32(-0.5) * d
        return (d / (z.astype(np.float64) + c)).astype(np.float32)

    def _labels_of(self, image: np.ndarray) -> np.ndarray:
        import mujoco

        n = self._scene.ngeom
        lut = np.full(n + 1, -1, dtype=np.int32)  # index 0 = nothing drawn
        geom_type = int(mujoco.mjtObj.mjOBJ_GEOM)
        for i in range(n):
            g = self._scene.geoms[i]
            if g.segid >= 0 and g.objtype == geom_type and 0 <= g.objid < len(self._labels):
                lut[g.segid + 1] = self._labels[g.objid]
        if n < 255:  # ids in the red channel: a lookup over all 256 values
            return lut[np.minimum(np.arange(256), n)][self._segids(image)]
        return lut[np.clip(self._segids(image), 0, n)]

    def close(self) -> None:
        self._contents.reset()
        if self._context is not None:
            self._context.free()
            self._context = None
        if self._gl is not None:
            from muble_plugins.renderers.mujoco.gl import release_context

            release_context(self._gl)
            self._gl = None
        self._model = self._scene = self._set_up_with = None

    def __del__(self) -> None:  # GL resources left to interpreter exit print EGL errors
        try:
            self.close()
        except Exception:  # noqa: BLE001 - nothing useful can be done during teardown
            pass
