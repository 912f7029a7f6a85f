"""The MuBlE config of a Gymnasium environment: a Hydra-composed config, or one composed from overrides."""
from __future__ import annotations

from typing import Any, Sequence

from muble.core.errors import ConfigError


def _key(override: str) -> str:
    return override.split("=", 1)[0].lstrip("+~")


def environment_config(config: Any = None, overrides: Sequence[str] = (), defaults: Sequence[str] = ()) -> Any:
    """``config`` (a composed ``DictConfig`` or a plain dict of one) with ``overrides`` applied; without it, the
    ``run`` config composed with ``defaults`` then ``overrides`` (an override of the same key replaces a default).
    With ``split`` set, the split's own settings are merged in (``muble.dataset.production.with_split``), so that
    ``scene_index`` k is index k of that split as ``muble generate`` makes it.
    """
    from omegaconf import DictConfig, OmegaConf

    from muble.dataset.production import with_split

    if isinstance(overrides, str):
        raise ConfigError(f"overrides must be a list of 'key=value' strings, got the string {overrides!r:.60}")
    if config is not None:
        cfg = OmegaConf.create(config) if isinstance(config, dict) else config
        if not isinstance(cfg, DictConfig):
            raise ConfigError(f"config must be a composed MuBlE config (DictConfig or dict), got {type(config).__name__}")
        # Value overrides only: a composed config's groups (renderer=…) are chosen already.
        bad = [o for o in overrides if "=" not in o]
        if bad:
            raise ConfigError(f"overrides must be of the form key=value, got {bad}")
        cfg = OmegaConf.merge(cfg, OmegaConf.from_dotlist([o.lstrip("+") for o in overrides]))
        return with_split(cfg)
    from muble.app.config import compose

    own = {_key(o) for o in overrides}
    merged = [o for o in defaults if _key(o) not in own] + list(overrides)
    return with_split(compose("run", merged))


def generation_size(config: Any = None, overrides: Sequence[str] = ()) -> tuple[int, int]:
    """The image size ``muble generate`` makes scenes at under ``config`` and ``overrides``: the renderer size they
    name, without an environment's own default image size (``environment_config``'s ``defaults``). With
    ``split=NAME`` an environment generates that split's scenes at it, as the dataset's were, and renders them at
    its own size, as it plays stored episodes."""
    from muble.episode.components import image_size

    return image_size(environment_config(config, overrides))
