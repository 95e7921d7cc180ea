"""gsplat (CUDA) backend of :func:`activesplat.splat.rasterize`: an adapter to gsplat's projection,
tile intersection and blending kernels (gsplat 1.5; ``pip install activesplat[cuda]``). Imported lazily.

Matching semantics: the depth channel is blended like a colour, giving the *accumulated* depth sum
w_i z_i (what we want; gsplat's "RGB+ED" would divide by alpha), classic 3DGS (no antialiasing
compensation), ``eps2d=0.3`` (the low-pass), ``near_plane=0.01``, 16 px tiles, pixel centres at +0.5,
colours passed directly (no SH).
Known differences from the numba/torch backends, all inside gsplat's CUDA code:
- gsplat clamps alpha at 0.999 (we use 0.99) and since 1.5 bins tiles with per-axis (and
  opacity-aware) radii; images agree to 3e-3 at worst, gradients to 4.3e-4 relative (docs/gpu.md).
- gsplat has no median depth: a small Triton kernel (:mod:`median_triton`) walks the tile lists
  gsplat built for the same call, with this project's blending rules; without Triton (CPU-only
  PyTorch builds) a second, non-differentiable pass of the numba backend on the CPU gives it.
- ``mask`` is applied by rendering the selected subset; radii / means2d of the others are 0.
- CPU inputs are rendered on the GPU and the outputs moved back (gradients flow through the copies);
  the mapper, render-eval and refinement keep their maps on the GPU so that nothing is copied.
"""

from __future__ import annotations

from dataclasses import fields

import torch
from torch import Tensor

from activesplat.splat.raster import RenderOutput
from activesplat.splat.raster.constants import RASTER
from activesplat.splat.raster.planar import depth_slopes


def rasterize_gsplat(means, quats, scales, opacities, colors, viewmat, K, width, height, background, mask,
                     planar_depth: bool = False):
    """Render through gsplat's CUDA kernels (one camera) into a :class:`RenderOutput`."""
    if means.device.type != "cuda":  # CPU tensors: render on the GPU, outputs (and gradients) come back
        out = rasterize_gsplat(*(t.cuda() for t in (means, quats, scales, opacities, colors, viewmat, K)),
                               width, height, background.cuda(), None if mask is None else mask.cuda(),
                               planar_depth)
        return RenderOutput(**{f.name: getattr(out, f.name).to(means.device) for f in fields(out)})
    n, device = means.shape[0], means.device
    # the view depth of every Gaussian asked for, drawn or not (as numba); 0 outside the caller's mask
    depths = means.float() @ viewmat[2, :3].float() + viewmat[2, 3].float()
    if mask is not None:
        depths = torch.where(mask, depths, torch.zeros_like(depths))
    if n and RASTER.clamp_cull_depth > 0.0:  # gsplat clamps the Jacobian instead; cull as the others do
        clamped = ~_inside_clamp(means, viewmat, K, width, height)
        if bool(clamped.any()):  # else no mask: the subset copy costs a few ms on a large map
            mask = ~clamped if mask is None else mask & ~clamped
    if n == 0 or (mask is not None and not bool(mask.any())):
        out = _background_only(background, n, width, height, device)
        out.depths = depths
        return out
    if mask is not None:
        means, quats, scales, opacities, colors = (t[mask] for t in (means, quats, scales, opacities, colors))
    f32 = [t.to(device, torch.float32) for t in (means, quats, scales, opacities, colors, viewmat, K)]
    means, quats, scales, opacities, colors, viewmat, K = f32
    n_extra = 3 if planar_depth else 1
    bg = torch.cat([background.to(device, torch.float32), torch.zeros(n_extra, device=device)])[None]
    rgbd, alphas, radii, means2d, meta = _render(means, quats, scales, opacities, colors, viewmat, K, width,
                                                 height, bg, planar_depth)
    median = _median_depth(meta, means, quats, scales, opacities, viewmat, K, width, height,
                           planar_depth).to(device)
    depth = _planar_depth_image(rgbd) if planar_depth else rgbd[..., 3]
    radii, means2d = _per_gaussian(radii, means2d, n, mask, device)
    return RenderOutput(rgb=rgbd[..., :3], depth=depth, alpha=alphas[..., 0], median_depth=median,
                        radii=radii, means2d=means2d, depths=depths)


def _inside_clamp(means: Tensor, viewmat: Tensor, K: Tensor, width: int, height: int) -> Tensor:
    """(N,) bool: drawn by the clamp rule (``RASTER.clamp_cull_depth``, ``torch_ref.inside_clamp``;
    Gaussians behind the near plane count as inside, gsplat culls them itself)."""
    from activesplat.splat.raster.torch_ref import inside_clamp

    with torch.no_grad():
        p = means.detach().float() @ viewmat[:3, :3].float().T + viewmat[:3, 3].float()
        z = p[:, 2]
        front = z > RASTER.near
        safe_z = torch.where(front, z, torch.ones_like(z))
        return ~front | inside_clamp(p[:, 0], p[:, 1], safe_z, K, width, height)


def _render(means, quats, scales, opacities, colors, viewmat, K, width, height, bg, planar_depth=False):
    """gsplat's projection, tile intersection and blending for one camera (what ``gsplat.rasterization``
    does with ``render_mode="RGB+D"``, classic mode, unpacked), called step by step so that the returned
    (N, 2) ``means2d`` is the tensor the blending reads: its ``.grad`` after backward is the 2D-mean
    gradient 3DGS densification uses. Returns ((H,W,4) colour + depth sum, (H,W,1) alpha, (N,2) radii,
    (N,2) means2d, the tile lists for the median depth).

    With ``planar_depth`` the Gaussian's depth at pixel x is z + p . (x - mean2d) (:mod:`.planar`): a
    sum of per-Gaussian features times 1, u and v, so gsplat blends the three features z - p . mean2d,
    p_u, p_v (channels 3-5) and :func:`_planar_depth_image` combines them."""
    from gsplat import fully_fused_projection, isect_offset_encode, isect_tiles, rasterize_to_pixels

    tile = RASTER.tile_size
    radii, means2d, depths, conics, _ = fully_fused_projection(
        means, None, quats, scales, viewmat[None], K[None], width, height, eps2d=RASTER.low_pass,
        near_plane=RASTER.near, opacities=opacities)
    tiles_x, tiles_y = -(-width // tile), -(-height // tile)
    _, isect_ids, flatten_ids = isect_tiles(means2d, radii, depths, tile, tiles_x, tiles_y, n_images=1)
    offsets = isect_offset_encode(isect_ids, 1, tiles_x, tiles_y)
    m2d = means2d[0]
    meta = {"means2d": means2d, "conics": conics, "opacities": opacities[None], "depths": depths,
            "isect_offsets": offsets, "flatten_ids": flatten_ids, "tile_width": tiles_x,
            "tile_height": tiles_y, "tile_size": tile}
    if planar_depth:
        slopes = depth_slopes(means, quats, scales, viewmat, K, scalar_radii(radii[0]))
        offset = depths[0] - (slopes * m2d).sum(dim=-1)
        features = torch.cat([colors, offset[:, None], slopes], dim=-1)[None]
        meta["slopes"] = slopes[None]  # the median kernel's (no slopes: centre depths)
    else:
        features = torch.cat([colors, depths[0, :, None]], dim=-1)[None]
    rgbd, alphas = rasterize_to_pixels(m2d[None], conics, features, opacities[None], width, height, tile,
                                       offsets, flatten_ids, backgrounds=bg)
    return rgbd[0], alphas[0], radii[0], m2d, meta


def _planar_depth_image(features: Tensor) -> Tensor:
    """(H, W) depth from the blended planar-depth features (channels 3-5 of (H, W, 6)) at the pixel
    centres (j + 0.5, i + 0.5)."""
    h, w = features.shape[:2]
    u = torch.arange(w, device=features.device, dtype=features.dtype) + 0.5
    v = torch.arange(h, device=features.device, dtype=features.dtype) + 0.5
    return features[..., 3] + u[None, :] * features[..., 4] + v[:, None] * features[..., 5]


def _background_only(background: Tensor, n: int, width: int, height: int, device) -> RenderOutput:
    zeros = torch.zeros(height, width, device=device)
    return RenderOutput(rgb=background.to(device, torch.float32).expand(height, width, 3).clone(),
                        depth=zeros, alpha=zeros.clone(), median_depth=zeros.clone(),
                        radii=torch.zeros(n, dtype=torch.int32, device=device),
                        means2d=torch.zeros(n, 2, device=device), depths=torch.zeros(n, device=device))


def scalar_radii(radii: Tensor) -> Tensor:
    """One pixel radius per Gaussian, (N,): gsplat >= 1.5 returns per-axis radii (N, 2), of which the
    larger; older versions return (N,) already."""
    return radii.max(dim=-1).values if radii.ndim == 2 else radii


def _per_gaussian(radii: Tensor, means2d: Tensor, n: int, mask: Tensor | None,
                  device) -> tuple[Tensor, Tensor]:
    """radii (N,) int32 (the larger of gsplat's per-axis radii) and means2d (N,2), zero outside ``mask``."""
    radii = scalar_radii(radii)
    if mask is None:
        return radii.to(torch.int32), means2d
    full_radii = torch.zeros(n, dtype=torch.int32, device=device)
    full_radii[mask] = radii.to(torch.int32)
    full_means2d = torch.zeros(n, 2, dtype=means2d.dtype, device=device).index_put((mask,), means2d)
    return full_radii, full_means2d


def _median_depth(meta, means, quats, scales, opacities, viewmat, K, width, height, planar_depth) -> Tensor:
    """Median depth on the GPU from gsplat's tile lists (Triton), else from the numba backend."""
    try:
        from activesplat.splat.raster.median_triton import median_depth_from_meta
    except ImportError:
        return _median_depth_cpu(means, quats, scales, opacities, viewmat, K, width, height, planar_depth)
    return median_depth_from_meta(meta, width, height)


@torch.no_grad()
def _median_depth_cpu(means, quats, scales, opacities, viewmat, K, width, height, planar_depth) -> Tensor:
    """Median depth (T first below 0.5) from the numba backend: gsplat does not provide it."""
    from activesplat.splat.raster.numba_backend import rasterize_numba

    cpu = [t.detach().cpu() for t in (means, quats, scales, opacities)]
    colors = torch.zeros(cpu[0].shape[0], 3)
    out = rasterize_numba(*cpu, colors, viewmat.cpu(), K.cpu(), width, height, torch.zeros(3), None,
                          planar_depth)
    return out.median_depth
