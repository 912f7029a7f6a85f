"""Procedural generation of SHOP-VRB2 scenes: sampling, mesh-exact placement, visibility and stability checks."""
from muble.generation.config import GeneratorConfig, register_generator_config
from muble.generation.generator import SceneGenerator

__all__ = ["GeneratorConfig", "SceneGenerator", "register_generator_config"]
