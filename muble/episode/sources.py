"""Where an episode's scene and instruction come from, and the runner that executes it, from one composed config.

Three sources, the same for the Gymnasium environments and the remote agent server:
- **generated**: scene ``scene_index`` of the generator seeded with ``seed`` and an instruction of a template (or
  of a template mix), exactly as ``muble run`` chooses them; with ``split=NAME`` in the config, index
  ``scene_index`` of that split as ``muble generate`` makes it (``muble.episode.components.split_episode``);
- **dataset**: the stored scene and instruction of ``split``/``index`` under ``dataset.root``, as ``muble eval``
  reads them;
- **data**: a scene and an instruction given as SHOP-VRB2 JSON data.
"""
from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence, cast

import numpy as np

from muble.core.errors import ConfigError, SceneValidationError, unknown_name
from muble.core.interfaces import Instruction, Task
from muble.core.scene import SceneGraph
from muble.episode.components import KeptRenderer

log = logging.getLogger(__name__)

_SPLIT_NAME = re.compile(r"^[A-Za-z0-9_-]{1,64}$")

# The ways to name an episode (Gymnasium's reset options, ``muble serve``'s ``episode`` document), by their keys.
EPISODE_FORMS = "{scene_index[, template]}, {split, index} or {scene, instruction}"


def dataset_root(cfg: Any) -> Path | None:
    """The folder of stored episodes a config names (``dataset.root``), or None when it names none: outside a
    Hydra job the default ``dataset.root``, a Hydra run folder, cannot be resolved."""
    from omegaconf.errors import OmegaConfBaseException

    try:
        root = cfg.dataset.root
    except (OmegaConfBaseException, AttributeError, KeyError, ValueError):
        return None
    return Path(str(root)) if root else None


def episode_kind(request: Any) -> str | None:
    """Which source a mapping names an episode from, by its keys: ``generated`` (``scene_index``, optionally
    ``template``), ``stored`` (``split``, ``index``) or ``data`` (``scene``, ``instruction``); None for any other
    keys (``EPISODE_FORMS`` says what to give)."""
    keys = set(request) if isinstance(request, dict) else None
    if keys in ({"scene_index"}, {"scene_index", "template"}):
        return "generated"
    if keys == {"split", "index"}:
        return "stored"
    if keys == {"scene", "instruction"}:
        return "data"
    return None


@dataclass
class EpisodeSpec:
    """A scene, an instruction of it and the task (template) that judges the episode."""

    scene: SceneGraph
    instruction: Instruction
    task: Task
    source: dict[str, Any]


class EpisodeFactory:
    """Builds the configured plugins once; makes episodes from any source and a runner per episode.

    ``cfg`` is a composed MuBlE config (``muble.app.config.compose("run", overrides)``). ``render`` renders a
    keyframe with the configured renderer after every primitive (a fresh renderer per episode). With ``split``
    set, generated episodes are that split's indices; ``cfg`` then comes with the split's own settings
    (``muble.dataset.production.split_run_config``, which the Gymnasium environment and the server apply), and
    ``split_size`` is the image size ``muble generate`` makes the split at where ``cfg``'s renderer size is
    another (default: ``cfg``'s).
    """

    def __init__(self, cfg: Any, render: bool = True, split_size: tuple[int, int] | None = None):
        from omegaconf import OmegaConf

        from muble.episode.components import build_components
        from muble.io.layout import check_split_name
        from muble.plugins.registry import get_registry

        self.split = None if cfg.get("split") is None else check_split_name(str(cfg.split), "split")
        self.split_size = split_size
        self.cfg = cfg
        self.render = render
        self.registry = get_registry()
        self.components = build_components(cfg, renderer=False, task=False)
        # the renderer config group is a mapping of options
        self.renderer_options = cast(dict[str, Any], OmegaConf.to_container(cfg.renderer, resolve=True))
        self._generator = None
        self._kept_renderer = None

    @property
    def templates(self) -> list[str]:
        return list(self.registry.names("task"))

    @property
    def mix(self) -> list[str]:
        """The templates an episode is drawn from when none are named: the configured mix (``dataset.templates``,
        the ten SHOP-VRB2 templates unless changed; the stiffness family only when named)."""
        return list(self.cfg.dataset.templates)

    def runner(self, keep_renderer: bool = False):
        """A runner for one episode. Its renderer is its own (episodes on threads of their own never share a GL
        context), or with ``keep_renderer`` the factory's one renderer, kept across episodes (its GL context and
        uploaded meshes reused): only for episodes that all run on one thread, one at a time (``EpisodeThread``),
        which must also call ``close_renderer``."""
        from muble.episode.components import episode_runner

        components = dict(self.components)
        if self.render:
            if not keep_renderer:
                components["renderer"] = self.registry.create("renderer", self.renderer_options["name"],
                                                              self.renderer_options)
            else:
                if self._kept_renderer is None:
                    self._kept_renderer = self.registry.create("renderer", self.renderer_options["name"],
                                                               self.renderer_options)
                components["renderer"] = KeptRenderer(self._kept_renderer)
        return episode_runner(self.cfg, components)

    def close_renderer(self) -> None:
        """Close the renderer kept across episodes (call it on the thread the episodes ran on)."""
        if self._kept_renderer is not None:
            self._kept_renderer.close()
            self._kept_renderer = None

    def task(self, template: str) -> Task:
        if template not in self.templates:
            raise ConfigError(unknown_name("template", template, self.templates))
        return self.registry.create("task", template, {})

    # ----------------------------------------------------------------------------------------------- sources
    def generated(self, scene_index: int, templates: Sequence[str] | None = None,
                  weights: Sequence[float] | None = None) -> EpisodeSpec | None:
        """Scene ``scene_index`` of the configured generator and seed with an instruction of ``templates``: the
        one template's first instruction (as ``muble run``), or one drawn from the mix for that scene
        (``choose_from_mix``: a template drawn by ``weights``, then the others in drawn order). None when no
        template applies to the scene.

        ``templates`` and ``weights`` default to the configured mix (``dataset.templates`` and
        ``dataset.template_weights``, read and checked as ``muble generate`` reads them); named templates without
        weights get equal shares. (``muble generate`` goes the other way: the template of each index first, then a
        scene that suits it; so the same index is not the same episode in both.)

        With ``split`` configured, the episode is index ``scene_index`` of that split as ``muble generate`` makes
        it, its template the one the split's mix gives the index: naming ``templates`` or ``weights`` then is a
        ``ConfigError``, and an index with no scene that suits its template a ``SceneGenerationError``."""
        from muble.episode.runner import choose_instruction, instruction_rng
        from muble.generation.task_mix import choose_from_mix, template_weights

        seed = int(self.cfg.seed)
        if self.split is not None:
            return self._split_episode(self.split, int(scene_index), templates, weights)
        if templates is None and weights is None:
            weights = list(self.cfg.dataset.template_weights)
        templates = list(templates or self.mix)
        tasks = [self.task(t) for t in templates]
        scene = self.generator().generate(int(scene_index))
        source = {"kind": "generated", "seed": seed, "scene_index": int(scene_index)}
        if len(tasks) == 1:
            try:
                instruction = choose_instruction(tasks[0], scene, seed, int(scene_index))
            except ConfigError:
                return None
            return EpisodeSpec(scene, instruction, tasks[0], {**source, "template": templates[0]})
        w = np.asarray(template_weights(templates, weights), dtype=float)
        task, instruction = choose_from_mix(tasks, w / w.sum(), scene, instruction_rng(seed, int(scene_index)))
        if instruction is None:
            return None
        return EpisodeSpec(scene, instruction, task, {**source, "template": instruction.template_id})

    def _split_episode(self, split: str, index: int, templates: Sequence[str] | None,
                       weights: Sequence[float] | None) -> EpisodeSpec:
        from muble.core.streams import split_seed
        from muble.episode.components import split_episode

        if templates is not None or weights is not None:
            raise ConfigError(f"with split={split} an index's template is the one the split's template mix "
                              "gives it (dataset.templates, dataset.template_weights): name no template, or set "
                              "split=null to choose one")
        suited = split_episode(self.cfg, split, index, self.components["object_set"], size=self.split_size)
        return EpisodeSpec(suited.scene, suited.instruction, suited.task,
                           {"kind": "generated", "seed": int(self.cfg.seed), "split": split,
                            "split_seed": split_seed(int(self.cfg.seed), split), "scene_index": index,
                            "template": suited.template})

    def stored(self, split: str, index: int, root: str | Path | None = None) -> EpisodeSpec:
        """The stored scene and instruction of ``split``/``index`` under ``root`` (default ``dataset.root``)."""
        from muble.io.instructions_io import load_instruction
        from muble.io.layout import DatasetLayout
        from muble.io.scene_io import load_scene

        if not isinstance(split, str) or not _SPLIT_NAME.match(split):
            raise ConfigError(f"split must be a plain name (letters, digits, '_', '-'), got {split!r:.40}")
        if isinstance(index, bool) or not isinstance(index, int) or index < 0:
            raise ConfigError(f"index must be a non-negative integer, got {index!r:.40}")
        root = root or dataset_root(self.cfg)
        if root is None:
            raise ConfigError(f"no dataset to read episode {split}/{index} from: set dataset.root=DIR (a folder "
                              "`muble generate` or `muble data` wrote), or protocol=NAME to play a frozen "
                              "benchmark's shipped splits (e.g. protocol=shopvrb2_v2 with split 'mini')")
        layout = DatasetLayout(Path(root), split)
        instruction_file = layout.split_dir / layout.instruction(index)
        scene_file = layout.split_dir / layout.scene(index)
        if not instruction_file.is_file() or not scene_file.is_file():
            raise ConfigError(f"the dataset has no episode {split}/{index} (looked in {layout.split_dir})")
        _, instruction = load_instruction(instruction_file)
        if instruction is None:
            raise SceneValidationError(f"{instruction_file} has no instruction (no template applied to the scene)")
        return EpisodeSpec(load_scene(scene_file), instruction, self.task(instruction.template_id),
                           {"kind": "dataset", "split": split, "index": index})

    def from_data(self, scene: Any, instruction: Any) -> EpisodeSpec:
        """A scene and an instruction given as SHOP-VRB2 JSON data (dicts); ``SceneValidationError`` if malformed."""
        from muble.io.instructions_io import instruction_from_dict
        from muble.io.scene_io import scene_from_dict

        parsed = instruction_from_dict(instruction)
        return EpisodeSpec(scene_from_dict(scene), parsed, self.task(parsed.template_id), {"kind": "data"})

    # --------------------------------------------------------------------------------------------- resources
    def generator(self):
        if self._generator is None:
            from muble.episode.components import scene_generator

            self._generator = scene_generator(self.cfg, self.components["object_set"])
        return self._generator

    def close(self) -> None:
        if self._generator is not None:
            self._generator.close()
            self._generator = None

