"""The contact sheet: one PNG tile per scene, drawn from the scene graphs."""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from muble import get_registry
from muble.generation import SceneGenerator
from muble.generation.contact_sheet import write_contact_sheet
from tests.generation.builtin import BUILTIN

pytestmark = pytest.mark.gl


def test_contact_sheet_tiles_every_scene(tmp_path):
    object_set = get_registry().create("object_set", "shopvrb2")
    generator = SceneGenerator({**BUILTIN, "stability": False}, seed=1, object_set=object_set)
    try:
        scenes = [generator.generate(i) for i in range(3)]
    finally:
        generator.close()
    path = write_contact_sheet(tmp_path / "sheet.png", scenes, object_set, "mujoco",
                               {"depth": False, "segmentation": False}, columns=2, scale=0.25)
    image = np.asarray(Image.open(path))
    assert image.shape == (2 * 120, 2 * 212, 3)
    tiles = [image[:120, :212], image[:120, 212:], image[120:, :212]]
    assert all(t.std() > 10 for t in tiles)  # each drawn tile shows a table and objects
    assert (image[120:, 212:] == 255).all()  # the fourth cell stays empty
