"""Mujoco renderer plugin (being written)."""
from dataclasses import dataclass

from muble import Renderer


@dataclass
class MujocoRendererConfig:
    width: int = 640
    height: int = 480


class MujocoRenderer(Renderer):
    def __init__(self, **options):
        self.options = options

    def setup(self, scene, model):
        raise NotImplementedError

    def render(self, data, camera):
        raise NotImplementedError
