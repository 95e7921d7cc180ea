"""Median depth on the GPU: a small Triton kernel over gsplat's per-tile intersection lists.

gsplat renders colour, blended depth and opacity but not the median depth (the view depth of the
Gaussian at which the transmittance T first drops below 0.5), which eqs. 8 and 10 and the panoramas
use. This kernel walks the depth-sorted list of each 16 x 16 tile that gsplat's tile intersection has
already built for the same render (``isect_offsets``, ``flatten_ids``, in the layout of
``gsplat.rasterization``'s meta), with the projected means, conics, opacities and depths of that call,
and applies the blending rules of :mod:`activesplat.splat.raster.constants` (alpha clamp 0.99, skip below
1/255, stop before T < 1e-4), so it gives the numba backend's median depth without copying the map to the CPU.

Triton ships with the CUDA builds of PyTorch; with ``TRITON_INTERPRET=1`` the same kernel runs on CPU
tensors (the tests do that). Not differentiable (the median depth never is).
"""

from __future__ import annotations

import torch
import triton
import triton.language as tl

from activesplat.splat.raster.constants import RASTER

CHUNK = 32
"""Gaussians of a tile's list blended per loop iteration of the kernel."""


@triton.jit
def _median_depth_kernel(offsets, ids, means2d, conics, opacities, depths, slopes, out, tiles_x, width,
                         height, alpha_max, alpha_min, t_min, t_median, TILE: tl.constexpr,
                         CHUNK: tl.constexpr):
    """One program per tile. The tile's depth-sorted list is read CHUNK Gaussians at a time: the
    transmittance after each of them comes from a cumulative sum of log(1 - alpha) (the blending rules of
    the numba backend, alpha clamped and skipped below alpha_min), and a pixel is done at the first
    Gaussian that takes it below t_median: its median depth is that Gaussian's depth, unless the same
    Gaussian also takes it below t_min, where blending stops before it (median 0). The tile stops when
    all its pixels are done: only the front of each list is read."""
    tile = tl.program_id(0)
    start = tl.load(offsets + tile)
    end = tl.load(offsets + tile + 1)
    p = tl.arange(0, TILE * TILE)
    col = (tile % tiles_x) * TILE + p % TILE
    row = (tile // tiles_x) * TILE + p // TILE
    inside = (col < width) & (row < height)
    fx = (col.to(tl.float32) + 0.5)[:, None]
    fy = (row.to(tl.float32) + 0.5)[:, None]
    b = tl.arange(0, CHUNK)
    trans = tl.full((TILE * TILE,), 1.0, tl.float32)
    median = tl.zeros((TILE * TILE,), tl.float32)
    live = inside
    k = start
    n_live = tl.sum(live.to(tl.int32), axis=0)
    while (k < end) & (n_live > 0):
        valid = (k + b) < end
        g = tl.load(ids + k + b, mask=valid, other=0).to(tl.int64)
        dx = tl.load(means2d + 2 * g, mask=valid, other=0.0)[None, :] - fx
        dy = tl.load(means2d + 2 * g + 1, mask=valid, other=0.0)[None, :] - fy
        power = 0.5 * (tl.load(conics + 3 * g, mask=valid, other=0.0)[None, :] * dx * dx
                       + tl.load(conics + 3 * g + 2, mask=valid, other=0.0)[None, :] * dy * dy) \
            + tl.load(conics + 3 * g + 1, mask=valid, other=0.0)[None, :] * dx * dy
        alpha = tl.minimum(alpha_max, tl.load(opacities + g, mask=valid, other=0.0)[None, :] * tl.exp(-power))
        hit = valid[None, :] & (power >= 0.0) & (alpha >= alpha_min)
        log_keep = tl.where(hit, tl.log(1.0 - alpha), 0.0)
        t_after = trans[:, None] * tl.exp(tl.cumsum(log_keep, axis=1))
        first = tl.min(tl.where(hit & (t_after < t_median), b[None, :], CHUNK), axis=1)
        at_first = b[None, :] == first[:, None]
        t_first = tl.sum(tl.where(at_first, t_after, 0.0), axis=1)
        depth = (tl.load(depths + g, mask=valid, other=0.0)[None, :]  # at the pixel (planar depth: slopes)
                 - tl.load(slopes + 2 * g, mask=valid, other=0.0)[None, :] * dx
                 - tl.load(slopes + 2 * g + 1, mask=valid, other=0.0)[None, :] * dy)
        depth_first = tl.sum(tl.where(at_first, depth, 0.0), axis=1)
        done = live & (first < CHUNK)
        median = tl.where(done & (t_first >= t_min), depth_first, median)
        live = live & ~done
        trans = trans * tl.exp(tl.sum(log_keep, axis=1))
        n_live = tl.sum(live.to(tl.int32), axis=0)
        k += CHUNK
    tl.store(out + row * width + col, median, mask=inside)


@torch.no_grad()
def median_depth_from_meta(meta: dict, width: int, height: int) -> torch.Tensor:
    """(height, width) median depth of camera 0 of a ``gsplat.rasterization`` call (``packed=False``,
    one camera), 0 where T never drops below 0.5. ``meta["slopes"]`` (1, N, 2), where present, are the
    planar-depth slopes (:mod:`.planar`)."""
    tile = int(meta["tile_size"])
    offsets = meta["isect_offsets"][0].reshape(-1).to(torch.int64)
    ids = meta["flatten_ids"].to(torch.int64)
    offsets = torch.cat([offsets, offsets.new_tensor([ids.numel()])])
    out = torch.zeros(height, width, dtype=torch.float32, device=offsets.device)
    if ids.numel() == 0:
        return out
    if "slopes" not in meta:  # centre depths (no planar depth)
        meta = {**meta, "slopes": torch.zeros_like(meta["means2d"])}
    f32 = [meta[k][0].detach().to(torch.float32).contiguous()
           for k in ("means2d", "conics", "opacities", "depths", "slopes")]
    tiles_x = int(meta["tile_width"])
    grid = (tiles_x * int(meta["tile_height"]),)
    _median_depth_kernel[grid](offsets, ids, *f32, out, tiles_x, width, height, RASTER.alpha_max,
                               RASTER.alpha_min, RASTER.transmittance_min, RASTER.median_transmittance,
                               TILE=tile, CHUNK=CHUNK)
    return out
