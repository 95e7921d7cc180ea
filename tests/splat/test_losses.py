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


def _plain_loss_passes(rgb, depth, obs_rgb, obs_depth, win, c1, c2, weights):
    """The three passes of the fused loss as plain numpy float32 loops, each sum taken in the kernels'
    order (tap k = 0, 1, ... from 0): the blurred X, Y, XX, YY, XY, the SSIM derivatives, dL/drgb and
    dL/ddepth."""
    height, width = depth.shape
    nw = len(win)
    ho, wo = height - nw + 1, width - nw + 1
    ok = obs_depth > 0
    x = np.where(ok[..., None], rgb, np.float32(0.0)).transpose(2, 0, 1)
    y = np.where(ok[..., None], obs_rgb, np.float32(0.0)).transpose(2, 0, 1)
    h = np.zeros((5, 3, height, wo), np.float32)
    for q, src in enumerate((x, y, x * x, y * y, x * y)):
        for k in range(nw):
            h[q] += win[k] * src[:, :, k:k + wo]
    acc = np.zeros((5, 3, ho, wo), np.float32)
    for k in range(nw):
        acc += win[k] * h[:, :, k:k + ho]
    m1, m2 = acc[0], acc[1]
    s11, s22, s12 = acc[2] - m1 * m1, acc[3] - m2 * m2, acc[4] - m1 * m2
    two, one = np.float32(2.0), np.float32(1.0)
    a1, b1 = two * m1 * m2 + c1, m1 * m1 + m2 * m2 + c1
    a2, b2 = two * s12 + c2, s11 + s22 + c2
    inv = one / (b1 * b2)
    ssim = a1 * a2 * inv
    d = np.stack([two * m2 * (a2 - a1) * inv - two * m1 * ssim * (one / b1 - one / b2), -ssim / b2,
                  two * a1 * inv])
    col = np.zeros((3, 3, height, wo), np.float32)
    for k in range(nw):
        col[:, :, k:k + ho] += win[k] * d
    full = np.zeros((3, 3, height, width), np.float32)
    for k in range(nw):
        full[..., k:k + wo] += win[k] * col
    w_ssim, w_color, w_depth = weights
    gx = w_ssim * (full[0] + two * x * full[1] + y * full[2])
    g_rgb = np.where(ok, gx + w_color * np.sign(rgb - obs_rgb).transpose(2, 0, 1), np.float32(0.0))
    g_depth = np.where(ok, w_depth * np.sign(depth - obs_depth), np.float32(0.0))
    return h, d, g_rgb.transpose(1, 2, 0), g_depth


@pytest.mark.parametrize("window", [11, 7])
def test_fused_loss_passes_are_the_plain_loops_bit_for_bit(window):
    """The numba passes (registers over the taps for the default 11-tap window, plain loops otherwise, a
    zero border for the transposed blurs) add the same float32 products in the same order as plain loops:
    every intermediate and gradient is the same bit for bit, also where pixels are invalid."""
    from activesplat.splat._loss_numba import loss_grad_rows, loss_rows, ssim_columns
    from activesplat.splat.losses import SSIM_C1, SSIM_C2, ssim_window

    arrays = [t.numpy() for t in _loss_case(window, 37, 45)]
    arrays[0][5, 7] = arrays[2][5, 7]  # a zero colour difference: sign 0
    win = ssim_window(window)
    c1, c2 = np.float32(SSIM_C1), np.float32(SSIM_C2)
    weights = (np.float32(-0.01), np.float32(0.002), np.float32(0.003))
    h, sums = loss_rows(*arrays, win)
    d, _ = ssim_columns(h, win, c1, c2)
    g_rgb, g_depth = loss_grad_rows(d, win, *arrays, *weights)
    want_h, want_d, want_rgb, want_depth = _plain_loss_passes(*arrays, win, c1, c2, weights)
    p = window - 1
    inner = np.zeros(d.shape, bool)
    inner[:, :, p:-p, p:-p] = True
    assert np.array_equal(h, want_h) and np.array_equal(d[:, :, p:-p, p:-p], want_d)
    assert not d[~inner].any()  # the border the transposed blurs read is zero
    assert np.array_equal(g_rgb, want_rgb) and np.array_equal(g_depth, want_depth)
    assert int(sums[:, 2].sum()) == int((arrays[3] > 0).sum())
