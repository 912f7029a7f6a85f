"""An episode's parts built from one composed config: the configured plugins, the runner, the scene generator.

``muble run``, ``muble generate``, ``muble eval``, the Gymnasium environments and the remote server all build them
here, so every entry point turns the same config into the same objects.
"""
from __future__ import annotations

from typing import Any, cast

from omegaconf import DictConfig, OmegaConf

from muble.core.errors import ConfigError
from muble.plugins.registry import get_registry

# Plugin kind -> config group that selects it.
GROUP_OF_KIND = {
    "renderer": "renderer",
    "planner": "planner",
    "task": "task",
    "object_set": "objects",
    "agent": "agent",
}


def build_components(cfg: DictConfig, renderer: bool = True, task: bool = True) -> dict[str, Any]:
    """Instantiate every configured plugin through the registry (a typo in any option fails here, early); each is
    what its registered factory built (``Registry.create``), so the components are typed as it types them.

    ``renderer=False`` leaves the renderer out (None); ``task=False`` the task (when each instruction names its own).
    """
    registry = get_registry()
    components: dict[str, Any] = {}
    for kind, group in GROUP_OF_KIND.items():
        if (kind == "renderer" and not renderer) or (kind == "task" and not task):
            components[kind] = None
            continue
        node = cfg[group]
        components[kind] = registry.create(kind, node.name, node)
    components["sensors"] = {name: registry.create("sensor", name, options or {})
                             for name, options in cfg.sensors.enabled.items()}
    enabled = cfg.get("disturbances", {}).get("enabled", {}) or {}
    components["disturbances"] = {name: registry.create("disturbance", name, options or {})
                                  for name, options in enabled.items()}
    return components


def episode_runner(cfg: DictConfig, components: dict[str, Any]):
    from muble.episode.runner import EpisodeRunner

    robot = OmegaConf.to_container(cfg.robot, resolve=True)
    track, mode = benchmark_settings(cfg)
    if mode != "graph" and components["renderer"] is None:
        raise ConfigError(f"observation mode '{mode}' shows the agent images: it needs a renderer "
                          "(with evaluation.render, or muble run's keyframes)")
    return EpisodeRunner(get_registry(), robot, components["planner"], components["agent"],
                         components["object_set"], cfg.objects.name, components["sensors"], components["renderer"],
                         tuple(cfg.episode.cameras), cfg.episode.max_steps, track=track, mode=mode,
                         disturbances=components.get("disturbances") or {}, seed=int(cfg.get("seed", 0)),
                         disturbances_per_episode=tuple(cfg.get("disturbances", {}).get("per_episode", ()) or ()),
                         noise=OmegaConf.to_container(cfg.noise, resolve=True) if cfg.get("noise") else None)


def benchmark_settings(cfg: Any) -> tuple[str, str]:
    """(track, observation mode) of a config (``benchmark.track``, ``benchmark.mode``; program and graph when
    the config has no ``benchmark`` section)."""
    bench = cfg.get("benchmark") if hasattr(cfg, "get") else None
    if not bench:
        return "program", "graph"
    value = lambda v: str(getattr(v, "value", v))  # noqa: E731 - an enum member or its string
    return value(bench.get("track", "program")), value(bench.get("mode", "graph"))


def image_size(cfg: Any) -> tuple[int, int]:
    """(width, height) of a config's images: ``renderer.width`` and ``renderer.height``, the one setting that sizes
    the scenes' camera, their masks, the keyframes and the Gym image spaces (a DictConfig or a plain dict)."""
    renderer = cfg["renderer"]
    return int(renderer["width"]), int(renderer["height"])


def scene_generator(cfg: DictConfig, object_set: object):
    from muble.generation.generator import SceneGenerator

    options = cast(dict[str, Any], OmegaConf.to_container(cfg.generator, resolve=True))  # a mapping of options
    return SceneGenerator(options, seed=cfg.seed, object_set=object_set, image_size=image_size(cfg))


def split_episode(cfg: Any, split: str, index: int, object_set: Any, timings: dict[str, float] | None = None,
                  size: tuple[int, int] | None = None):
    """The scene, template and instruction of index ``index`` of ``split`` as ``muble generate`` makes them
    (``muble.generation.task_mix.SuitedScene``): the generator seeded with the split's seed (``split_seed``), the
    index's template and object count from the split's template mix, the first scene sample that suits the
    template. ``cfg`` is the config as the split is produced (``muble.dataset.protocol.split_config``, or
    ``muble.dataset.production.split_run_config`` for a composed one) and ``object_set`` built from it.
    ``muble generate`` makes every index with it, and ``muble run split=S``, the Gymnasium environments and
    ``muble serve`` make index k of split S with it, so that theirs is index k of the dataset. ``timings`` gets
    the generator's seconds per stage (``SceneGenerator.timings``). ``size`` is the image size the split is
    generated at (the scenes' camera, masks and visibility checks), by default ``cfg``'s renderer size: a caller
    that renders at another size (a Gymnasium environment's small images) passes ``muble generate``'s."""
    from pathlib import Path

    from muble.core.streams import split_seed
    from muble.episode.runner import instruction_rng
    from muble.generation.generator import SceneGenerator
    from muble.generation.task_mix import suited_scene, template_weights
    from muble.io.layout import DatasetLayout

    def plain(node: Any) -> Any:
        return OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node

    registry = get_registry()
    seed = split_seed(cfg["seed"], split)
    ds = cfg["dataset"]
    generator = SceneGenerator(dict(plain(cfg["generator"]), split=split), seed=seed, object_set=object_set,
                               image_size=size or image_size(cfg))
    options = plain(ds.get("task_options")) or {}
    tasks = {name: registry.create("task", name, dict(options)) for name in plain(ds["templates"])}
    weights = template_weights(list(tasks), plain(ds["template_weights"]))
    try:
        suited = suited_scene(generator, tasks, weights, seed, index, lambda i: instruction_rng(seed, i))
    finally:
        generator.close()
        if timings is not None:
            timings.update(generator.timings)
    suited.scene.image_filename = Path(DatasetLayout(Path("."), split).image(index)).name
    suited.instruction.image_filename = suited.scene.image_filename
    return suited


def generated_env(cfg: DictConfig, components: dict[str, Any], index: int):
    """The environment (no sensors) of scene ``index`` as ``cfg``'s generator, object set and robot make it;
    the caller closes it."""
    from muble.sim.build import object_models
    from muble.sim.env import TabletopEnv

    generator = scene_generator(cfg, components["object_set"])
    try:
        scene = generator.generate(index)
    finally:
        generator.close()
    return TabletopEnv(scene, object_models(scene, components["object_set"], cfg.objects.name),
                       OmegaConf.to_container(cfg.robot, resolve=True), {})


class KeptRenderer:
    """A renderer kept across episodes, as an episode runner sees it: the runner's ``close`` at the episode's end
    leaves it open, so its next ``setup`` reuses what it holds (a GL context, uploaded meshes). Whoever keeps it
    closes ``inner`` (``close_at_exit`` arranges that at interpreter exit). Only for episodes that run on one
    thread, one at a time."""

    def __init__(self, inner: Any, close_at_exit: bool = False) -> None:
        self.inner = inner
        self._close_at_exit = close_at_exit

    def setup(self, scene: Any, model: Any) -> None:
        self.inner.setup(scene, model)
        if self._close_at_exit:
            import atexit

            # Registered after the first setup, so that it runs before any exit hook the renderer's own resources
            # registered while being set up (atexit runs the last registered first).
            atexit.register(self.inner.close)
            self._close_at_exit = False

    def render(self, data: Any, camera: str):
        return self.inner.render(data, camera)

    def close(self) -> None:
        pass

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)
