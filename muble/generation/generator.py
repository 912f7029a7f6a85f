"""The SHOP-VRB2 scene generator: sample objects, place them mesh-exactly, check visibility and rest, record GT.

Every scene is a pure function of (``seed``, ``index``): its objects are drawn from the named stream
``scene.objects`` and their placements from ``scene.layout`` (``muble.core.streams``, keyed by index and scene
sample), and every retry draws from them, so the same pair always yields the same JSON, and a shard of indices can
be generated anywhere in any order. The hidden physical properties asked for (``physical_properties``) come from
streams of their own (``PROPERTY_STREAMS``), so drawing them changes no other draw.
"""
from __future__ import annotations

import collections
import dataclasses
import logging
import math
import time
from typing import Any, Callable

import numpy as np
from omegaconf import DictConfig

from muble.core import physical_properties
from muble.core.errors import ConfigError, SceneGenerationError, unknown_name
from muble.core.objects import ObjectModel, ObjectSpec
from muble.core.ranges import configured
from muble.core.scene import SceneGraph, SceneObject
from muble.generation import checks, ground_truth
from muble.generation.config import GeneratorConfig, on_stage
from muble.generation.placement import mesh_distance, shared_collision_meshes
from muble.core import streams
from muble.generation.staging import LAMPS, jittered_camera, jittered_lamps
from muble.generation.view import shared_view
from muble.stage.camera import DEFAULT_HEIGHT, DEFAULT_WIDTH, CameraParams, euler_xyz_to_matrix
from muble.stage.layout import Placement, TableLayout
from muble.stage.rest import settled
from muble.stage.table import STAGE_KEY, UNNAMED_STAGE

log = logging.getLogger(__name__)

WEIGHT_RESAMPLES = 30
# Raised whenever the same settings make other files (2: named random streams, fixed-order sums, 9-decimal floats);
# a dataset folder records it, so one made by another version is not resumed into a mix of both.
GENERATOR_VERSION = 2
# The stream each hidden physical property (``muble.core.physical_properties.PROPERTIES``) is drawn from: MuBlE's
# own three declared in ``muble.core.streams``, a package's as ``scene.<sampled_as>`` (``Property.stream``).
PROPERTY_STREAMS = streams.PROPERTY_STREAMS


def _property_stream(name: str) -> str:
    prop = physical_properties.SAMPLED[name]
    if name in PROPERTY_STREAMS:
        return PROPERTY_STREAMS[name]
    assert prop.stream is not None
    return streams.declare(prop.stream, f"a scene sample's {prop.name} values of its objects (index, sample)")


@dataclasses.dataclass(frozen=True)
class Staging:
    """The camera and lamps of one scene, and what follows from the camera: its table directions. ``jittered``
    says whether the camera differs from the generator's default one (the view model is then re-aimed)."""

    camera: CameraParams
    directions: dict[str, list[float]]
    lamps: dict[str, list[float]]
    lamp_energy: dict[str, float] | None
    jittered: bool


def _named(name: str, option: str) -> str:
    if not name:
        raise ConfigError(f"generator.{option} is not set: name the plugin (muble_conf/generator/*.yaml names the "
                          "built-in one)")
    return name


class SceneGenerator:
    """Generates scenes by index. ``object_set`` and ``renderer`` default to registry plugins named in the config;
    ``image_size`` is the (width, height) of the scenes' images, the run's ``renderer.width`` and
    ``renderer.height`` (``muble.episode.components.image_size``): the camera in each scene file, its masks and
    the visibility checks are of that image."""

    def __init__(self, config: GeneratorConfig | dict | DictConfig | None = None, seed: int = 0,
                 object_set: Any = None, renderer: Any = None,
                 reach_check: Callable[[SceneGraph, dict[int, ObjectModel]], str | None] | None = None,
                 image_size: tuple[int, int] = (DEFAULT_WIDTH, DEFAULT_HEIGHT)):
        from muble.sim.env import ROBOT_DEFAULTS

        # The options left at their defaults take the stage's values (``muble.generation.config.on_stage``).
        self.config = cfg = on_stage(configured(GeneratorConfig, config, owner="generator"))
        self.seed = int(seed)
        # The physics step of the robot the scenes are made for: layouts settle as its episodes will run.
        self.timestep = float((cfg.robot or {}).get("timestep") or ROBOT_DEFAULTS["timestep"])
        self._check_config(cfg)
        if object_set is None:
            from muble.plugins.registry import get_registry

            object_set = get_registry().create("object_set", _named(cfg.object_set, "object_set"),
                                               cfg.object_set_options)
        self.object_set = object_set
        self.camera = CameraParams(np.array(cfg.camera_position, float), euler_xyz_to_matrix(np.asarray(cfg.camera_rotation, float)),
                                   int(image_size[0]), int(image_size[1]), cfg.lens_mm)
        self.check_camera = self.camera.scaled(cfg.occlusion_scale) if cfg.occlusion_scale != 1.0 else self.camera
        self._renderer = renderer
        self._mask_renderer = None
        self._collision_meshes = shared_collision_meshes()
        # One render model for every layout; sized for the full image so the mask renderer can share it.
        self._view = shared_view(self.camera, cfg.table_x, cfg.table_y,
                                 slots=cfg.min_objects + len(cfg.count_probabilities) - 1 + cfg.distractors)
        self.directions = ground_truth.directions(self.camera)
        if reach_check is None and cfg.reach_check:
            from muble.generation.reachability import ReachCheck

            reach_check = ReachCheck(cfg.robot, _named(cfg.reach_primitive, "reach_primitive"))
        # (scene, models) -> None, or why the robot cannot grasp and put down some object: the last check.
        self.reach_check = reach_check
        self.failures: collections.Counter[str] = collections.Counter()  # why layouts were rejected, all scenes
        # seconds spent per stage, all scenes
        self.timings: collections.defaultdict[str, float] = collections.defaultdict(float)

    @staticmethod
    def _check_config(cfg: GeneratorConfig) -> None:
        """What the schema's bounds cannot say: how options relate to each other and to the table."""
        table_w = min(cfg.table_x[1] - cfg.table_x[0], cfg.table_y[1] - cfg.table_y[0])
        if cfg.margin >= table_w:
            raise ConfigError(f"margin {cfg.margin} m must be narrower than the table ({table_w:.2f} m); "
                              "lower generator.margin")
        if cfg.reach_x[0] >= cfg.reach_x[1] or cfg.reach_y[0] >= cfg.reach_y[1]:
            raise ConfigError(f"reach_x {cfg.reach_x} and reach_y {cfg.reach_y} must be [low, high] ranges")
        if not cfg.count_probabilities or abs(sum(cfg.count_probabilities) - 1) > 1e-6:
            raise ConfigError(f"count_probabilities must sum to 1, got {cfg.count_probabilities}")
        for name in cfg.physical_properties:
            if name not in physical_properties.PROPERTIES:
                raise ConfigError(unknown_name("generator.physical_properties property", name,
                                               list(physical_properties.PROPERTIES)))

    # --- renderers --------------------------------------------------------------------------------------------
    def _renderer_for(self, camera: CameraParams):
        from muble.plugins.registry import get_registry

        options = {**self.config.renderer_options, "width": camera.width, "height": camera.height}
        return get_registry().create("renderer", _named(self.config.renderer, "renderer"), options)

    def _draw(self, renderer, models, placements, staging: Staging | None = None):
        """Segmentation of a layout seen by the scene's camera (``staging``; none: the configured camera): the
        shared view model is re-posed (and re-aimed for a jittered camera); a renderer's setup returns at once for
        the view model it already has (the ``Renderer`` contract)."""
        camera = staging.camera if staging is not None and staging.jittered else None
        view, data = self._view.pose(models, placements, camera)
        renderer.setup(None, view)
        return renderer.render(data, checks.CAMERA_NAME)

    @property
    def renderer(self):
        if self._renderer is None:
            self._renderer = self._renderer_for(self.check_camera)
        return self._renderer

    def close(self) -> None:
        for r in (self._renderer, self._mask_renderer):
            if r is not None:
                r.close()
        self._renderer = self._mask_renderer = None

    # --- camera and lamps --------------------------------------------------------------------------------------
    def staging(self, index: int) -> Staging:
        """The camera and lamps of scene ``index``: the configured ones, each moved by its jitter option from a
        stream of its own (``muble.generation.staging``), so the objects and their layout do not change."""
        cfg = self.config
        camera, directions, jittered = self.camera, self.directions, False
        if cfg.camera_jitter_m > 0 or cfg.camera_jitter_deg > 0:
            camera = jittered_camera(self.camera, cfg.camera_rotation, streams.stream(streams.CAMERA_JITTER, self.seed, index),
                                     cfg.camera_jitter_m, cfg.camera_jitter_deg)
            directions, jittered = ground_truth.directions(camera), True
        lamps, energy = {k: list(v) for k, v in LAMPS.items()}, None
        if cfg.lamp_jitter > 0:
            lamps, energy = jittered_lamps(LAMPS, streams.stream(streams.LAMP_JITTER, self.seed, index),
                                           cfg.lamp_jitter)
        return Staging(camera, directions, lamps, energy, jittered)

    # --- sampling ---------------------------------------------------------------------------------------------
    def _sample_specs(self, rng: np.random.Generator, count: int | None = None) -> list[ObjectSpec] | None:
        """``count`` objects (default: drawn from the count probabilities) whose weights differ pairwise by at least
        ``min_weight_gap``, or None when no such set was drawn in ``WEIGHT_RESAMPLES`` draws per object."""
        cfg = self.config
        if count is None:
            count = cfg.min_objects + int(rng.choice(len(cfg.count_probabilities), p=cfg.count_probabilities))
        specs: list[ObjectSpec] = []
        for _ in range(count):
            for _ in range(WEIGHT_RESAMPLES):
                spec = self.object_set.sample(rng)
                spec.weight_g = round(float(spec.weight_g), 1)  # the file keeps 0.1 g; the gap is checked on that
                if all(abs(spec.weight_g - s.weight_g) >= cfg.min_weight_gap for s in specs):
                    specs.append(spec)
                    break
            else:
                return None
        return specs

    def _physical_properties(self, specs: list[ObjectSpec], models: list[ObjectModel],
                             rngs: dict[str, np.random.Generator]) -> tuple[list[ObjectModel], list[dict[str, Any]]]:
        """The models with the hidden physical properties drawn for them, and each object's scene keys and values
        (``muble.core.physical_properties.sampled``, rounded as the file keeps them): per property of ``rngs``, per
        object in scene order, for the objects that carry it (``muble.core.physical_properties.carried``)."""
        values: list[dict[str, Any]] = [{} for _ in specs]
        if not rngs:
            return models, values
        for name, rng in rngs.items():
            key = physical_properties.SCENE_KEYS[name]
            for value, spec, model in zip(values, specs, models):
                if physical_properties.carried(name, self.object_set, spec, model):
                    value[key] = physical_properties.sampled(name, rng, model, spec.weight_g)
        # The model gets what the file says, as an environment built from the file does (muble.sim.build).
        models = [dataclasses.replace(m, **physical_properties.model_fields(v, s.weight_g)) if v else m
                  for v, s, m in zip(values, specs, models)]
        return models, values

    def _layout(self, models: list[ObjectModel], rng: np.random.Generator) -> list[Placement] | None:
        cfg = self.config
        layout = TableLayout(cfg.reach_x, cfg.reach_y, cfg.table_x, cfg.table_y, cfg.margin, cfg.robot_clearance,
                             distance=mesh_distance)
        meshes = [self._collision_meshes.get(m) for m in models]
        placements: list[Placement | None] = [None] * len(models)
        for i in sorted(range(len(models)), key=lambda k: -meshes[k].radius):  # big footprints first pack best
            placements[i] = layout.try_place(meshes[i], rng, cfg.placement_tries)
            if placements[i] is None:
                return None
        return placements  # type: ignore[return-value]

    # --- one scene --------------------------------------------------------------------------------------------
    def generate(self, index: int, *, sample: int = 0, objects: int | None = None,
                 accept: Callable[[SceneGraph], bool] | None = None,
                 stacks: Callable[[SceneGraph], list[tuple[int, int]]] | None = None,
                 admits: Callable[[list[ObjectSpec]], bool] | None = None) -> SceneGraph:
        """The scene for ``index``; raises ``SceneGenerationError`` naming the failing checks if no layout passes.

        ``sample`` > 0 draws a further, independent scene for the same index (its own streams, keyed by
        ``(index, sample)``), e.g. when the scene drawn first does not suit the task wanted there. ``objects`` fixes the
        object count instead of drawing it. ``accept(scene)`` is asked about each placed layout before the
        costlier checks (visibility, rest, reach); it sees every field but the masks. ``admits(specs)`` is asked
        about each set of objects drawn before it is placed (``Task.admits``); a set it refuses is drawn again
        without placing it. ``stacks(scene)`` names the
        (top, base) pairs, bottom pair first, that the scene's task will stack (asked after ``accept``): with
        ``stack_check`` on, a layout is kept only when each such stack stands upright in physics.
        """
        cfg = self.config
        objects_rng = streams.stream(streams.SCENE_OBJECTS, self.seed, int(index), int(sample))
        layout_rng = streams.stream(streams.SCENE_LAYOUT, self.seed, int(index), int(sample))
        # In PROPERTIES order, which is the order of their keys in the file; none asked for: no stream is made.
        property_rngs = {name: streams.stream(_property_stream(name), self.seed, int(index), int(sample))
                         for name in physical_properties.PROPERTIES if name in cfg.physical_properties}
        staging = self.staging(index)
        reasons: collections.Counter[str] = collections.Counter()
        for _ in range(cfg.layout_tries):
            specs = self._sample_specs(objects_rng, objects)
            if specs is None:
                reasons["weights"] += 1
                continue
            if admits is not None and not admits(specs):
                reasons["objects"] += 1
                continue
            t0 = time.perf_counter()
            models = [self.object_set.build(s) for s in specs]
            # Before every check, so placement, rest, stacks and reach see the objects as the file will give them.
            models, properties = self._physical_properties(specs, models, property_rngs)
            t1 = time.perf_counter()
            placements = self._layout(models, layout_rng)
            t2 = time.perf_counter()
            self.timings["build"] += t1 - t0
            self.timings["placement"] += t2 - t1
            if placements is None:
                reasons["placement"] += 1
                continue
            if accept is not None and not accept(self._scene(index, specs, models, placements, None, staging,
                                                             properties)):
                reasons["not accepted"] += 1
                continue
            frame = self._draw(self.renderer, models, placements, staging)
            t4 = time.perf_counter()
            self.timings["render"] += t4 - t2
            need = cfg.min_visible_pixels * (self.check_camera.width * self.check_camera.height) / (
                DEFAULT_WIDTH * DEFAULT_HEIGHT)
            if np.any(checks.visible_pixels(frame.segmentation, len(models)) < need):
                reasons["occlusion"] += 1
                continue
            if cfg.stability:
                moved = checks.settle(models, placements, cfg.table_x, cfg.table_y, self.timestep, cfg.settle_time)
                self.timings["stability"] += time.perf_counter() - t4
                if not all(settled(m, limit=cfg.stability_tolerance) for m in moved):
                    reasons["stability"] += 1
                    continue
            scene = self._scene(index, specs, models, placements, None, staging, properties)
            pairs = stacks(scene) if stacks is not None and cfg.stack_check else []
            if pairs:
                t5 = time.perf_counter()
                fallen = checks.stacks_stand(models, placements, pairs, cfg.table_x, cfg.table_y, self.timestep)
                self.timings["stacking"] += time.perf_counter() - t5
                if fallen:
                    reasons["stacking"] += 1
                    log.debug("scene %d: layout rejected: %s", index, fallen)
                    continue
            if self.reach_check is not None:
                t5 = time.perf_counter()
                unreachable = self.reach_check(scene, dict(enumerate(models)))
                self.timings["reach"] += time.perf_counter() - t5
                if unreachable:
                    reasons["reach"] += 1
                    log.debug("scene %d: layout rejected: %s", index, unreachable)
                    continue
            if cfg.masks:
                self._apply_masks(scene, self._masks(models, placements, frame, staging))
            self.failures.update(reasons)
            return scene
        self.failures.update(reasons)
        detail = ", ".join(f"{k}: {v}" for k, v in sorted(reasons.items()))
        raise SceneGenerationError(
            f"scene {index}: no valid layout in {cfg.layout_tries} tries ({detail}). Place fewer or smaller "
            "objects, lower generator.margin or generator.min_visible_pixels, or widen reach_x/reach_y",
            index=int(index), reasons=dict(reasons))

    def _masks(self, models, placements, frame, staging: Staging) -> np.ndarray:
        if self.check_camera is self.camera:
            return frame.segmentation
        if self._mask_renderer is None:
            self._mask_renderer = self._renderer_for(self.camera)
        return self._draw(self._mask_renderer, models, placements, staging).segmentation

    @staticmethod
    def _apply_masks(scene: SceneGraph, segmentation: np.ndarray) -> None:
        from muble.core.types import SEG_TABLE

        *masks, table_mask = ground_truth.encode_masks(segmentation, [*range(len(scene.objects)), SEG_TABLE])
        for obj, mask in zip(scene.objects, masks):
            obj.mask = mask
        scene.table = {"mask": table_mask}

    def _scene(self, index, specs, models, placements, segmentation, staging: Staging,
               properties: list[dict[str, Any]]) -> SceneGraph:
        cfg = self.config
        objects = []
        masks = None
        if segmentation is not None:
            from muble.core.types import SEG_TABLE

            *masks, table_mask = ground_truth.encode_masks(segmentation, [*range(len(specs)), SEG_TABLE])
        # Every float the file gets is rounded (ground_truth.rounded), so that values a rounding error apart on
        # another CPU are written the same; relationships are decided on the rounded positions the file holds.
        rounded = ground_truth.rounded
        for i, (spec, model, p) in enumerate(zip(specs, models, placements)):
            ext = np.asarray(model.extents, float)
            position = np.array(rounded(p.position))
            objects.append(SceneObject(
                id=i, model=spec.model, name=spec.category, shape=spec.shape, size=spec.size,
                material=spec.material, colour=spec.colour, position=position, orientation=np.array(rounded(p.quat)),
                weight_gt=spec.weight_g, stackable=bool(model.stackable), stack_base=bool(model.stack_base),
                pickupable=bool(model.pickupable), rotation=rounded(math.degrees(p.yaw) % 360.0),
                pixel_coords=rounded(ground_truth.pixel_coords(staging.camera, position)),
                movability="portable" if model.pickupable else "stationary",
                bbox=rounded({"x": float(ext[0]), "y": float(ext[1]), "z": float(ext[2])}),
                scale_factor=rounded(float(spec.scale)),
                mask=masks[i] if masks is not None else None,
                stiffness=rounded(float(model.stiffness)),
                extra=dict(properties[i]),  # the hidden physical properties drawn (none unless asked for)
            ))
        name = f"SHOPVRB2_{cfg.split}_{index:06d}.png"
        scene = SceneGraph(
            objects=objects, split=cfg.split, image_index=int(index), image_filename=name,
            directions=rounded(staging.directions), camera_params=rounded(staging.camera.to_scene_params()),
            lamp_params={k: rounded(list(v)) for k, v in staging.lamps.items()},
            relationships=ground_truth.relationships([o.position for o in objects], rounded(staging.directions)),
            # Lamp energy factors (``lamp_jitter``) sit beside lamp_params, which maps lamp names to positions.
            extra={**({"lamp_energy": rounded(dict(staging.lamp_energy))} if staging.lamp_energy is not None else {}),
                   "generator": {"seed": self.seed, "index": int(index), "object_set": cfg.object_set},
                   # A file without the key stands on UNNAMED_STAGE (robosuite's): scenes made on it keep the
                   # bytes they had before stages could be chosen (protocol shopvrb2_v1's data hashes).
                   **({STAGE_KEY: cfg.stage} if cfg.stage and cfg.stage != UNNAMED_STAGE else {})},
        )
        if masks is not None:
            scene.table = {"mask": table_mask}
        return scene
