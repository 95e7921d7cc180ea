"""Mapping losses, paper eqs. 5-7 (SplaTAM's mapping loss).

L = w_c * (lambda_1 * L1(C) + lambda_2 * (1 - SSIM(C))) + w_d * L1(D), with every term taken over the
pixels with valid observed depth (docs/protocol.md §2). SSIM is pytorch-msssim's single-scale SSIM
(11 px Gaussian window, sigma 1.5, valid convolution), computed on images whose invalid pixels are
zeroed in both prediction and observation so that they do not contribute a difference.

On the CPU (float32 images at least as large as the window) :func:`mapping_loss` computes the value and
its gradient in three fused numba passes (``_loss_numba.loss_rows`` / ``ssim_columns`` /
``loss_grad_rows``): the same formulas as the torch path (pytorch-msssim's separable valid blur, C1 =
0.01^2, C2 = 0.03^2, the masked L1 means), with the SSIM gradient written out by hand instead of going
through autograd. Elsewhere (other devices, float64, tiny images) it runs the torch reference.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
import torch
from pytorch_msssim import ssim as _ssim

from activesplat.splat.config import MapperConfig


@dataclass
class LossTerms:
    """The scalar terms of eq. 7 (``total`` is differentiable, the others are detached floats)."""

    total: torch.Tensor
    color_l1: float
    ssim: float
    depth_l1: float


def masked_l1(pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """Mean absolute error over ``valid`` pixels; ``pred``/``target`` (H,W) or (H,W,C), ``valid`` (H,W)."""
    diff = (pred - target).abs()
    if diff.dim() == 3:
        diff = diff.mean(dim=2)
    count = valid.sum().clamp_min(1)
    return (diff * valid).sum() / count


def ssim(pred: torch.Tensor, target: torch.Tensor, window: int = 11) -> torch.Tensor:
    """SSIM of two (H,W,3) images in [0,1] (data range 1), pytorch-msssim's single-scale SSIM."""
    x = pred.permute(2, 0, 1).unsqueeze(0)
    y = target.permute(2, 0, 1).unsqueeze(0)
    return _ssim(x, y, data_range=1.0, size_average=True, win_size=window)


def mapping_loss(rgb: torch.Tensor, depth: torch.Tensor, obs_rgb: torch.Tensor, obs_depth: torch.Tensor,
                 cfg: MapperConfig) -> LossTerms:
    """Eqs. 5-7: rendered ``rgb`` (H,W,3) and ``depth`` (H,W) against the observation (rgb in [0,1],
    depth in metres with 0 = invalid)."""
    if _fused_applies(rgb, depth, obs_rgb, obs_depth, cfg.ssim_window):
        return _fused_mapping_loss(rgb, depth, obs_rgb, obs_depth, cfg)
    return mapping_loss_torch(rgb, depth, obs_rgb, obs_depth, cfg)


def mapping_loss_torch(rgb: torch.Tensor, depth: torch.Tensor, obs_rgb: torch.Tensor,
                       obs_depth: torch.Tensor, cfg: MapperConfig) -> LossTerms:
    """:func:`mapping_loss` in torch autograd (any device and dtype; the reference of the fused path)."""
    valid = obs_depth > 0
    color_l1 = masked_l1(rgb, obs_rgb, valid)
    m = valid.unsqueeze(2).to(rgb.dtype)
    ssim_value = ssim(rgb * m, obs_rgb * m, cfg.ssim_window)
    depth_l1 = masked_l1(depth, obs_depth, valid)
    photometric = cfg.lambda_l1 * color_l1 + cfg.lambda_ssim * (1.0 - ssim_value)  # eq. 5
    total = cfg.weight_color * photometric + cfg.weight_depth * depth_l1  # eq. 7
    return LossTerms(total, float(color_l1.detach()), float(ssim_value.detach()), float(depth_l1.detach()))


# --------------------------------------------------------------------------- fused CPU path
SSIM_SIGMA = 1.5  # pytorch-msssim's default window sigma
SSIM_C1, SSIM_C2 = 0.01**2, 0.03**2  # (K1 data_range)^2, (K2 data_range)^2 with data_range 1


@cache
def ssim_window(size: int) -> np.ndarray:
    """pytorch-msssim's 1-D Gaussian window (``_fspecial_gauss_1d``), float32."""
    coords = torch.arange(size, dtype=torch.float) - size // 2
    g = torch.exp(-(coords**2) / (2 * SSIM_SIGMA**2))
    return (g / g.sum()).numpy()


def _fused_applies(rgb, depth, obs_rgb, obs_depth, window: int) -> bool:
    tensors = (rgb, depth, obs_rgb, obs_depth)
    if any(t.device.type != "cpu" or t.dtype != torch.float32 for t in tensors):
        return False
    h, w = obs_depth.shape[0], obs_depth.shape[-1]
    return (window % 2 == 1 and h >= window and w >= window and tuple(rgb.shape) == (h, w, 3)
            and rgb.shape == obs_rgb.shape and depth.shape == obs_depth.shape and obs_depth.dim() == 2)


def _fused_mapping_loss(rgb, depth, obs_rgb, obs_depth, cfg) -> LossTerms:
    """:func:`mapping_loss` by the numba passes; the gradient is computed with the value when rgb or depth
    needs one, and handed to autograd by :class:`_KnownGradient`."""
    from activesplat.splat._loss_numba import loss_grad_rows, loss_rows, ssim_columns

    arrays = [np.ascontiguousarray(t.detach().numpy()) for t in (rgb, depth, obs_rgb, obs_depth)]
    win = ssim_window(cfg.ssim_window)
    h, sums = loss_rows(*arrays, win)
    d, row_ssim = ssim_columns(h, win, np.float32(SSIM_C1), np.float32(SSIM_C2))
    count = max(float(sums[:, 2].sum()), 1.0)
    n_ssim = row_ssim.shape[0] * (depth.shape[1] - len(win) + 1)  # channels x output pixels of the valid blur
    color_l1, depth_l1 = float(sums[:, 0].sum()) / count, float(sums[:, 1].sum()) / count
    ssim_value = float(row_ssim.sum()) / n_ssim
    photometric = cfg.lambda_l1 * color_l1 + cfg.lambda_ssim * (1.0 - ssim_value)  # eq. 5
    total = torch.tensor(cfg.weight_color * photometric + cfg.weight_depth * depth_l1)  # eq. 7
    if torch.is_grad_enabled() and (rgb.requires_grad or depth.requires_grad):
        weights = (-cfg.weight_color * cfg.lambda_ssim / n_ssim,  # of the SSIM map sum,
                   cfg.weight_color * cfg.lambda_l1 / (3.0 * count), cfg.weight_depth / count)  # the L1 sums
        g_rgb, g_depth = loss_grad_rows(d, win, *arrays, *(np.float32(w) for w in weights))
        total = _KnownGradient.apply(rgb, depth, total, torch.from_numpy(g_rgb), torch.from_numpy(g_depth))
    return LossTerms(total, color_l1, ssim_value, depth_l1)


class _KnownGradient(torch.autograd.Function):
    """``total`` as a function of ``rgb`` and ``depth`` whose gradients are already known."""

    @staticmethod
    def forward(ctx, rgb, depth, total, g_rgb, g_depth):
        ctx.grads = (g_rgb, g_depth)
        return total.clone()

    @staticmethod
    def backward(ctx, v_total):
        g_rgb, g_depth = ctx.grads
        return g_rgb * v_total, g_depth * v_total, None, None, None
