"""Mapping losses, paper eqs. 5-7 (SplaTAM's mapping loss).

L = w_c * (lambda_1 * L1(C) + lambda_2 * (1 - SSIM(C))) + w_d * L1(D), with every term taken over the
pixels with valid observed depth (docs/protocol.md §2). SSIM is pytorch-msssim's single-scale SSIM
(11 px Gaussian window, sigma 1.5, valid convolution), computed on images whose invalid pixels are
zeroed in both prediction and observation so that they do not contribute a difference.
"""

from __future__ import annotations

from dataclasses import dataclass

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
    valid = obs_depth > 0
    color_l1 = masked_l1(rgb, obs_rgb, valid)
    m = valid.unsqueeze(2).to(rgb.dtype)
    ssim_value = ssim(rgb * m, obs_rgb * m, cfg.ssim_window)
    depth_l1 = masked_l1(depth, obs_depth, valid)
    photometric = cfg.lambda_l1 * color_l1 + cfg.lambda_ssim * (1.0 - ssim_value)  # eq. 5
    total = cfg.weight_color * photometric + cfg.weight_depth * depth_l1  # eq. 7
    return LossTerms(total, float(color_l1.detach()), float(ssim_value.detach()), float(depth_l1.detach()))
