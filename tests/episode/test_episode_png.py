"""Keyframe PNGs: the fast compression level writes the same pixels as Pillow's default."""
from __future__ import annotations

import io

import numpy as np
from PIL import Image

from muble.episode.runner import PNG_COMPRESS_LEVEL, png_bytes


def test_fast_png_level_keeps_the_pixels():
    rgb = np.random.default_rng(0).integers(0, 256, size=(48, 64, 3), dtype=np.uint8)
    rgb[:, :32] = 200  # a flat half, where compression levels differ most
    fast, default = png_bytes(rgb), png_bytes(rgb, compress_level=6)
    assert PNG_COMPRESS_LEVEL == 1 and fast != default
    for data in (fast, default):
        np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(data))), rgb)
