"""Losses of eqs. 5-7 against independent computations."""

import numpy as np
import torch

from activesplat.splat.config import MapperConfig
from activesplat.splat.losses import mapping_loss, masked_l1, ssim


def _ssim_numpy(x: np.ndarray, y: np.ndarray) -> float:
    """Independent single-scale SSIM: 11-tap Gaussian (sigma 1.5), valid window, C1/C2 of Wang et al."""
    g = np.exp(-((np.arange(11) - 5.0) ** 2) / (2 * 1.5**2))
    g /= g.sum()

    def blur(a):  # separable valid convolution over (H, W) for each channel
        a = np.apply_along_axis(lambda r: np.convolve(r, g, mode="valid"), 0, a)
        return np.apply_along_axis(lambda r: np.convolve(r, g, mode="valid"), 1, a)

    c1, c2 = 0.01**2, 0.03**2
    mx, my = blur(x), blur(y)
    sxx, syy, sxy = blur(x * x) - mx**2, blur(y * y) - my**2, blur(x * y) - mx * my
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx**2 + my**2 + c1) * (sxx + syy + c2))
    return float(s.mean())


def test_ssim_matches_independent_implementation():
    rng = np.random.default_rng(0)
    x = rng.random((32, 40, 3))
    y = np.clip(x + 0.1 * rng.standard_normal(x.shape), 0, 1)
    got = ssim(torch.tensor(x, dtype=torch.float64), torch.tensor(y, dtype=torch.float64)).item()
    assert abs(got - _ssim_numpy(x, y)) < 1e-6
    assert abs(ssim(torch.tensor(x), torch.tensor(x)).item() - 1.0) < 1e-6


def test_masked_l1_ignores_invalid_pixels():
    pred = torch.zeros(4, 4)
    target = torch.ones(4, 4)
    target[0, 0] = 100.0
    valid = torch.ones(4, 4, dtype=torch.bool)
    valid[0, 0] = False
    assert masked_l1(pred, target, valid).item() == 1.0
    assert masked_l1(pred, target, torch.zeros(4, 4, dtype=torch.bool)).item() == 0.0


def test_mapping_loss_weights_eq7():
    rng = np.random.default_rng(1)
    obs_rgb = torch.tensor(rng.random((24, 24, 3)), dtype=torch.float32)
    rgb = (obs_rgb + 0.05 * torch.tensor(rng.standard_normal((24, 24, 3)), dtype=torch.float32)).clamp(0, 1)
    obs_depth = torch.tensor(rng.random((24, 24)) + 1.0, dtype=torch.float32)
    obs_depth[:3] = 0.0  # invalid rows
    depth = obs_depth + 0.2
    depth[:3] = 55.0  # ignored
    cfg = MapperConfig()
    terms = mapping_loss(rgb, depth, obs_rgb, obs_depth, cfg)
    valid = obs_depth > 0
    l1 = (rgb - obs_rgb).abs().mean(dim=2)[valid].mean().item()
    m = valid.unsqueeze(2).float()
    s = ssim(rgb * m, obs_rgb * m).item()
    expected = 0.5 * (0.8 * l1 + 0.2 * (1 - s)) + 1.0 * 0.2
    assert abs(terms.depth_l1 - 0.2) < 1e-5
    assert abs(terms.color_l1 - l1) < 1e-6
    assert abs(terms.total.item() - expected) < 1e-5


def test_mapping_loss_is_differentiable():
    obs_rgb = torch.rand(16, 16, 3, generator=torch.Generator().manual_seed(0))
    rgb = torch.full((16, 16, 3), 0.5, requires_grad=True)
    depth = torch.full((16, 16), 2.0, requires_grad=True)
    terms = mapping_loss(rgb, depth, obs_rgb, torch.ones(16, 16), MapperConfig())
    terms.total.backward()
    assert rgb.grad is not None and rgb.grad.abs().sum() > 0
    assert torch.allclose(depth.grad, torch.full((16, 16), 1.0 / 256))
