"""The per-view rendering metrics against their definitions (docs/protocol.md §6), computed here by hand in
numpy: PSNR over one MSE of all three channels, SSIM with an 11 px Gaussian window (sigma 1.5) over the
valid region, depth L1 in cm over pixels with ground-truth depth, uint8 images scaled to [0, 1]."""

import math

import numpy as np
import pytest
import torch
from numpy.lib.stride_tricks import sliding_window_view

from activesplat.eval import image_metrics as im
from activesplat.eval.render_eval import RenderEvalConfig, view_metrics


def _pair(seed: int, size=(40, 48), noise=0.05):
    rng = np.random.default_rng(seed)
    gt = rng.random((*size, 3)).astype(np.float32)
    rgb = np.clip(gt + rng.normal(0, noise, gt.shape), 0, 1).astype(np.float32)
    return rgb, gt


def _ssim_by_definition(x: np.ndarray, y: np.ndarray) -> float:
    """Wang et al. 2004 with a Gaussian window (11 px, sigma 1.5), data range 1, K = (0.01, 0.03), the map
    averaged over the positions where the whole window fits and over the channels."""
    coords = np.arange(11) - 5
    g = np.exp(-coords**2 / (2 * 1.5**2))
    w = np.outer(g, g) / np.outer(g, g).sum()

    def filt(a):
        return np.einsum("ijkl,kl->ij", sliding_window_view(a, (11, 11)), w)

    c1, c2 = 0.01**2, 0.03**2
    values = []
    for c in range(3):
        a, b = x[..., c].astype(np.float64), y[..., c].astype(np.float64)
        ma, mb = filt(a), filt(b)
        saa, sbb, sab = filt(a * a) - ma**2, filt(b * b) - mb**2, filt(a * b) - ma * mb
        s = ((2 * ma * mb + c1) * (2 * sab + c2)) / ((ma**2 + mb**2 + c1) * (saa + sbb + c2))
        values.append(s.mean())
    return float(np.mean(values))


def test_psnr_is_one_mse_over_all_three_channels():
    rgb, gt = _pair(0)
    mse = np.mean((rgb.astype(np.float64) - gt) ** 2)
    assert im.psnr(rgb, gt) == pytest.approx(10 * math.log10(1 / mse), abs=1e-4)
    # channels with very different errors: the pooled MSE, not the mean of per-channel PSNRs (the
    # convention of the release's SplaTAM helpers, which reads higher)
    skewed = gt.copy()
    skewed[..., 0] = np.clip(gt[..., 0] + 0.2, 0, 1)
    pooled = 10 * math.log10(1 / np.mean((skewed.astype(np.float64) - gt) ** 2))
    diff = skewed.astype(np.float64) - gt
    channel_mse = [max(np.mean(diff[..., c] ** 2), 1e-12) for c in range(3)]
    per_channel = np.mean([10 * math.log10(1 / e) for e in channel_mse])
    assert im.psnr(skewed, gt) == pytest.approx(pooled, abs=1e-4)
    assert per_channel > pooled + 10
    assert im.psnr(gt, gt) == float("inf")


def test_ssim_is_the_gaussian_window_definition():
    for seed, noise in ((1, 0.02), (2, 0.2)):
        rgb, gt = _pair(seed, noise=noise)
        assert im.ssim(rgb, gt) == pytest.approx(_ssim_by_definition(rgb, gt), abs=2e-6)
    assert im.ssim(gt, gt) == pytest.approx(1.0, abs=1e-6)


def test_ms_ssim_is_pytorch_msssim_with_data_range_one_and_none_on_small_images():
    from pytorch_msssim import ms_ssim

    rgb, gt = _pair(3, size=(176, 168), noise=0.1)
    nchw = [torch.from_numpy(a).permute(2, 0, 1)[None] for a in (rgb, gt)]
    assert im.ms_ssim(rgb, gt) == pytest.approx(float(ms_ssim(*nchw, data_range=1.0, win_size=11)), abs=1e-6)
    assert im.ms_ssim(*_pair(4, size=(160, 200))) is None


def test_depth_l1_is_in_cm_over_pixels_with_ground_truth_depth():
    rng = np.random.default_rng(5)
    gt = rng.uniform(0.5, 5.0, (30, 30))
    gt[:7] = 0.0  # no ground-truth depth there: left out whatever is rendered
    depth = gt + rng.normal(0, 0.1, gt.shape)
    depth[:7] = 9.0
    valid = gt > 0
    by_hand = 100 * np.abs(depth[valid] - gt[valid]).mean()
    assert im.depth_l1_cm(depth, gt) == pytest.approx(by_hand, rel=1e-12)
    assert im.depth_l1_cm(torch.from_numpy(depth), gt) == pytest.approx(im.depth_l1_cm(depth, gt))
    assert im.depth_l1_cm(depth, np.zeros_like(gt)) is None


def test_uint8_images_are_divided_by_255():
    rgb, gt = _pair(6)
    rgb8, gt8 = ((a * 255).round().astype(np.uint8) for a in (rgb, gt))
    assert im.psnr(rgb8, gt8) == pytest.approx(im.psnr(rgb8 / 255.0, gt8 / 255.0), abs=1e-4)
    assert im.ssim(rgb8, gt8) == pytest.approx(im.ssim(rgb8 / 255.0, gt8 / 255.0), abs=1e-6)


def test_view_metrics_take_the_simulator_uint8_ground_truth_and_cap_psnr():
    rgb, gt = _pair(7)
    gt8 = (gt * 255).round().astype(np.uint8)
    depth = np.full(gt.shape[:2], 2.0)
    alpha = np.ones(gt.shape[:2])
    alpha[:10] = 0.2
    m = view_metrics(rgb, depth, alpha, gt8, depth + 0.03, RenderEvalConfig(), lpips=False)
    assert m["psnr"] == pytest.approx(im.psnr(rgb, gt8 / 255.0), abs=1e-4)
    assert m["depth_l1_cm"] == pytest.approx(3.0)
    assert m["unmapped_pct"] == pytest.approx(100.0 * 10 / gt.shape[0])
    assert m["lpips"] is None
    same = view_metrics(gt8 / 255.0, depth, alpha, gt8, depth, RenderEvalConfig(), lpips=False)
    assert same["psnr"] == pytest.approx(100.0)
