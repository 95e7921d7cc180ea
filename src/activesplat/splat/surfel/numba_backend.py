"""numba CPU backend of :func:`activesplat.splat.surfel.rasterize_surfels`: two autograd Functions.

``_Project`` maps world surfels to their screen form (projected centre, depth, tangent matrix M,
facing normal, pixel box; kernels in ``numba_project``); ``_Composite`` bins them into 16x16
tiles with the 3D rasterizer's stable radix sort and tile lists and blends front to back
(``numba_tiles``). Splitting at the projected centres makes ``means2d`` a graph node whose
gradient densification can read. Everything is float32; inputs of other dtypes are cast (gradients come
back in the input dtype). Culled surfels (radius 0) get zero gradient.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import Tensor

from activesplat.splat.kernels import to_numpy as _np
from activesplat.splat.raster import numba_tiles as tiles
from activesplat.splat.raster.constants import RASTER
from activesplat.splat.raster.numba_backend import warm_up_scene
from activesplat.splat.surfel import SurfelRenderOutput
from activesplat.splat.surfel import numba_project as proj
from activesplat.splat.surfel import numba_tiles as stiles


class _Project(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means, quats, scales, opacities, view, intr, width, height):
        n = means.shape[0]
        arrays = [_np(means), _np(quats), _np(scales)]
        means2d, depths = np.zeros((n, 2), np.float32), np.zeros(n, np.float32)
        tmat, normals = np.zeros((n, 6), np.float32), np.zeros((n, 3), np.float32)
        boxes, radii, rects = np.zeros((n, 4), np.float32), np.zeros(n, np.int32), np.zeros((n, 4), np.int32)
        proj.project_forward(*arrays, _np(opacities), view, intr, width, height,
                             means2d, depths, tmat, normals, boxes, radii, rects)
        ctx.arrays, ctx.view, ctx.intr, ctx.radii = arrays, view, intr, radii
        flags = [torch.from_numpy(a) for a in (boxes, radii, rects)]
        ctx.mark_non_differentiable(*flags)
        return (torch.from_numpy(means2d), torch.from_numpy(depths), torch.from_numpy(tmat),
                torch.from_numpy(normals), *flags)

    @staticmethod
    def backward(ctx, v_means2d, v_depths, v_tmat, v_normals, _v_boxes, _v_radii, _v_rects):
        means, quats, scales = ctx.arrays
        v_means, v_quats, v_scales = np.zeros_like(means), np.zeros_like(quats), np.zeros_like(scales)
        proj.project_backward(means, quats, scales, ctx.view, ctx.intr, ctx.radii, _np(v_means2d),
                              _np(v_depths), _np(v_tmat), _np(v_normals), v_means, v_quats, v_scales)
        return (torch.from_numpy(v_means), torch.from_numpy(v_quats), torch.from_numpy(v_scales),
                None, None, None, None, None)


class _Composite(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means2d, depths, tmat, normals, opacities, colors, background, boxes, radii, rects,
                width, height):
        depth_np = _np(depths)
        order = tiles.stable_depth_order(np.flatnonzero(radii.numpy() > 0), depth_np)
        grid_x, grid_y = math.ceil(width / RASTER.tile_size), math.ceil(height / RASTER.tile_size)
        lists = tiles.build_tile_lists(order, rects.numpy(), grid_x, grid_x * grid_y)
        tile_starts, ids, emit_start, slot = lists
        feat = stiles.gather_features(order, ids, _np(means2d), depth_np, _np(tmat), _np(normals),
                                      _np(opacities), _np(colors), boxes.numpy())
        bg = _np(background)
        rgb, normal = np.empty((height, width, 3), np.float32), np.empty((height, width, 3), np.float32)
        depth, trans, median, dist, m2 = (np.empty((height, width), np.float32) for _ in range(5))
        last = np.empty((height, width), np.int64)
        stiles.composite_forward(tile_starts, feat, width, height, bg, rgb, depth, trans, median, normal,
                                 dist, m2, last)
        ctx.saved = (order, tile_starts, emit_start, slot, feat, bg, trans, depth, m2, last, width, height)
        ctx.n = means2d.shape[0]
        median_t = torch.from_numpy(median)
        ctx.mark_non_differentiable(median_t)
        return (torch.from_numpy(rgb), torch.from_numpy(depth), torch.from_numpy(1 - trans), median_t,
                torch.from_numpy(normal), torch.from_numpy(dist))

    @staticmethod
    def backward(ctx, v_rgb, v_depth, v_alpha, _v_median, v_normal, v_dist):
        order, tile_starts, emit_start, slot, feat, bg, trans, depth, m2, last, width, height = ctx.saved
        v_rgb_np = _np(v_rgb)
        grads = stiles.composite_backward(tile_starts, feat, width, height, bg, trans, depth, m2, last,
                                          v_rgb_np, _np(v_depth), _np(v_alpha), _np(v_normal), _np(v_dist))
        g = torch.from_numpy(stiles.sum_instance_rows(order, emit_start, slot, grads, ctx.n))
        v_bg = torch.from_numpy((v_rgb_np * trans[..., None]).sum(axis=(0, 1)))
        return (g[:, 0:2], g[:, 2], g[:, 3:9], g[:, 9:12], g[:, 12], g[:, 13:16], v_bg,
                None, None, None, None, None)


def _intrinsics(K: Tensor) -> np.ndarray:
    k = K.detach().double().cpu()
    return np.array([float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])], np.float32)


def rasterize_surfels_numba(means, quats, scales, opacities, colors, viewmat, K, background, width, height):
    """The numba backend of :func:`activesplat.splat.surfel.rasterize_surfels` (float32, CPU)."""
    device = means.device
    f32 = [t.to("cpu", torch.float32) for t in (means, quats, scales, opacities, colors, background)]
    means, quats, scales, opacities, colors, background = f32
    projected = _Project.apply(means, quats, scales, opacities, _np(viewmat), _intrinsics(K), width, height)
    means2d, depths, tmat, normals, boxes, radii, rects = projected
    images = _Composite.apply(means2d, depths, tmat, normals, opacities, colors, background, boxes, radii,
                              rects, width, height)
    rgb, depth, alpha, median, normal, dist = (t.to(device) for t in images)
    return SurfelRenderOutput(rgb=rgb, depth=depth, alpha=alpha, median_depth=median, normal=normal,
                              distortion=dist, radii=radii.to(device), means2d=means2d.to(device),
                              depths=depths.to(device))


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every numba kernel: one tiny forward + backward."""
    params, K = warm_up_scene(2)
    out = rasterize_surfels_numba(*params, torch.eye(4), K, torch.zeros(3), 32, 32)
    sum(out[name].sum() for name in ("rgb", "depth", "alpha", "normal", "distortion")).backward()
