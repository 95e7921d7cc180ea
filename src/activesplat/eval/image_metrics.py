"""Per-view rendering metrics (paper sec. IV, docs/protocol.md §6): PSNR, SSIM, MS-SSIM, LPIPS, depth L1.

Colour images are (H,W,3) in [0, 1] (uint8 inputs are divided by 255; renders are clamped to [0, 1]).

- ``psnr``: 10 log10(1 / MSE) over the whole image and all three channels, data range 1.
- ``ssim``: pytorch-msssim's single-scale SSIM (11 px Gaussian window, sigma 1.5, data range 1), the
  same function the mapper's loss uses. The authors' release reports MS-SSIM instead; we report both.
- ``ms_ssim``: pytorch-msssim's MS-SSIM (5 scales, 11 px window, data range 1); it needs both image sides
  > 160 px, smaller images give None.
- ``lpips``: LPIPS v0.1 with AlexNet, inputs mapped to [-1, 1] (``activesplat.eval.lpips``).
- ``depth_l1_cm``: mean |D_render - D_gt| in cm over the pixels with valid ground-truth depth (> 0).
"""

from __future__ import annotations

import numpy as np
import torch
from pytorch_msssim import ms_ssim as _ms_ssim

from activesplat.splat.losses import ssim as _ssim

MS_SSIM_MIN_SIDE = 161
"""pytorch-msssim's MS-SSIM downsamples 4 times with an 11 px window: sides must exceed (11 - 1) * 2^4."""


def as_float_image(image) -> torch.Tensor:
    """(H,W,3) float32 tensor in [0, 1] from a uint8 array or a float array / tensor."""
    if isinstance(image, torch.Tensor):
        t = image.detach().to("cpu", torch.float32)
    else:
        a = np.asarray(image)
        t = torch.from_numpy(a.astype(np.float32) / 255.0 if a.dtype == np.uint8 else a.astype(np.float32))
    return t.clamp(0.0, 1.0)


def psnr(rgb, gt) -> float:
    """PSNR in dB of two (H,W,3) images in [0, 1] (data range 1); inf for identical images."""
    mse = float((as_float_image(rgb) - as_float_image(gt)).square().mean())
    return float("inf") if mse == 0.0 else -10.0 * float(np.log10(mse))


def ssim(rgb, gt) -> float:
    """Single-scale SSIM (pytorch-msssim, 11 px window, data range 1)."""
    return float(_ssim(as_float_image(rgb), as_float_image(gt)))


def ms_ssim(rgb, gt) -> float | None:
    """MS-SSIM (pytorch-msssim, 11 px window, data range 1), None when a side is <= 160 px."""
    x, y = as_float_image(rgb), as_float_image(gt)
    if min(x.shape[:2]) < MS_SSIM_MIN_SIDE:
        return None
    return float(_ms_ssim(x.permute(2, 0, 1)[None], y.permute(2, 0, 1)[None], data_range=1.0, win_size=11))


def depth_l1_cm(depth, gt_depth) -> float | None:
    """Mean absolute depth error in cm over pixels with valid ground-truth depth (> 0); None if there are
    none."""
    d = np.asarray(depth.detach().cpu() if isinstance(depth, torch.Tensor) else depth, dtype=np.float64)
    g = np.asarray(gt_depth, dtype=np.float64)
    valid = g > 0
    if not valid.any():
        return None
    return 100.0 * float(np.abs(d[valid] - g[valid]).mean())
