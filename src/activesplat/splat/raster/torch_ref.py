"""Slow, obviously correct torch reference of the 3DGS rasterizer (plain autograd).

Each 16x16 tile is evaluated densely against every Gaussian whose 3-sigma square overlaps it (the
3DGS binning rule, so results match the tile-based backends exactly), sorted by view depth with a
stable sort. Transmittance is a cumulative product; the early stop (T * (1 - alpha) < 1e-4) is a
mask on the inclusive product, which is monotone, so it reproduces the sequential loop.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from activesplat.splat.kernels import quat_to_rotmat
from activesplat.splat.raster import Projection, RenderOutput
from activesplat.splat.raster.constants import RASTER
from activesplat.splat.raster.planar import depth_slopes, pixel_depths


def fov_limits(K: Tensor, width: int, height: int) -> tuple[float, float, float, float]:
    """Bounds on x/z and y/z at which the EWA Jacobian is evaluated (3DGS / gsplat ``persp_proj``)."""
    fx, fy, cx, cy = (float(v) for v in (K[0, 0], K[1, 1], K[0, 2], K[1, 2]))
    tan_x, tan_y = 0.5 * width / fx, 0.5 * height / fy
    pad_x, pad_y = RASTER.fov_clamp * tan_x, RASTER.fov_clamp * tan_y
    return cx / fx + pad_x, (width - cx) / fx + pad_x, cy / fy + pad_y, (height - cy) / fy + pad_y


def in_window(x: Tensor, y: Tensor, z: Tensor, K: Tensor, width: int, height: int) -> Tensor:
    """(N,) bool: the centre (camera coordinates x, y, z > 0) lies within the window where the Jacobian is
    not clamped (:func:`fov_limits`)."""
    lim_xn, lim_xp, lim_yn, lim_yp = fov_limits(K, width, height)
    rx, ry = x / z, y / z
    return (rx >= -lim_xn) & (rx <= lim_xp) & (ry >= -lim_yn) & (ry <= lim_yp)


def inside_clamp(x: Tensor, y: Tensor, z: Tensor, K: Tensor, width: int, height: int) -> Tensor:
    """(N,) bool: the Gaussian is drawn by the clamp rule: its centre (camera coordinates x, y, z > 0) lies
    within the window where the Jacobian is not clamped (:func:`in_window`), or it is at least
    ``RASTER.clamp_cull_depth`` away (True everywhere when that is 0)."""
    if RASTER.clamp_cull_depth <= 0.0:
        return torch.ones_like(z, dtype=torch.bool)
    return in_window(x, y, z, K, width, height) | (z >= RASTER.clamp_cull_depth)


def project_torch(means, quats, scales, viewmat, K, width, height, mask=None) -> Projection:
    """EWA splatting: world Gaussians -> 2D means, conics, view depths and screen radii."""
    rot, trans = viewmat[:3, :3], viewmat[:3, 3]
    p_view = means @ rot.T + trans
    x, y, z = p_view.unbind(-1)
    in_front = z > RASTER.near
    zs = torch.where(in_front, z, torch.ones_like(z))
    m = quat_to_rotmat(quats) * scales[:, None, :]
    cov_view = rot @ (m @ m.transpose(1, 2)) @ rot.T
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    lim_xn, lim_xp, lim_yn, lim_yp = fov_limits(K, width, height)
    tx = zs * torch.clamp(x / zs, -lim_xn, lim_xp)
    ty = zs * torch.clamp(y / zs, -lim_yn, lim_yp)
    zero = torch.zeros_like(zs)
    jac = torch.stack(
        [fx / zs, zero, -fx * tx / (zs * zs), zero, fy / zs, -fy * ty / (zs * zs)], dim=-1
    ).reshape(-1, 2, 3)
    cov2d = jac @ cov_view @ jac.transpose(1, 2)
    s00, s01, s11 = cov2d[:, 0, 0] + RASTER.low_pass, cov2d[:, 0, 1], cov2d[:, 1, 1] + RASTER.low_pass
    det = s00 * s11 - s01 * s01
    dets = torch.where(det > 0, det, torch.ones_like(det))
    conics = torch.stack([s11 / dets, -s01 / dets, s00 / dets], dim=-1)
    means2d = torch.stack([fx * x / zs + cx, fy * y / zs + cy], dim=-1)
    with torch.no_grad():
        radii = screen_radii(s00, s11, det, means2d, width, height)
        keep = in_front & (det > 0) & inside_clamp(x, y, zs, K, width, height)
        keep = keep & (mask if mask is not None else True)
        radii = torch.where(keep, radii, torch.zeros_like(radii))
    return Projection(means2d=means2d, conics=conics, depths=z, radii=radii)


def screen_radii(s00: Tensor, s11: Tensor, det: Tensor, means2d: Tensor, width: int, height: int) -> Tensor:
    """ceil(3 sqrt(lambda_max)) of the 2D covariance; 0 where the 3-sigma square touches no tile."""
    mid = 0.5 * (s00 + s11)
    lam = mid + torch.sqrt(torch.clamp(mid * mid - det, min=RASTER.min_eigen_gap))
    radius = torch.ceil(RASTER.extent_sigmas * torch.sqrt(lam))
    rect = tile_rects(means2d, radius, width, height)
    touches = (rect[:, 1] > rect[:, 0]) & (rect[:, 3] > rect[:, 2])
    return torch.where(touches & (det > 0), radius, torch.zeros_like(radius)).to(torch.int32)


def tile_rects(means2d: Tensor, radius: Tensor, width: int, height: int) -> Tensor:
    """(N,4) int [tx0, tx1, ty0, ty1) tiles overlapped by the square mean2d +- radius."""
    ts = RASTER.tile_size
    gx, gy = math.ceil(width / ts), math.ceil(height / ts)
    mx, my = means2d.detach().unbind(-1)
    r = radius.to(mx.dtype)
    return torch.stack([
        torch.clamp(torch.floor((mx - r) / ts), 0, gx), torch.clamp(torch.ceil((mx + r) / ts), 0, gx),
        torch.clamp(torch.floor((my - r) / ts), 0, gy), torch.clamp(torch.ceil((my + r) / ts), 0, gy),
    ], dim=-1).to(torch.int64)


def blend_weights(alpha: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Front-to-back compositing of (P, M) alphas sorted by depth: a pixel stops before the term that would
    bring T below 1e-4. Returns the weights w_i = alpha_i T_i and the transmittance before and after each
    term, each (P, M)."""
    with torch.no_grad():
        blended = torch.cumprod(1 - alpha, dim=1) >= RASTER.transmittance_min
    alpha = alpha * blended
    t_after = torch.cumprod(1 - alpha, dim=1)
    t_before = torch.cat([torch.ones_like(t_after[:, :1]), t_after[:, :-1]], dim=1)
    return alpha * t_before, t_before, t_after


def median_of(z: Tensor, t_before: Tensor, t_after: Tensor) -> Tensor:
    """(P,) the depth z (P, M) of the term at which T first drops below 0.5 (0 where it never does), no
    gradient."""
    with torch.no_grad():
        crossing = (t_after < RASTER.median_transmittance) & (t_before >= RASTER.median_transmittance)
        return (crossing * z.detach()).sum(dim=1)


def composite_tile(proj: Projection, ids: Tensor, opacities, colors, pix: Tensor, background,
                   slopes: Tensor | None = None):
    """Front-to-back blending of the depth-sorted Gaussians ``ids`` at pixel centres ``pix`` (P,2); with
    ``slopes`` (N,2) each Gaussian's depth varies over its footprint (:mod:`.planar`)."""
    d = proj.means2d[ids][None, :, :] - pix[:, None, :]
    a, b, c = proj.conics[ids].unbind(-1)
    power = 0.5 * (a * d[..., 0] ** 2 + c * d[..., 1] ** 2) + b * d[..., 0] * d[..., 1]
    alpha = torch.clamp(opacities[ids] * torch.exp(-power), max=RASTER.alpha_max)
    alpha = torch.where((power >= 0) & (alpha >= RASTER.alpha_min), alpha, torch.zeros_like(alpha))
    weights, t_before, t_after = blend_weights(alpha)
    t_final = t_after[:, -1]
    z = pixel_depths(proj.depths[ids], None if slopes is None else slopes[ids], proj.means2d[ids], pix)
    rgb = weights @ colors[ids] + t_final[:, None] * background
    depth = (weights * z).sum(dim=1)
    return rgb, depth, 1 - t_final, median_of(z, t_before, t_after)


def composite_torch(proj: Projection, opacities, colors, width, height, background, slopes=None):
    """Blend every tile of the image; returns (rgb, depth, alpha, median_depth) images."""
    ts = RASTER.tile_size
    dtype, device = proj.means2d.dtype, proj.means2d.device
    visible = torch.nonzero(proj.radii > 0).squeeze(1)
    order = visible[torch.sort(proj.depths.detach()[visible], stable=True).indices]
    rect = tile_rects(proj.means2d[order], proj.radii[order], width, height)
    rgb = background.expand(height, width, 3).clone()
    depth, median = (torch.zeros(height, width, dtype=dtype, device=device) for _ in range(2))
    alpha = torch.zeros(height, width, dtype=dtype, device=device)
    for ty in range(math.ceil(height / ts)):
        for tx in range(math.ceil(width / ts)):
            hit = (rect[:, 0] <= tx) & (tx < rect[:, 1]) & (rect[:, 2] <= ty) & (ty < rect[:, 3])
            if not bool(hit.any()):
                continue
            rows = slice(ty * ts, min(height, (ty + 1) * ts))
            cols = slice(tx * ts, min(width, (tx + 1) * ts))
            ii, jj = torch.meshgrid(
                torch.arange(rows.start, rows.stop, device=device),
                torch.arange(cols.start, cols.stop, device=device), indexing="ij",
            )
            pix = torch.stack([jj.reshape(-1), ii.reshape(-1)], dim=-1).to(dtype) + 0.5
            out = composite_tile(proj, order[hit], opacities, colors, pix, background, slopes)
            shape = ii.shape
            rgb[rows, cols] = out[0].reshape(*shape, 3)
            depth[rows, cols], alpha[rows, cols], median[rows, cols] = (o.reshape(shape) for o in out[1:])
    return rgb, depth, alpha, median


def rasterize_torch(means, quats, scales, opacities, colors, viewmat, K, width, height, background, mask,
                    planar_depth: bool = False):
    """The torch reference backend of :func:`activesplat.splat.rasterize`."""
    proj = project_torch(means, quats, scales, viewmat, K, width, height, mask)
    slopes = depth_slopes(means, quats, scales, viewmat, K, proj.radii) if planar_depth else None
    rgb, depth, alpha, median = composite_torch(proj, opacities, colors, width, height, background, slopes)
    return RenderOutput(
        rgb=rgb, depth=depth, alpha=alpha, median_depth=median, radii=proj.radii,
        means2d=proj.means2d, depths=proj.depths,
    )
