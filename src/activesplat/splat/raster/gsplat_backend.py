"""gsplat (CUDA) backend of :func:`activesplat.splat.rasterize`: a thin adapter to
``gsplat.rasterization`` (gsplat >= 1.4; ``pip install activesplat[cuda]``). Imported lazily.

Matching semantics: ``render_mode="RGB+D"`` gives the *accumulated* depth sum w_i z_i (what we want;
"RGB+ED" would divide by alpha), ``rasterize_mode="classic"``, ``eps2d=0.3`` (the low-pass),
``near_plane=0.01``, 16 px tiles, pixel centres at +0.5, colours passed directly (no SH).
Known differences from the numba/torch backends, all inside gsplat's CUDA code:
- gsplat clamps alpha at 0.999 (we use 0.99) and since 1.5 bins tiles with per-axis (and
  opacity-aware) radii; images agree to ~1e-3, not bit-for-bit.
- gsplat has no median depth: it is computed by a second, non-differentiable pass of the numba
  backend on the CPU (costs a device->host copy; exact 3DGS semantics).
- ``mask`` is applied by rendering the selected subset; radii / means2d of the others are 0.
"""

from __future__ import annotations

import torch
from torch import Tensor

from activesplat.splat.raster import RenderOutput
from activesplat.splat.raster.constants import RASTER


def rasterize_gsplat(means, quats, scales, opacities, colors, viewmat, K, width, height, background, mask):
    """Render through ``gsplat.rasterization`` (one camera) and reshape to :class:`RenderOutput`."""
    from gsplat import rasterization

    n, device = means.shape[0], means.device
    if n == 0 or (mask is not None and not bool(mask.any())):
        return _background_only(background, n, width, height, device)
    if mask is not None:
        means, quats, scales, opacities, colors = (t[mask] for t in (means, quats, scales, opacities, colors))
    f32 = [t.to(device, torch.float32) for t in (means, quats, scales, opacities, colors, viewmat, K)]
    means, quats, scales, opacities, colors, viewmat, K = f32
    bg = torch.cat([background.to(device, torch.float32), torch.zeros(1, device=device)])[None]
    render, alphas, meta = rasterization(
        means, quats, scales, opacities, colors, viewmat[None], K[None], width, height,
        near_plane=RASTER.near, eps2d=RASTER.low_pass, tile_size=RASTER.tile_size, packed=False,
        backgrounds=bg, render_mode="RGB+D", rasterize_mode="classic",
    )
    rgb, depth, alpha = render[0, ..., :3], render[0, ..., 3], alphas[0, ..., 0]
    median = _median_depth_cpu(means, quats, scales, opacities, viewmat, K, width, height).to(device)
    radii, means2d = _per_gaussian(meta, n, mask, device)
    return RenderOutput(rgb=rgb, depth=depth, alpha=alpha, median_depth=median, radii=radii,
                        means2d=means2d, depths=_view_depths(means, viewmat, n, mask))


def _background_only(background: Tensor, n: int, width: int, height: int, device) -> RenderOutput:
    zeros = torch.zeros(height, width, device=device)
    return RenderOutput(rgb=background.to(device, torch.float32).expand(height, width, 3).clone(),
                        depth=zeros, alpha=zeros.clone(), median_depth=zeros.clone(),
                        radii=torch.zeros(n, dtype=torch.int32, device=device),
                        means2d=torch.zeros(n, 2, device=device), depths=torch.zeros(n, device=device))


def _per_gaussian(meta: dict, n: int, mask: Tensor | None, device) -> tuple[Tensor, Tensor]:
    """radii (N,) int32 (max over axes when gsplat returns per-axis radii) and means2d (N,2)."""
    radii = meta["radii"][0]
    if radii.ndim == 2:  # gsplat >= 1.5: (N, 2) per-axis radii
        radii = radii.max(dim=-1).values
    means2d = meta["means2d"][0]
    if mask is None:
        return radii.to(torch.int32), means2d
    full_radii = torch.zeros(n, dtype=torch.int32, device=device)
    full_radii[mask] = radii.to(torch.int32)
    full_means2d = torch.zeros(n, 2, dtype=means2d.dtype, device=device).index_put((mask,), means2d)
    return full_radii, full_means2d


def _view_depths(means: Tensor, viewmat: Tensor, n: int, mask: Tensor | None) -> Tensor:
    z = means @ viewmat[2, :3] + viewmat[2, 3]
    if mask is None:
        return z
    return torch.zeros(n, dtype=z.dtype, device=z.device).index_put((mask,), z)


@torch.no_grad()
def _median_depth_cpu(means, quats, scales, opacities, viewmat, K, width, height) -> Tensor:
    """Median depth (T first below 0.5) from the numba backend: gsplat does not provide it."""
    from activesplat.splat.raster.numba_backend import rasterize_numba

    cpu = [t.detach().cpu() for t in (means, quats, scales, opacities)]
    colors = torch.zeros(cpu[0].shape[0], 3)
    out = rasterize_numba(*cpu, colors, viewmat.cpu(), K.cpu(), width, height, torch.zeros(3), None)
    return out.median_depth
