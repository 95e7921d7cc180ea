"""Losses of eqs. 5-7 against independent computations."""

import numpy as np
import pytest
import torch

from activesplat.splat.config import MapperConfig
from activesplat.splat.losses import mapping_loss, mapping_loss_torch, masked_l1, ssim


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


def _loss_case(seed: int, h: int, w: int):
    """Random rendered / observed images with about 20 % invalid depth pixels and an invalid corner."""
    g = torch.Generator().manual_seed(seed)
    obs_rgb = torch.rand(h, w, 3, generator=g)
    rgb = (obs_rgb + 0.1 * torch.randn(h, w, 3, generator=g)).clamp(0, 1)
    obs_depth = torch.rand(h, w, generator=g) + 1.0
    obs_depth[torch.rand(h, w, generator=g) < 0.2] = 0.0
    obs_depth[:4, :6] = 0.0
    depth = obs_depth + 0.05 * torch.randn(h, w, generator=g)
    depth[0, 0] = obs_depth[0, 0]  # a zero difference: the L1 gradient there is 0, as torch's abs
    return rgb, depth, obs_rgb, obs_depth


def _value_and_grads(fn, rgb, depth, obs_rgb, obs_depth, cfg, dtype=torch.float32):
    r = rgb.to(dtype).detach().requires_grad_(True)
    d = depth.to(dtype).detach().requires_grad_(True)
    terms = fn(r, d, obs_rgb.to(dtype), obs_depth.to(dtype), cfg)
    terms.total.backward()
    return terms, r.grad.double(), d.grad.double()


@pytest.mark.parametrize("h,w", [(64, 80), (256, 256), (11, 11), (12, 31)])
def test_fused_mapping_loss_matches_pytorch_msssim(h, w):
    """The numba loss (value, terms, gradients) against the torch reference (pytorch-msssim) in float64,
    with masked pixels; as close as the float32 torch path itself is."""
    cfg = MapperConfig()
    case = _loss_case(h * w, h, w)
    fused, g_rgb, g_depth = _value_and_grads(mapping_loss, *case, cfg)
    ref, r_rgb, r_depth = _value_and_grads(mapping_loss_torch, *case, cfg, torch.float64)
    assert abs(fused.total.item() - ref.total.item()) < 1e-6
    assert abs(fused.ssim - ref.ssim) < 1e-6
    assert abs(fused.color_l1 - ref.color_l1) < 1e-6
    assert abs(fused.depth_l1 - ref.depth_l1) < 1e-6
    assert (g_rgb - r_rgb).abs().max() < 1e-5 * r_rgb.abs().max()
    assert (g_depth - r_depth).abs().max() < 1e-5 * r_depth.abs().max()
    valid = case[3] > 0
    assert (g_rgb[~valid] == 0).all() and (g_depth[~valid] == 0).all()


def test_fused_mapping_loss_scales_the_incoming_gradient_and_skips_without_grad():
    cfg = MapperConfig(ssim_window=7, lambda_ssim=0.5, lambda_l1=0.5, weight_depth=2.0)
    case = _loss_case(3, 20, 24)
    rgb = case[0].clone().requires_grad_(True)
    terms = mapping_loss(rgb, case[1], case[2], case[3], cfg)
    (3.0 * terms.total).backward()
    r = case[0].clone().requires_grad_(True)
    ref = mapping_loss_torch(r, case[1], case[2], case[3], cfg)
    (3.0 * ref.total).backward()
    assert abs(terms.total.item() - ref.total.item()) < 1e-6
    assert torch.allclose(rgb.grad, r.grad, rtol=1e-4, atol=1e-5 * r.grad.abs().max().item())
    with torch.no_grad():
        value = mapping_loss(*case, cfg).total
    assert value.grad_fn is None and abs(value.item() - ref.total.item()) < 1e-6


def test_mapping_loss_falls_back_to_torch_on_small_images():
    """Images smaller than the window: pytorch-msssim skips the blur along that axis (with a warning)."""
    case = _loss_case(5, 8, 30)
    with pytest.warns(UserWarning, match="Skipping Gaussian Smoothing"):
        terms = mapping_loss(*case, MapperConfig())
        ref = mapping_loss_torch(*case, MapperConfig())
    assert terms.total.item() == ref.total.item()
