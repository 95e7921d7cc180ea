"""Slow, literal torch reference of the 2DGS surfel rasterizer (plain autograd; see ``surfel.py``).

The ray-splat intersection is written exactly as in the paper: T = K H, h_u = x T_2 - T_0,
h_v = y T_2 - T_1, (u, v) = c_xy / c_z with c = h_u x h_v, evaluated densely for every pixel of a tile
against every surfel binned to it (``bin_tiles=False`` evaluates all rendered surfels everywhere, which
checks that the screen boxes never clip a contribution). Transmittance is a cumulative product; the
early stop (T (1 - alpha) < 1e-4) is a mask on the inclusive product, which is monotone, so it
reproduces the sequential loop. Distortion uses exclusive cumulative sums (the one-pass 2DGS form).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor

from activesplat.splat.kernels import quat_to_rotmat
from activesplat.splat.raster.constants import RASTER
from activesplat.splat.raster.torch_ref import blend_weights, median_of
from activesplat.splat.surfel import SurfelRenderOutput
from activesplat.splat.surfel.constants import SURFEL


@dataclass
class SurfelProjection:
    """Per-surfel screen quantities of the reference."""

    means2d: Tensor  # (N, 2) projected centres (graph node: the screen shift of the footprint)
    depths: Tensor  # (N,) view z of the centres
    tmat: Tensor  # (N, 3, 3) T = K H, rows (x, y, w) of the homogeneous pixel of (u, v, 1)
    normals: Tensor  # (N, 3) camera-space normals facing the camera
    radii: Tensor  # (N,) int32, 0 = culled
    rects: Tensor  # (N, 4) int64 tiles [tx0, tx1, ty0, ty1)


def project_surfels_torch(means, quats, scales, opacities, viewmat, K, width, height) -> SurfelProjection:
    """World surfels -> the KWH transform, projected centres, facing normals, screen boxes."""
    rot, trans = viewmat[:3, :3], viewmat[:3, 3]
    p = means @ rot.T + trans
    z = p[:, 2]
    zs = torch.where(z > SURFEL.near, z, torch.ones_like(z))
    axes = rot @ quat_to_rotmat(quats)  # columns: camera-space t_u, t_v, normal
    h = torch.stack([axes[:, :, 0] * scales[:, :1], axes[:, :, 1] * scales[:, 1:], p], dim=-1)
    t_full = K @ h
    # Re-express T with the projected centre as its own graph node: rows 0, 1 = M + c_2d T_2, where
    # M = rows 0, 1 - c_2d T_2 (c_2d computed separately here); the value of T is unchanged.
    c2d = t_full[:, :2, 2] / zs[:, None]
    shifted = t_full[:, :2, :] - c2d[:, :, None] * t_full[:, 2:, :]
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    means2d = torch.stack([fx * p[:, 0] / zs + cx, fy * p[:, 1] / zs + cy], dim=-1)
    tmat = torch.cat([shifted + means2d[:, :, None] * t_full[:, 2:, :], t_full[:, 2:, :]], dim=1)
    normal = axes[:, :, 2]
    normals = torch.where(((normal * p).sum(-1) > 0)[:, None], -normal, normal)
    with torch.no_grad():
        radii, rects = screen_footprint(shifted, t_full[:, 2], means2d, z, opacities, width, height)
    return SurfelProjection(means2d=means2d, depths=z, tmat=tmat, normals=normals, radii=radii, rects=rects)


def screen_footprint(shifted: Tensor, row2: Tensor, means2d: Tensor, z: Tensor, opacities: Tensor,
                     width: int, height: int) -> tuple[Tensor, Tensor]:
    """Screen box of the alpha >= 1/255 footprint: the bounding box of the projected disc
    u^2 + v^2 <= r^2, r^2 = 2 ln(255 o) (tangent lines of the dual conic T diag(r^2, r^2, -1) T^T, in
    pixel coordinates relative to the centre), union the low-pass disc of radius r / sqrt(2).
    Returns radii (N,) int32 (0 = culled) and tile rectangles (N, 4)."""
    a0, b0 = shifted[:, 0, 0], shifted[:, 0, 1]
    a1, b1 = shifted[:, 1, 0], shifted[:, 1, 1]
    a2, b2 = row2[:, 0], row2[:, 1]
    r2 = 2 * (torch.log(torch.clamp(opacities, min=RASTER.alpha_min)) + SURFEL.log_255)
    keep = (opacities > RASTER.alpha_min) & (z - torch.sqrt(r2 * (a2 * a2 + b2 * b2)) > SURFEL.near)
    c22 = torch.where(keep, r2 * (a2 * a2 + b2 * b2) - z * z, -torch.ones_like(z))
    r_low = torch.sqrt(r2 / SURFEL.filter_inv_square)
    lo, hi = [], []
    for a, b, centre in ((a0, b0, means2d[:, 0]), (a1, b1, means2d[:, 1])):
        mid = r2 * (a * a2 + b * b2) / c22
        half_sq = (r2 * z * z * (a * a + b * b) - r2 * r2 * (a * b2 - b * a2) ** 2) / (c22 * c22)
        half = torch.sqrt(torch.clamp(half_sq, min=0))
        lo.append(centre + torch.minimum(mid - half, -r_low) - SURFEL.box_pad)
        hi.append(centre + torch.maximum(mid + half, r_low) + SURFEL.box_pad)
    ts = RASTER.tile_size
    cols = []
    for axis, size in ((0, width), (1, height)):
        first = torch.clamp(torch.ceil(lo[axis] - 0.5), min=0)
        last = torch.clamp(torch.floor(hi[axis] - 0.5), max=size - 1)
        keep &= first <= last
        cols += [torch.floor(first / ts), torch.floor(last / ts) + 1]
    rects = torch.where(keep[:, None], torch.stack(cols, dim=-1), torch.zeros(1, dtype=z.dtype))
    rects = rects.to(torch.int64)
    reach = torch.stack([means2d[:, 0] - lo[0], hi[0] - means2d[:, 0], means2d[:, 1] - lo[1],
                         hi[1] - means2d[:, 1]], dim=-1).amax(dim=-1)
    radii = torch.where(keep, torch.ceil(reach), torch.zeros_like(reach)).to(torch.int32)
    return radii, rects


def composite_tile(proj: SurfelProjection, ids: Tensor, opacities, colors, pix: Tensor, background):
    """Front-to-back blending of the depth-sorted surfels ``ids`` at pixel centres ``pix`` (P, 2)."""
    tm = proj.tmat[ids][None]  # (1, M, 3, 3)
    px, py = pix[:, 0, None, None], pix[:, 1, None, None]
    h_u = px * tm[..., 2, :] - tm[..., 0, :]
    h_v = py * tm[..., 2, :] - tm[..., 1, :]
    c = torch.linalg.cross(h_u, h_v, dim=-1)  # (P, M, 3)
    hit = c[..., 2] != 0
    s = c[..., :2] / torch.where(hit, c[..., 2], torch.ones_like(c[..., 2]))[..., None]
    rho3d = torch.where(hit, (s * s).sum(-1), torch.full_like(s[..., 0], math.inf))
    d = proj.means2d[ids][None] - pix[:, None, :]
    rho2d = SURFEL.filter_inv_square * (d * d).sum(-1)
    ray_wins = rho3d <= rho2d
    power = 0.5 * torch.where(ray_wins, rho3d, rho2d)
    z_hit = (tm[..., 2, :2] * s).sum(-1) + tm[..., 2, 2]
    z = torch.where(ray_wins, z_hit, proj.depths[ids][None].expand_as(z_hit))
    alpha = torch.clamp(opacities[ids] * torch.exp(-power), max=RASTER.alpha_max)
    alpha = torch.where(alpha >= RASTER.alpha_min, alpha, torch.zeros_like(alpha))
    w, t_before, t_after = blend_weights(alpha)
    t_final = t_after[:, -1]
    rgb = w @ colors[ids] + t_final[:, None] * background
    normal = w @ proj.normals[ids]
    wz, wzz = w * z, w * z * z
    d1, d2 = torch.cumsum(wz, dim=1) - wz, torch.cumsum(wzz, dim=1) - wzz  # exclusive running sums
    distortion = (w * (z * z * (1 - t_before) - 2 * z * d1 + d2)).sum(-1)
    return rgb, wz.sum(-1), 1 - t_final, median_of(z, t_before, t_after), normal, distortion


def rasterize_surfels_torch(means, quats, scales, opacities, colors, viewmat, K, background, width, height,
                            bin_tiles: bool = True) -> SurfelRenderOutput:
    """The torch reference backend of :func:`activesplat.splat.surfel.rasterize_surfels`."""
    proj = project_surfels_torch(means, quats, scales, opacities, viewmat, K, width, height)
    ts = RASTER.tile_size
    dtype, device = means.dtype, means.device
    visible = torch.nonzero(proj.radii > 0).squeeze(1)
    order = visible[torch.sort(proj.depths.detach()[visible], stable=True).indices]
    rect = proj.rects[order]
    rgb = background.expand(height, width, 3).clone()
    normal = torch.zeros(height, width, 3, dtype=dtype, device=device)
    depth, alpha, median, dist = (torch.zeros(height, width, dtype=dtype, device=device) for _ in range(4))
    for ty in range(math.ceil(height / ts)):
        for tx in range(math.ceil(width / ts)):
            hit = (rect[:, 0] <= tx) & (tx < rect[:, 1]) & (rect[:, 2] <= ty) & (ty < rect[:, 3])
            ids = order[hit] if bin_tiles else order
            if ids.numel() == 0:
                continue
            rows = slice(ty * ts, min(height, (ty + 1) * ts))
            cols = slice(tx * ts, min(width, (tx + 1) * ts))
            ii, jj = torch.meshgrid(torch.arange(rows.start, rows.stop, device=device),
                                    torch.arange(cols.start, cols.stop, device=device), indexing="ij")
            pix = torch.stack([jj.reshape(-1), ii.reshape(-1)], dim=-1).to(dtype) + 0.5
            out = composite_tile(proj, ids, opacities, colors, pix, background)
            shape = ii.shape
            rgb[rows, cols], normal[rows, cols] = out[0].reshape(*shape, 3), out[4].reshape(*shape, 3)
            depth[rows, cols], alpha[rows, cols] = out[1].reshape(shape), out[2].reshape(shape)
            median[rows, cols], dist[rows, cols] = out[3].reshape(shape), out[5].reshape(shape)
    return SurfelRenderOutput(rgb=rgb, depth=depth, alpha=alpha, median_depth=median, normal=normal,
                              distortion=dist, radii=proj.radii, means2d=proj.means2d, depths=proj.depths)
