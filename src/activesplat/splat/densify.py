"""Per-frame mapping rules: new Gaussians from pixels, eq. 8 (densification), eq. 10 (high-loss
samples) and pruning.

All masks are computed from a render of the current view *before* the map is changed.
"""

from __future__ import annotations

import numpy as np
import torch

from activesplat.geometry import backproject, in_sorted, voxel_groups, voxel_keys
from activesplat.splat.config import MapperConfig
from activesplat.splat.gaussians import GaussianMap, camera_points, sigmoid


def opacity_test_mask(alpha: torch.Tensor, obs_depth: torch.Tensor, cfg: MapperConfig) -> torch.Tensor:
    """Eq. 8's opacity test: the holes (O < tau_o1) on valid observed depth."""
    return (obs_depth > 0) & (alpha < cfg.densify_opacity)


def densification_mask(alpha: torch.Tensor, depth: torch.Tensor, obs_depth: torch.Tensor,
                       cfg: MapperConfig) -> torch.Tensor:
    """Eq. 8: M_k = (O < tau_o1) or (D_obs < D_render and |D_obs - D_render| > k * median error),
    only where the observed depth is valid. ``depth`` is the alpha-blended render (as SplaTAM)."""
    valid = obs_depth > 0
    error = (obs_depth - depth).abs()
    median_error = error[valid].median() if bool(valid.any()) else error.new_zeros(())
    margin = cfg.densify_k * median_error
    in_front = (obs_depth < depth) & (error > margin)
    if cfg.densify_max_depth_m is not None:
        in_front &= obs_depth < cfg.densify_max_depth_m
    return opacity_test_mask(alpha, obs_depth, cfg) | (valid & in_front)


def high_loss_mask(alpha: torch.Tensor, median_depth: torch.Tensor, obs_depth: torch.Tensor,
                   cfg: MapperConfig) -> torch.Tensor:
    """Eq. 10: M_h = (O > tau_o2) and (D_obs < D_render) and |D_obs - D_render| > epsilon_1, with the
    median depth as the release, on valid observed depth."""
    valid = obs_depth > 0
    closer = obs_depth < median_depth
    far_off = (obs_depth - median_depth).abs() > cfg.high_loss_depth_m
    return valid & (alpha > cfg.high_loss_opacity) & closer & far_off


def stride_mask(mask: torch.Tensor, stride: int) -> torch.Tensor:
    """Keep only the pixels on a ``stride`` grid (one candidate per stride x stride block)."""
    if stride == 1:
        return mask
    grid = torch.zeros_like(mask)
    grid[stride // 2::stride, stride // 2::stride] = True
    return mask & grid


def depth_edge_band(depth: torch.Tensor, band_px: int, jump: float) -> torch.Tensor:
    """(H, W) bool: the pixels on the near side of a depth jump, within ``band_px`` pixels of it. A jump
    is where the observed surface is not continuous: the inverse depth, affine on a plane, has a second
    difference (along rows or columns, neighbours 1 px away) above ``jump`` times its value, or a
    neighbour is invalid. A pixel is on its near side when some depth within ``band_px`` pixels is farther
    than its own by more than ``jump`` of it (invalid depth counts as infinitely far). Only those
    Gaussians reach over something else; a far floor or a wall seen at a slant, whose depth grows fast
    but smoothly, is no jump. On the CPU in numba (``_mapper_numba.edge_band``, the same mask)."""
    if depth.device.type == "cpu":
        from activesplat.splat._mapper_numba import edge_band

        d = np.ascontiguousarray(depth.detach().numpy(), dtype=np.float32)
        return torch.from_numpy(edge_band(d, band_px, np.float32(jump), np.float32(1.0 + jump)))
    return _depth_edge_band_torch(depth, band_px, jump)


def _depth_edge_band_torch(depth: torch.Tensor, band_px: int, jump: float) -> torch.Tensor:
    """:func:`depth_edge_band` in torch (any device)."""
    d = depth.to(torch.float32)
    valid = d > 0
    inv = torch.where(valid, 1.0 / d.clamp_min(1e-12), torch.zeros_like(d))
    edge = torch.zeros_like(valid)
    for dim in (0, 1):
        n = d.shape[dim]
        if n < 3:
            continue
        a, p, b = (inv.narrow(dim, i, n - 2) for i in range(3))
        va, vp, vb = (valid.narrow(dim, i, n - 2) for i in range(3))
        kink = vp & (~va | ~vb | ((a - 2.0 * p + b).abs() > jump * p))
        edge.narrow(dim, 1, n - 2).logical_or_(kink)
    k = 2 * band_px + 1
    far = torch.where(valid, d, torch.full_like(d, float("inf")))[None, None]
    near = torch.nn.functional.max_pool2d(far, k, stride=1, padding=band_px)[0, 0] > d * (1.0 + jump)
    if band_px > 1:
        edge = torch.nn.functional.max_pool2d(edge[None, None].float(), 2 * band_px - 1, stride=1,
                                              padding=band_px - 1)[0, 0] > 0
    return edge & near & valid


def colour_detail(rgb: torch.Tensor, stride: int, colour_range: float) -> torch.Tensor:
    """(H, W) bool: the pixels of the ``stride`` x ``stride`` blocks whose colours span more than
    ``colour_range`` in some channel (max - min over the block): where one Gaussian per block would blur
    texture the observation has. On the CPU in numba (``_mapper_numba.colour_blocks``, the same mask)."""
    if rgb.device.type == "cpu":
        from activesplat.splat._mapper_numba import colour_blocks

        x = np.ascontiguousarray(rgb.detach().numpy(), dtype=np.float32)
        return torch.from_numpy(colour_blocks(x, stride, np.float32(colour_range)))
    return _colour_detail_torch(rgb, stride, colour_range)


def _colour_detail_torch(rgb: torch.Tensor, stride: int, colour_range: float) -> torch.Tensor:
    """:func:`colour_detail` in torch (any device)."""
    h, w = rgb.shape[:2]
    x = rgb.to(torch.float32).permute(2, 0, 1)[None]
    pad = (0, (-w) % stride, 0, (-h) % stride)
    hi = torch.nn.functional.max_pool2d(torch.nn.functional.pad(x, pad, value=-1.0), stride)
    lo = -torch.nn.functional.max_pool2d(torch.nn.functional.pad(-x, pad, value=-2.0), stride)
    block = ((hi - lo) > colour_range).any(dim=1)[0]
    return block.repeat_interleave(stride, 0).repeat_interleave(stride, 1)[:h, :w]


def surface_frame(depth: np.ndarray, v: np.ndarray, u: np.ndarray, K: np.ndarray, stride: int,
                  plane_tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The observed surface around pixels (v, u) in the camera frame: ``normal`` (unit, facing the
    camera), ``along`` (unit, in the surface plane: the viewing ray projected onto it, or any tangent
    where the ray is the normal) and ``ok``. The normal comes from the back-projected neighbours
    ``stride`` pixels away on either side in u and in v.
    Pixels whose neighbours are invalid, off the image, or not on one plane with it (inverse depth,
    which is affine in the pixel coordinates on a plane, departs from the neighbours' mean by more
    than ``plane_tol`` of its value: a depth edge or a curved surface) are not ``ok`` (their rows of
    the other arrays are 0). Returns ((M, 3), (M, 3), (M,) bool)."""
    m = len(v)
    normal, along = np.zeros((m, 3)), np.zeros((m, 3))
    if m == 0:
        return normal, along, np.zeros(0, dtype=bool)
    h, w = depth.shape
    s = stride
    ok = (u - s >= 0) & (u + s < w) & (v - s >= 0) & (v + s < h)
    vi, ui = np.where(ok, v, s), np.where(ok, u, s)  # in-range stand-ins for the rows that are not ok
    camera = np.eye(4)

    def point(rows, cols):  # camera-frame points and their depths
        return backproject(depth, camera, K, rows, cols), depth[rows, cols].astype(np.float64)

    p, z = point(vi, ui)
    pr, zr = point(vi, ui + s)
    pl, zl = point(vi, ui - s)
    pd, zd = point(vi + s, ui)
    pu, zu = point(vi - s, ui)
    ok &= (z > 0) & (zr > 0) & (zl > 0) & (zd > 0) & (zu > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / z
        for za, zb in ((zr, zl), (zd, zu)):
            ok &= np.abs(0.5 * (1.0 / za + 1.0 / zb) - inv) <= plane_tol * inv
        n = np.cross(pr - pl, pd - pu)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        ray = p / np.linalg.norm(p, axis=1, keepdims=True)
        c = (ray * n).sum(axis=1)
        n = np.where(c[:, None] > 0, -n, n)  # facing the camera: against the ray
        c = np.abs(c)
        a = ray + c[:, None] * n  # ray minus its normal component
        norm_a = np.linalg.norm(a, axis=1)
        # head-on (ray along the normal): any tangent does; take camera x made orthogonal to n
        x = np.array([1.0, 0.0, 0.0]) - n[:, :1] * n
        a = np.where((norm_a > 1e-6)[:, None], a, x)
        a /= np.linalg.norm(a, axis=1, keepdims=True)
    ok &= np.isfinite(c) & (c > 0) & np.isfinite(n).all(axis=1) & np.isfinite(a).all(axis=1)
    normal[ok], along[ok] = n[ok], a[ok]
    return normal, along, ok


def one_per_voxel(points: np.ndarray, fine: np.ndarray, occupied: np.ndarray, size: float) -> np.ndarray:
    """(M,) bool: the candidate centres ``points`` (M, 3) that a voxel budget of one new centre per voxel of
    ``size`` metres keeps (MapperConfig "Voxel budget"): none in a voxel of ``occupied`` (sorted voxel keys
    of the map's centres), and one per voxel among the rest, a grid pick (``fine`` False) before a fine
    one, then the first in raster order."""
    keys = voxel_keys(points, size)
    free = np.flatnonzero(~in_sorted(occupied, keys))
    order, first = voxel_groups(keys[free], fine[free])  # by voxel, grid picks first, then raster order
    keep = np.zeros(len(keys), dtype=bool)
    keep[free[order[first]]] = True
    return keep


def gaussians_from_pixels(mask: torch.Tensor, rgb: torch.Tensor, depth: torch.Tensor, pose: np.ndarray,
                          K: np.ndarray, cfg: MapperConfig, occupied: np.ndarray | None = None,
                          exempt: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """Raw parameters of one Gaussian per masked pixel (``mask`` lies on valid observed depth, as eq. 8's
    mask does) on the ``pixel_stride`` grid: back-projected
    centre, radius = init_radius_scale * stride * depth / focal (projective scale), opacity
    ``init_opacity``, colour = the pixel's colour (docs/protocol.md §2, initialisation). Isotropic as the
    paper when ``init_normal_scale`` is 1. Otherwise, where the observed depth around the pixel is one
    plane (:func:`surface_frame`), the Gaussian is turned to it and its radius along the normal is
    ``init_normal_scale`` times the radius (MapperConfig "Flat Gaussians"). With ``init_max_radius_m`` no
    radius exceeds it, and with ``init_capped_fill`` every pixel where the capped radius is under half the
    grid's spacing is picked (MapperConfig "Capped birth radius"). With ``occupied`` (sorted voxel keys of
    the map's centres in view) and ``cfg.densify_voxel_m``, the picks are thinned by :func:`one_per_voxel`,
    except those on ``exempt`` pixels ((H, W) bool)."""
    focal = 0.5 * (float(K[0, 0]) + float(K[1, 1]))
    pick = stride_mask(mask, cfg.pixel_stride)
    fine = None
    if cfg.edge_band_px > 0 and cfg.pixel_stride > 1:  # every pixel near a depth jump, at its own radius
        fine = mask & depth_edge_band(depth, cfg.edge_band_px, cfg.edge_jump)
    if cfg.detail_colour_range is not None and cfg.pixel_stride > 1:  # and every pixel of a detailed block
        detail = mask & colour_detail(rgb, cfg.pixel_stride, cfg.detail_colour_range)
        fine = detail if fine is None else fine | detail
    if cfg.init_max_radius_m is not None and cfg.init_capped_fill and cfg.pixel_stride > 1:
        # and every pixel where the capped radius would fall below half the grid's spacing
        sparse = mask & (depth * (0.5 * cfg.pixel_stride / focal) > cfg.init_max_radius_m)
        fine = sparse if fine is None else fine | sparse
    if fine is not None:
        pick = pick | fine
    v, u = (t.cpu().numpy() for t in torch.nonzero(pick, as_tuple=True))
    depth_np = depth.detach().cpu().numpy()
    points_np = backproject(depth_np, pose, K, v, u)
    budget = None
    if occupied is not None and cfg.densify_voxel_m is not None:
        is_fine = np.zeros(len(v), dtype=bool) if fine is None else fine.cpu().numpy()[v, u]
        # exempt pixels (the opacity test's holes) are kept whatever the budget, at their own radius
        spared = np.zeros(len(v), dtype=bool) if exempt is None else exempt.cpu().numpy()[v, u]
        keep = one_per_voxel(points_np, is_fine, occupied, cfg.densify_voxel_m) | spared
        budget = ~spared[keep]
        v, u, points_np = v[keep], u[keep], points_np[keep]
    points = torch.from_numpy(points_np.astype(np.float32))
    z = torch.from_numpy(depth_np[v, u])
    stride = float(cfg.pixel_stride)
    if fine is not None:
        stride = torch.where(fine.cpu()[torch.from_numpy(v), torch.from_numpy(u)], 1.0, stride)
    radii = cfg.init_radius_scale * stride * z / focal
    if cfg.init_max_radius_m is not None:
        radii = torch.clamp(radii, max=cfg.init_max_radius_m)
    if budget is not None:  # the centres the budget kept cover the voxels between them
        floor = torch.from_numpy(np.where(budget, cfg.densify_voxel_radius * cfg.densify_voxel_m, 0.0))
        radii = torch.maximum(radii, floor.to(radii.dtype))
    colors = rgb[torch.from_numpy(v), torch.from_numpy(u)]
    frames = factors = None
    if cfg.init_normal_scale < 1.0:
        normal, along, ok = surface_frame(depth_np, v, u, K, cfg.pixel_stride, cfg.init_plane_tol)
        rot = pose[:3, :3]
        # world-frame columns (slant axis, tangent across it, normal): a right-handed frame
        frames = np.stack([along @ rot.T, np.cross(normal, along) @ rot.T, normal @ rot.T], axis=2)[ok]
        factors = np.ones((int(ok.sum()), 3))
        factors[:, 2] = cfg.init_normal_scale
        frames = torch.from_numpy(frames.astype(np.float32))
        factors = torch.from_numpy(factors.astype(np.float32))
        ok = torch.from_numpy(ok)
    raw = GaussianMap.raw_from_points(points, colors, radii, cfg.init_opacity,
                                      None if frames is None else (ok, frames, factors))
    return {k: t.to(rgb.device) for k, t in raw.items()}


def _project(means: torch.Tensor, pose: np.ndarray, K: np.ndarray, h: int, w: int
             ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Camera depth, integer pixel column and row of each centre, and whether it lies in the image."""
    cam = camera_points(means, pose)
    z = cam[:, 2]
    safe_z = torch.where(z > 1e-6, z, torch.ones_like(z))
    u = torch.floor(float(K[0, 0]) * cam[:, 0] / safe_z + float(K[0, 2])).long()
    v = torch.floor(float(K[1, 1]) * cam[:, 1] / safe_z + float(K[1, 2])).long()
    inside = (z > 1e-6) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    return z, u, v, inside


def free_space_mask(means: torch.Tensor, pose: np.ndarray, K: np.ndarray, obs_depth: torch.Tensor,
                    margin_m: float, window_px: int) -> torch.Tensor:
    """Floaters: Gaussians whose centre projects into the current view *in front of* the observed
    surface by more than ``margin_m``, i.e. sits in space the sensor ray has just seen to be empty.

    The observed depth is the minimum over a (2 ``window_px`` + 1)^2 neighbourhood of valid pixels, so
    a Gaussian on a depth edge (foreground rim seen one pixel off) is never taken for a floater; a
    neighbourhood with an invalid pixel (unknown space) never prunes. Returns (N,) bool, True = floater.
    """
    h, w = obs_depth.shape
    z, u, v, inside = _project(means, pose, K, h, w)
    if obs_depth.device.type == "cpu" and obs_depth.dtype == z.dtype == torch.float32:
        from activesplat.splat._mapper_numba import floaters  # the window minimum at each centre only

        depth = np.ascontiguousarray(obs_depth.detach().numpy())
        return torch.from_numpy(floaters(z.numpy(), u.numpy(), v.numpy(), inside.numpy(), depth, window_px,
                                         np.float32(margin_m)))
    return _floaters_torch(z, u, v, inside, obs_depth, margin_m, window_px)


def _floaters_torch(z: torch.Tensor, u: torch.Tensor, v: torch.Tensor, inside: torch.Tensor,
                    obs_depth: torch.Tensor, margin_m: float, window_px: int) -> torch.Tensor:
    """The test of :func:`free_space_mask` on the projected centres (:func:`_project`), in torch."""
    observed = torch.where(obs_depth > 0, obs_depth, torch.zeros_like(obs_depth))
    k = 2 * window_px + 1
    # min-pool of the depth; any invalid (0) pixel makes the neighbourhood minimum 0 -> never a floater
    nearest = -torch.nn.functional.max_pool2d(-observed[None, None], k, stride=1, padding=window_px)[0, 0]
    if window_px > 0:  # max_pool2d pads with -inf, so the border needs the zero padding made explicit
        nearest[:window_px], nearest[-window_px:] = 0.0, 0.0
        nearest[:, :window_px], nearest[:, -window_px:] = 0.0, 0.0
    floater = torch.zeros_like(inside)
    idx = torch.nonzero(inside, as_tuple=True)[0]
    floater[idx] = z[idx] < nearest[v[idx], u[idx]] - margin_m
    return floater


def coarse_mask(means: torch.Tensor, log_scales: torch.Tensor, pose: np.ndarray, K: np.ndarray,
                obs_depth: torch.Tensor, cfg: MapperConfig) -> torch.Tensor:
    """Coarse Gaussians (MapperConfig "Coarse refresh"): those this view sees whole, unoccluded and at
    least ``refresh_coarse_factor`` times finer than their size, i.e. whose largest scale exceeds that
    factor times the radius a new Gaussian would get at their depth (and ``refresh_min_radius_m``).
    Their whole footprint (``refresh_sigmas`` sigmas) must lie inside the image on valid observed depth,
    with nothing observed in front of the centre by more than max(``refresh_depth_margin_m``, scale),
    and the depth observed at the centre must match it to that tolerance. Returns (N,) bool."""
    from activesplat.splat._mapper_numba import coarse_rows

    if means.shape[0] == 0 or cfg.refresh_coarse_factor is None:
        return torch.zeros(means.shape[0], dtype=torch.bool, device=means.device)
    pose = np.asarray(pose, dtype=np.float64)
    fx, fy, cx, cy = float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
    radius_per_z = cfg.init_radius_scale * cfg.pixel_stride / (0.5 * (fx + fy))
    depth = np.ascontiguousarray(obs_depth.detach().cpu().numpy(), dtype=np.float32)
    out = coarse_rows(means.detach().cpu().numpy(), log_scales.detach().cpu().numpy(), pose[:3, :3].copy(),
                      pose[:3, 3].copy(), fx, fy, cx, cy, depth, cfg.refresh_coarse_factor, radius_per_z,
                      cfg.refresh_min_radius_m, cfg.refresh_sigmas, cfg.refresh_depth_margin_m)
    return torch.from_numpy(out).to(means.device)


def prune_mask(raw: dict[str, torch.Tensor], cfg: MapperConfig) -> torch.Tensor:
    """Gaussians to keep among the raw parameters ``raw`` (any subset of rows): drop near-transparent
    (opacity < prune_opacity) and oversized (largest scale > prune_max_scale_m) ones, as 3DGS."""
    with torch.no_grad():
        opacity = sigmoid(raw["opacity_logits"].detach())
        largest = torch.exp(raw["log_scales"].detach().max(dim=1).values)
        return (opacity >= cfg.prune_opacity) & (largest <= cfg.prune_max_scale_m)


def cap_mask(opacity_logits: torch.Tensor, keep: torch.Tensor, cap: int) -> torch.Tensor:
    """The optional global cap: of the Gaussians ``keep`` marks, the ``cap`` most opaque survive (the old
    rule; it forgets whatever is least opaque anywhere in the map, so it is off by default)."""
    keep = keep.clone()
    excess = int(keep.sum()) - cap
    if excess > 0:
        ranked = torch.where(keep, opacity_logits, torch.full_like(opacity_logits, float("inf")))
        keep[torch.topk(ranked, excess, largest=False).indices] = False
    return keep
