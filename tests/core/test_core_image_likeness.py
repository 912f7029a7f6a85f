"""The frame-comparison metrics: mask IoU, SSIM, CIE L*a*b* and CIEDE2000 on inputs with known answers."""
import numpy as np
import pytest

from tests.support.image_likeness import ciede2000, mask_iou, mean_lab, srgb_to_lab, ssim

# Pairs and differences from Sharma, Wu and Dalal (2005), "The CIEDE2000 color-difference formula", table 1:
# they exercise the hue wrap-around, the neutral axis and the blue-region rotation term.
SHARMA_PAIRS = [
    ((50.0, 2.6772, -79.7751), (50.0, 0.0, -82.7485), 2.0425),
    ((50.0, 0.0, 0.0), (50.0, -1.0, 2.0), 2.3669),
    ((50.0, 2.49, -0.001), (50.0, -2.49, 0.0009), 7.1792),
    ((50.0, 2.5, 0.0), (73.0, 25.0, -18.0), 27.1492),
    ((60.2574, -34.0099, 36.2677), (60.4626, -34.1751, 39.4387), 1.2644),
    ((2.0776, 0.0795, -1.135), (0.9033, -0.0636, -0.5514), 0.9082),
]


def test_ciede2000_matches_the_published_pairs():
    first = np.array([p[0] for p in SHARMA_PAIRS])
    second = np.array([p[1] for p in SHARMA_PAIRS])
    expected = np.array([p[2] for p in SHARMA_PAIRS])
    np.testing.assert_allclose(ciede2000(first, second), expected, atol=1e-4)
    np.testing.assert_allclose(ciede2000(second, first), expected, atol=1e-4)  # symmetric
    assert ciede2000(np.array([40.0, 10.0, -5.0]), np.array([40.0, 10.0, -5.0])) == 0.0


def test_srgb_to_lab_of_known_colours():
    np.testing.assert_allclose(srgb_to_lab(np.array([255, 255, 255])), [100.0, 0.0, 0.0], atol=1e-3)
    np.testing.assert_allclose(srgb_to_lab(np.array([0, 0, 0])), [0.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(srgb_to_lab(np.array([255, 0, 0])), [53.2408, 80.0925, 67.2032], atol=1e-3)
    np.testing.assert_allclose(srgb_to_lab(np.array([0, 0, 255])), [32.2970, 79.1875, -107.8602], atol=1e-3)


def test_mask_iou():
    a = np.zeros((10, 10), bool)
    b = np.zeros((10, 10), bool)
    a[:, :6] = True  # 60 pixels
    b[:, 3:] = True  # 70 pixels, 30 shared
    assert mask_iou(a, b) == pytest.approx(30 / 100)
    assert mask_iou(a, a) == 1.0
    assert mask_iou(np.zeros((4, 4), bool), np.zeros((4, 4), bool)) == 1.0  # both empty: they agree
    with pytest.raises(ValueError, match="shapes"):
        mask_iou(a, b[:5])


def test_ssim_is_one_for_equal_images_and_falls_with_noise():
    rng = np.random.default_rng(0)
    image = (rng.random((40, 60, 3)) * 255).astype(np.uint8)
    assert ssim(image, image) == pytest.approx(1.0)
    noisy = np.clip(image + rng.normal(0, 40, image.shape), 0, 255).astype(np.uint8)
    assert ssim(image, noisy) < 0.9
    with pytest.raises(ValueError, match="shapes"):
        ssim(image, image[:20])


def test_ssim_agrees_with_scikit_image():
    metrics = pytest.importorskip("skimage.metrics")
    rng = np.random.default_rng(1)
    a = (rng.random((48, 64, 3)) * 255).astype(np.uint8)
    b = np.clip(a * 0.8 + rng.normal(0, 20, a.shape) + 20, 0, 255).astype(np.uint8)
    assert ssim(a, b) == pytest.approx(metrics.structural_similarity(a, b, channel_axis=2, data_range=255), abs=1e-6)


def test_mean_lab_inside_a_mask():
    image = np.zeros((4, 4, 3), np.uint8)
    image[:2] = 255
    mask = np.zeros((4, 4), bool)
    mask[:2] = True
    np.testing.assert_allclose(mean_lab(image, mask), [100.0, 0.0, 0.0], atol=1e-3)
    assert np.isnan(mean_lab(image, np.zeros((4, 4), bool))).all()
