"""Hydra configuration groups of MuBlE (installed as ``muble_conf``)."""
from __future__ import annotations

from pathlib import Path
from typing import Any


def group_defaults(group: str, option: str) -> dict[str, Any]:
    """The values ``<group>/<option>.yaml`` sets itself (no ``defaults`` list, no ``${…}`` interpolations): for
    code that builds one part without composing a whole config, e.g.
    ``SceneGenerator({**group_defaults("generator", "shopvrb2"), "object_set": "shopvrb2"})``."""
    import yaml

    data = yaml.safe_load((Path(__file__).parent / group / f"{option}.yaml").read_text()) or {}
    return {k: v for k, v in data.items()
            if k != "defaults" and not (isinstance(v, str) and v.startswith("${"))}
