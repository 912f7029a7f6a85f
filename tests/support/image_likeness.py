"""How alike two renders of one scene are: mask overlap, structural similarity and colour difference.

Plain numpy and scipy, so a benchmark or test that compares frames needs no image library:

- ``mask_iou``: intersection over union of two boolean masks;
- ``ssim``: the structural similarity of two 8-bit images, with scikit-image's defaults (7x7 uniform window,
  K1 0.01, K2 0.03, sample covariances, the mean over channels), so figures agree with ``render_quality.py``'s;
- ``srgb_to_lab`` and ``ciede2000``: CIE L*a*b* under D65 and the CIEDE2000 colour difference (Sharma, Wu and
  Dalal 2005), where about 1 is a just-noticeable difference and 10 a clearly different shade;
- ``mean_lab``: the mean L*a*b* colour of an image inside a mask.
"""
from __future__ import annotations

import numpy as np

SSIM_WINDOW = 7  # scikit-image's default window
SSIM_K1, SSIM_K2 = 0.01, 0.03
D65_WHITE = np.array([0.95047, 1.0, 1.08883])  # reference white of sRGB, XYZ with Y = 1
SRGB_TO_XYZ = np.array([[0.4124564, 0.3575761, 0.1804375],
                        [0.2126729, 0.7151522, 0.0721750],
                        [0.0193339, 0.1191920, 0.9503041]])


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boolean masks of one shape; 1.0 when both are empty (they agree)."""
    a, b = np.asarray(a, dtype=bool), np.asarray(b, dtype=bool)
    if a.shape != b.shape:
        raise ValueError(f"masks of different shapes {a.shape} and {b.shape}")
    union = np.count_nonzero(a | b)
    return 1.0 if union == 0 else np.count_nonzero(a & b) / union


def _ssim_channel(x: np.ndarray, y: np.ndarray, data_range: float) -> float:
    from scipy.ndimage import uniform_filter

    n = SSIM_WINDOW**2
    unbias = n / (n - 1)  # sample (not population) covariances, as scikit-image's default
    mean = {k: uniform_filter(v, SSIM_WINDOW) for k, v in (("x", x), ("y", y), ("xx", x * x), ("yy", y * y),
                                                           ("xy", x * y))}
    vx = unbias * (mean["xx"] - mean["x"] ** 2)
    vy = unbias * (mean["yy"] - mean["y"] ** 2)
    cxy = unbias * (mean["xy"] - mean["x"] * mean["y"])
    c1, c2 = (SSIM_K1 * data_range) ** 2, (SSIM_K2 * data_range) ** 2
    s = ((2 * mean["x"] * mean["y"] + c1) * (2 * cxy + c2)
         / ((mean["x"] ** 2 + mean["y"] ** 2 + c1) * (vx + vy + c2)))
    pad = (SSIM_WINDOW - 1) // 2  # the border, where the window leaves the image, is left out
    return float(s[pad:-pad, pad:-pad].mean())


def ssim(a: np.ndarray, b: np.ndarray, data_range: float = 255.0) -> float:
    """Structural similarity of two images (H, W) or (H, W, C) of one shape: the mean over channels."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"images of different shapes {a.shape} and {b.shape}")
    if min(a.shape[:2]) < SSIM_WINDOW:
        raise ValueError(f"images of {a.shape[1]}x{a.shape[0]} are smaller than the {SSIM_WINDOW}-pixel window")
    if a.ndim == 2:
        return _ssim_channel(a, b, data_range)
    return float(np.mean([_ssim_channel(a[..., c], b[..., c], data_range) for c in range(a.shape[2])]))


def srgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    """CIE L*a*b* (D65) of 8-bit sRGB colours, shape (..., 3) -> (..., 3)."""
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    xyz = linear @ SRGB_TO_XYZ.T / D65_WHITE
    eps, kappa = 216 / 24389, 24389 / 27
    f = np.where(xyz > eps, np.cbrt(xyz), (kappa * xyz + 16) / 116)
    return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])], axis=-1)


def ciede2000(lab1: np.ndarray, lab2: np.ndarray) -> np.ndarray:
    """CIEDE2000 difference of L*a*b* colours (..., 3), with kL = kC = kH = 1."""
    l1, a1, b1 = np.moveaxis(np.asarray(lab1, dtype=np.float64), -1, 0)
    l2, a2, b2 = np.moveaxis(np.asarray(lab2, dtype=np.float64), -1, 0)
    c_bar = (np.hypot(a1, b1) + np.hypot(a2, b2)) / 2
    g = 0.5 * (1 - np.sqrt(c_bar**7 / (c_bar**7 + 25.0**7)))
    a1p, a2p = (1 + g) * a1, (1 + g) * a2
    c1p, c2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.degrees(np.arctan2(b1, a1p)) % 360
    h2p = np.degrees(np.arctan2(b2, a2p)) % 360
    chroma_zero = (c1p * c2p) == 0
    dlp, dcp = l2 - l1, c2p - c1p
    dh = h2p - h1p
    dh = np.where(dh > 180, dh - 360, np.where(dh < -180, dh + 360, dh))
    dh = np.where(chroma_zero, 0.0, dh)
    dhp = 2 * np.sqrt(c1p * c2p) * np.sin(np.radians(dh) / 2)
    lp_bar, cp_bar = (l1 + l2) / 2, (c1p + c2p) / 2
    h_sum = h1p + h2p
    hp_bar = np.where(np.abs(h1p - h2p) <= 180, h_sum / 2,
                      np.where(h_sum < 360, (h_sum + 360) / 2, (h_sum - 360) / 2))
    hp_bar = np.where(chroma_zero, h_sum, hp_bar)
    t = (1 - 0.17 * np.cos(np.radians(hp_bar - 30)) + 0.24 * np.cos(np.radians(2 * hp_bar))
         + 0.32 * np.cos(np.radians(3 * hp_bar + 6)) - 0.20 * np.cos(np.radians(4 * hp_bar - 63)))
    d_theta = 30 * np.exp(-(((hp_bar - 275) / 25) ** 2))
    r_c = 2 * np.sqrt(cp_bar**7 / (cp_bar**7 + 25.0**7))
    s_l = 1 + 0.015 * (lp_bar - 50) ** 2 / np.sqrt(20 + (lp_bar - 50) ** 2)
    s_c = 1 + 0.045 * cp_bar
    s_h = 1 + 0.015 * cp_bar * t
    r_t = -np.sin(np.radians(2 * d_theta)) * r_c
    return np.sqrt((dlp / s_l) ** 2 + (dcp / s_c) ** 2 + (dhp / s_h) ** 2 + r_t * (dcp / s_c) * (dhp / s_h))


def mean_lab(rgb: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Mean L*a*b* of an 8-bit sRGB image's pixels inside ``mask``; NaN where the mask is empty."""
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return np.full(3, np.nan)
    return srgb_to_lab(np.asarray(rgb)[mask]).mean(axis=0)
