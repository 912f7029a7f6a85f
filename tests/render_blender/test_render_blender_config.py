"""The renderer's yaml extends its schema: defaults compose, typos are errors, the registry builds it."""
from pathlib import Path

import pytest
from omegaconf import OmegaConf
from omegaconf.errors import ConfigKeyError

import muble_conf
from muble_plugins.renderers.blender import BlenderRenderer, BlenderRendererConfig

YAML = Path(muble_conf.__file__).parent / "renderer" / "blender.yaml"


def _composed(**overrides):
    schema = OmegaConf.structured(BlenderRendererConfig)
    values = OmegaConf.load(YAML)
    values.pop("defaults")
    return OmegaConf.merge(schema, values, overrides)


def test_yaml_extends_the_schema():
    cfg = _composed()
    assert (cfg.width, cfg.height, cfg.engine, cfg.device) == (848, 480, "CYCLES", "CPU")
    with pytest.raises(ConfigKeyError):
        _composed(sampels=8)


def test_registry_builds_the_renderer_without_importing_blender():
    import sys

    from muble import get_registry

    blender_loaded_before = "bpy" in sys.modules
    renderer = get_registry().create("renderer", "blender", {"width": 64, "height": 48, "samples": 2})
    assert isinstance(renderer, BlenderRenderer)
    assert renderer.config.samples == 2
    if not blender_loaded_before:  # Blender loads in setup(), never when the plugin is built
        assert "bpy" not in sys.modules
