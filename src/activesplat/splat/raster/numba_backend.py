"""numba CPU backend of :func:`activesplat.splat.rasterize`: two autograd Functions.

``_Project`` maps world Gaussians to screen conics (kernels in ``numba_project``);
``_Composite`` bins them into 16x16 tiles and blends front to back (``numba_tiles``).
Splitting at the 2D means, as gsplat does, makes ``means2d`` a graph node whose gradient 3DGS
densification can read. Everything is float32; inputs of other dtypes are cast (gradients come
back in the input dtype). Gaussians with radius 0 (culled, masked, off-screen) get zero gradient,
also through ``out.means2d`` / ``out.depths`` (the torch reference would still differentiate those).
"""

from __future__ import annotations

import math
import time
from contextlib import contextmanager

import numpy as np
import torch
from torch import Tensor

from activesplat.errors import InvalidInputError
from activesplat.splat.kernels import to_numpy as _np
from activesplat.splat.raster import RenderOutput
from activesplat.splat.raster import numba_project as proj
from activesplat.splat.raster import numba_tiles as tiles
from activesplat.splat.raster.constants import RASTER
from activesplat.splat.raster.torch_ref import fov_limits

STAGE_CPU_MS: dict[str, float] | None = None
"""When a dict, every stage adds its CPU milliseconds (``time.process_time``) under its name:
project, sort, bin, composite, composite_backward, sum_grads, project_backward
(``benchmarks/raster.py --stages``). None (the default) times nothing."""


@contextmanager
def _stage(name: str):
    if STAGE_CPU_MS is None:
        yield
        return
    t0 = time.process_time()
    yield
    STAGE_CPU_MS[name] = STAGE_CPU_MS.get(name, 0.0) + 1e3 * (time.process_time() - t0)


def _intrinsics(K: Tensor, width: int, height: int) -> np.ndarray:
    """[fx, fy, cx, cy, lim_x-, lim_x+, lim_y-, lim_y+] as float32 for the kernels."""
    k = K.detach().double().cpu()
    fx, fy, cx, cy = float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])
    return np.array([fx, fy, cx, cy, *fov_limits(k, width, height)], np.float32)


class _Project(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means, quats, scales, view, intr, width, height, mask):
        n = means.shape[0]
        arrays = [_np(means), _np(quats), _np(scales)]
        means2d, conics = np.empty((n, 2), np.float32), np.empty((n, 3), np.float32)
        depths, radii = np.empty(n, np.float32), np.empty(n, np.int32)
        rects, slopes = np.empty((n, 4), np.int32), np.empty((n, 2), np.float32)
        with _stage("project"):
            proj.project_forward(*arrays, view, intr, width, height, mask, means2d, conics, depths, radii,
                                 rects, slopes)
        ctx.arrays, ctx.view, ctx.intr, ctx.radii, ctx.conics = arrays, view, intr, radii, conics
        radii_t, rects_t, slopes_t = (torch.from_numpy(a) for a in (radii, rects, slopes))
        ctx.mark_non_differentiable(radii_t, rects_t, slopes_t)
        return (torch.from_numpy(means2d), torch.from_numpy(conics), torch.from_numpy(depths), radii_t,
                rects_t, slopes_t)

    @staticmethod
    def backward(ctx, v_means2d, v_conics, v_depths, _v_radii, _v_rects, _v_slopes):
        means, quats, scales = ctx.arrays
        v_means, v_quats, v_scales = np.empty_like(means), np.empty_like(quats), np.empty_like(scales)
        with _stage("project_backward"):
            proj.project_backward(means, quats, scales, ctx.view, ctx.intr, ctx.radii, ctx.conics,
                                  _np(v_means2d), _np(v_conics), _np(v_depths), v_means, v_quats, v_scales)
        return (torch.from_numpy(v_means), torch.from_numpy(v_quats), torch.from_numpy(v_scales),
                None, None, None, None, None)


class _Composite(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means2d, conics, depths, slopes, opacities, colors, background, radii, rects, width,
                height):
        rects = rects.numpy()
        depth_np = _np(depths)
        with _stage("sort"):
            order = tiles.stable_depth_order(np.flatnonzero(radii.numpy() > 0), depth_np)
        grid_x, grid_y = math.ceil(width / RASTER.tile_size), math.ceil(height / RASTER.tile_size)
        with _stage("bin"):
            tile_starts, feat, emit_start, slot = tiles.bin_features(
                order, rects, grid_x, grid_x * grid_y, _np(means2d), _np(conics), _np(opacities), _np(colors),
                depth_np, _np(slopes))
        if np.diff(tile_starts).max(initial=0) >= tiles.MAX_TILE_LIST:
            raise InvalidInputError(f"rasterize: more than {tiles.MAX_TILE_LIST} Gaussians overlap one "
                                    "16x16 tile, which the numba backend cannot composite")
        bg = _np(background)
        rgb = np.empty((height, width, 3), np.float32)
        depth, trans, median = (np.empty((height, width), np.float32) for _ in range(3))
        last = np.empty((height, width), np.int64)
        with _stage("composite"):
            tiles.composite_forward(tile_starts, feat, width, height, bg, rgb, depth, trans, median, last)
        ctx.saved = (order, tile_starts, emit_start, slot, feat, bg, trans, last, width, height)
        ctx.n = means2d.shape[0]
        median_t = torch.from_numpy(median)
        ctx.mark_non_differentiable(median_t)
        return torch.from_numpy(rgb), torch.from_numpy(depth), torch.from_numpy(1 - trans), median_t

    @staticmethod
    def backward(ctx, v_rgb, v_depth, v_alpha, _v_median):
        order, tile_starts, emit_start, slot, feat, bg, trans, last, width, height = ctx.saved
        v_rgb_np = _np(v_rgb)
        with _stage("composite_backward"):
            grads = tiles.composite_backward(tile_starts, feat, width, height, bg, trans, last,
                                             v_rgb_np, _np(v_depth), _np(v_alpha))
        with _stage("sum_grads"):
            sums = tiles.sum_instance_grads(order, emit_start, slot, grads, ctx.n)
        v_means2d, v_conics, v_opacities, v_colors, v_depths = (torch.from_numpy(a) for a in sums)
        v_bg = torch.from_numpy((v_rgb_np * trans[..., None]).sum(axis=(0, 1)))
        return v_means2d, v_conics, v_depths, None, v_opacities, v_colors, v_bg, None, None, None, None


def rasterize_numba(means, quats, scales, opacities, colors, viewmat, K, width, height, background, mask,
                    planar_depth: bool = False):
    """The numba backend of :func:`activesplat.splat.rasterize` (float32, CPU)."""
    device = means.device
    f32 = [t.to("cpu", torch.float32) for t in (means, quats, scales, opacities, colors, background)]
    means, quats, scales, opacities, colors, background = f32
    view = _np(viewmat)
    intr = _intrinsics(K, width, height)
    n = means.shape[0]
    mask_np = np.ones(n, np.bool_) if mask is None else np.ascontiguousarray(mask.cpu().numpy())
    projected = _Project.apply(means, quats, scales, view, intr, width, height, mask_np)
    means2d, conics, depths, radii, rects, slopes = projected
    if not planar_depth:
        slopes = torch.zeros(n, 2)
    rgb, depth, alpha, median = _Composite.apply(means2d, conics, depths, slopes, opacities, colors,
                                                 background, radii, rects, width, height)
    return RenderOutput(rgb=rgb.to(device), depth=depth.to(device), alpha=alpha.to(device),
                        median_depth=median.to(device), radii=radii.to(device),
                        means2d=means2d.to(device), depths=depths.to(device))


def warm_up_scene(scale_dims: int, n: int = 8) -> tuple[list[Tensor], Tensor]:
    """The warm-up render of the numba backends: n Gaussians (`scale_dims` = 3) or surfels (2) about 2 m in
    front of a 32x32 camera at the origin, parameters requiring grad; returns (means, quats, scales,
    opacities, colors) and K."""
    gen = torch.Generator().manual_seed(0)
    means = torch.cat([torch.rand(n, 2, generator=gen) - 0.5, torch.full((n, 1), 2.0)], dim=1)
    params = [means, torch.randn(n, 4, generator=gen), torch.full((n, scale_dims), 0.2),
              torch.full((n,), 0.5), torch.rand(n, 3, generator=gen)]
    K = torch.tensor([[16.0, 0, 16], [0, 16, 16], [0, 0, 1]])
    return [p.requires_grad_(True) for p in params], K


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every numba kernel: one tiny forward + backward of
    :func:`warm_up_scene` (:func:`activesplat.splat.raster.prepare_backend`)."""
    from activesplat.splat.raster import prepare_backend

    prepare_backend("numba")
