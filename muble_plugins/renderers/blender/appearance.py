"""Image statistics of a rendered surface, used to check that material classes look different."""
from __future__ import annotations

import numpy as np
from scipy import ndimage

FEATURES = ("brightness", "contrast", "highlight", "saturation", "texture")
REC709_LUMA = np.array([0.2126, 0.7152, 0.0722])


def luma(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luma of an 8-bit RGB image, in 0..1."""
    return (rgb.astype(float) / 255.0) @ REC709_LUMA


def appearance(rgb: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    """Brightness (mean luma), contrast (luma spread), highlight (99th-percentile luma), saturation and
    texture (mean absolute Laplacian of luma) over the pixels in ``mask``, eroded by one pixel so that
    silhouette edges do not count."""
    inner = ndimage.binary_erosion(mask, iterations=1)
    if inner.sum() < 10:
        raise ValueError("mask too small to measure an appearance; render at a larger resolution")
    colour = rgb.astype(float) / 255.0
    y = luma(rgb)
    top, bottom = colour.max(axis=-1), colour.min(axis=-1)
    saturation = np.where(top > 0, (top - bottom) / np.maximum(top, 1e-6), 0.0)
    texture = np.abs(ndimage.laplace(y))
    values = y[inner]
    return {
        "brightness": float(values.mean()),
        "contrast": float(values.std()),
        "highlight": float(np.percentile(values, 99)),
        "saturation": float(saturation[inner].mean()),
        "texture": float(texture[inner].mean()),
    }


FLOOR = 0.02  # features below this are noise, so ratios are taken above it


def appearance_distance(a: dict[str, float], b: dict[str, float]) -> float:
    """The largest log-ratio over the features: 0.3 means one surface has 35 % more of something."""
    return max(abs(np.log((a[k] + FLOOR) / (b[k] + FLOOR))) for k in FEATURES)
