"""numba kernels of the online mapper (CPU): the view culling of
:func:`activesplat.splat.gaussians.frustum_rows` and the row-sparse Adam update of
:class:`activesplat.splat.optim.RowAdam`, each one parallel pass over the rows, where the torch
versions (kept for other devices, and compared in the tests) make a dozen passes and temporaries; the
keyframe overlap; the per-frame masks of :mod:`activesplat.splat.densify` that torch computes with
max-pools over the whole image (the depth-edge band, the colour-detail blocks, the floater test of the
pruning), which give the torch versions' masks bit for bit (the tests compare them); the coarse refresh's
rows. The mapping loss's kernels are in :mod:`activesplat.splat._loss_numba`."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(inline="always", cache=True)
def camera_point(px, py, pz, rot, t):
    """The point (px, py, pz) in the camera frame of a camera-to-world (``rot``, ``t``): R^T (p - t), with
    ``rot`` the 3x3 rotation's nine entries row by row and ``t`` a 3-tuple (:func:`pose_tuples`). Scalars
    only: a helper that takes an array costs two atomic reference-count updates per call."""
    dx = px - t[0]
    dy = py - t[1]
    dz = pz - t[2]
    return (dx * rot[0] + dy * rot[3] + dz * rot[6],
            dx * rot[1] + dy * rot[4] + dz * rot[7],
            dx * rot[2] + dy * rot[5] + dz * rot[8])


@njit(cache=True)
def pose_tuples(rot, t):
    """The (3, 3) ``rot`` and (3,) ``t`` arrays of a camera-to-world as the tuples :func:`camera_point`
    takes, read once per kernel call."""
    return ((rot[0, 0], rot[0, 1], rot[0, 2], rot[1, 0], rot[1, 1], rot[1, 2], rot[2, 0], rot[2, 1],
             rot[2, 2]), (t[0], t[1], t[2]))


@njit(inline="always", cache=True)
def _drawn(means, log_scales, i, rot, t, fx, fy, cx, cy, width, height, near, lim_x, lim_y, sigmas, low_pass,
           far, window, margin, use_depth):
    """The test of :func:`cull_rows` for row ``i`` (inlined into the loop over the rows; ``rot`` and ``t``
    as :func:`pose_tuples`). The screen radius (an exp and a square root) is computed only where it
    decides: for a centre outside the image, or one that the observed depth would hide when the
    footprint is small enough; a centre in the image puts the footprint there whatever the radius (>= 1)."""
    xw, yw, z = camera_point(means[i, 0], means[i, 1], means[i, 2], rot, t)
    if z <= near:
        return False
    x = xw / z
    y = yw / z
    u = fx * x + cx
    v = fy * y + cy
    inside = 0 <= u <= width and 0 <= v <= height
    if inside:
        if not use_depth:
            return True
        ui = int(math.floor(u))
        vi = int(math.floor(v))
        if not (ui < width and vi < height and z > far[vi, ui] + margin):
            return True  # not hidden, whatever the radius
    xc = min(max(x, -lim_x), lim_x)
    yc = min(max(y, -lim_y), lim_y)
    stretch = 1.0 + xc * xc + yc * yc
    s = math.exp(max(log_scales[i, 0], max(log_scales[i, 1], log_scales[i, 2]))) * max(fx, fy) / z
    radius = sigmas * math.sqrt(s * s * stretch + low_pass) + 1.0
    if inside:  # hidden if the footprint fits the depth window
        return not radius <= window
    if u + radius < 0 or u - radius > width or v + radius < 0 or v - radius > height:
        return False
    if use_depth and radius <= window:
        ui = int(math.floor(u))
        vi = int(math.floor(v))
        if 0 <= ui < width and 0 <= vi < height and z > far[vi, ui] + margin:
            return False
    return True


@njit(parallel=True, cache=True)
def cull_rows(means, log_scales, rot, t, fx, fy, cx, cy, width, height, near, lim_x, lim_y, sigmas,
              low_pass, far, window, margin, use_depth):
    """(N,) bool: the Gaussian's conservative footprint reaches the image and, with ``use_depth``, the
    observed surface (``far``: window maxima of the depth, inf where unknown) does not hide it."""
    n = means.shape[0]
    keep = np.zeros(n, dtype=np.bool_)
    rt, tt = pose_tuples(rot, t)
    for i in prange(n):
        keep[i] = _drawn(means, log_scales, i, rt, tt, fx, fy, cx, cy, width, height, near, lim_x, lim_y,
                         sigmas, low_pass, far, window, margin, use_depth)
    return keep


@njit(parallel=True, cache=True)
def cull_some_rows(rows, means, log_scales, rot, t, fx, fy, cx, cy, width, height, near, lim_x, lim_y,
                   sigmas, low_pass, far, window, margin, use_depth):
    """(len(rows),) bool: the test of :func:`cull_rows` for the rows ``rows`` only."""
    keep = np.zeros(rows.shape[0], dtype=np.bool_)
    rt, tt = pose_tuples(rot, t)
    for k in prange(rows.shape[0]):
        keep[k] = _drawn(means, log_scales, rows[k], rt, tt, fx, fy, cx, cy, width, height, near, lim_x,
                         lim_y, sigmas, low_pass, far, window, margin, use_depth)
    return keep


@njit(inline="always", cache=True)
def adam_row(param, exp_avg, exp_avg_sq, grad, k, i, step_size, bias2_sqrt, beta1, beta2, eps):
    """In place: the Adam step of row ``i`` of the (N, D) arrays with the gradient row ``grad[k]``,
    ``step_size`` = lr / (1 - beta1^t), ``bias2_sqrt`` = sqrt(1 - beta2^t)."""
    for d in range(param.shape[1]):
        g = grad[k, d]
        m = beta1 * exp_avg[i, d] + (1.0 - beta1) * g
        v = beta2 * exp_avg_sq[i, d] + (1.0 - beta2) * g * g
        exp_avg[i, d] = m
        exp_avg_sq[i, d] = v
        param[i, d] -= step_size * m / (math.sqrt(v) / bias2_sqrt + eps)


@njit(parallel=True, cache=True)
def adam_rows(param, exp_avg, exp_avg_sq, grad, rows, step_size, bias2_sqrt, beta1, beta2, eps):
    """In place, for every k: Adam on row ``rows[k]`` of the (N, D) arrays with gradient ``grad[k]``;
    ``step_size[k]`` = lr / (1 - beta1^t), ``bias2_sqrt[k]`` = sqrt(1 - beta2^t) of the row's own t."""
    for k in prange(rows.shape[0]):
        adam_row(param, exp_avg, exp_avg_sq, grad, k, rows[k], step_size[k], bias2_sqrt[k], beta1, beta2, eps)


@njit(parallel=True, cache=True)
def adam_nonzero_rows(params, exp_avgs, exp_avg_sqs, grads, rows, steps, rates, bias1_of, bias2_sqrt_of,
                      beta1, beta2, eps):
    """:func:`adam_rows` for all parameters at once, on the rows ``rows[k]`` whose gradient (``grads[p][k]``
    over every parameter p) is not all zero: each such row's step count t goes up by one and every parameter
    takes the Adam step of :func:`adam_rows` with the bias corrections ``bias1_of[t]`` = 1 - beta1^t and
    ``bias2_sqrt_of[t]`` = sqrt(1 - beta2^t) (tables made by numpy, whose vectorised pow can differ from
    a scalar one in the last bit). Returns which k were stepped. ``params`` etc. are tuples of (N, D_p)
    float32 arrays, ``grads`` of (len(rows), D_p)."""
    n = rows.shape[0]
    touched = np.zeros(n, dtype=np.bool_)
    for k in prange(n):
        nonzero = False
        for p in range(len(grads)):
            for d in range(grads[p].shape[1]):
                nonzero |= grads[p][k, d] != 0
        if not nonzero:
            continue
        touched[k] = True
        i = rows[k]
        steps[i] += 1
        bias1, bias2_sqrt = bias1_of[steps[i]], bias2_sqrt_of[steps[i]]
        for p in range(len(params)):
            adam_row(params[p], exp_avgs[p], exp_avg_sqs[p], grads[p], k, i, rates[p] / bias1, bias2_sqrt,
                     beta1, beta2, eps)
    return touched


@njit(parallel=True, cache=True)
def overlap_shares(points, rot, offset, fx, fy, cx, cy, width, height, border):
    """(M,): for camera m (world -> camera p R_m - offset_m), the share of ``points`` (P,3) in front of
    it and more than ``border`` px inside its image."""
    m_count, p_count = rot.shape[0], points.shape[0]
    share = np.zeros(m_count)
    for m in prange(m_count):
        inside = 0
        for p in range(p_count):
            x = points[p, 0] * rot[m, 0, 0] + points[p, 1] * rot[m, 1, 0] + points[p, 2] * rot[m, 2, 0]
            y = points[p, 0] * rot[m, 0, 1] + points[p, 1] * rot[m, 1, 1] + points[p, 2] * rot[m, 2, 1]
            z = points[p, 0] * rot[m, 0, 2] + points[p, 1] * rot[m, 1, 2] + points[p, 2] * rot[m, 2, 2]
            x -= offset[m, 0]
            y -= offset[m, 1]
            z -= offset[m, 2]
            if z <= 1e-6:
                continue
            u = fx * x / z + cx
            v = fy * y / z + cy
            if border < u < width - border and border < v < height - border:
                inside += 1
        share[m] = inside / p_count
    return share


# --------------------------------------------------------------------------- occlusion culling
@njit(parallel=True, cache=True)
def far_depth(depth, r):
    """The farthest observed depth within the (2r+1)^2 window (clipped to the image) around each pixel, inf
    where any pixel of the window is invalid (<= 0): ``gaussians._far_depth`` (two max-pools) in two
    parallel passes of shifted maxima. Max is exact, so the result is the same bit for bit."""
    height, width = depth.shape
    inf = np.float32(np.inf)
    rows = np.empty((height, width), np.float32)
    for i in prange(height):
        for j in range(width):
            rows[i, j] = depth[i, j] if depth[i, j] > 0 else inf
        x = rows[i].copy()
        for d in range(1, r + 1):
            for j in range(width - d):  # neighbours d to the right, then d to the left
                v = x[j + d]
                rows[i, j] = v if v > rows[i, j] else rows[i, j]
            for j in range(d, width):
                v = x[j - d]
                rows[i, j] = v if v > rows[i, j] else rows[i, j]
    out = np.empty((height, width), np.float32)
    for i in prange(height):
        for j in range(width):
            out[i, j] = rows[i, j]
        for ii in range(max(0, i - r), min(height, i + r + 1)):
            for j in range(width):
                v = rows[ii, j]
                out[i, j] = v if v > out[i, j] else out[i, j]
    return out


# --------------------------------------------------------------------------- densification and pruning
@njit(parallel=True, cache=True)
def window_any(mask, r):
    """(H, W) bool: some pixel of ``mask`` within the (2r+1)^2 window (clipped to the image) is set; a
    max-pool of the mask, in two parallel passes."""
    height, width = mask.shape
    rows = np.empty((height, width), np.bool_)
    for i in prange(height):
        for j in range(width):
            hit = False
            for jj in range(max(0, j - r), min(width, j + r + 1)):
                hit |= mask[i, jj]
            rows[i, j] = hit
    out = np.empty((height, width), np.bool_)
    for i in prange(height):
        for j in range(width):
            out[i, j] = False
        for ii in range(max(0, i - r), min(height, i + r + 1)):
            for j in range(width):
                out[i, j] |= rows[ii, j]
    return out


@njit(parallel=True, cache=True)
def edge_band(depth, band, jump, scale):
    """``densify.depth_edge_band`` of the float32 ``depth`` in three parallel passes, with torch's float32
    arithmetic (``jump`` and ``scale`` = 1 + jump as float32): the kinks of the inverse depth along rows
    and columns, dilated by band - 1, where the farthest depth within ``band`` (:func:`far_depth`) lies
    beyond depth x ``scale``, on valid depth. The same mask bit for bit (tested against the torch one)."""
    height, width = depth.shape
    zero, one, two, tiny = np.float32(0.0), np.float32(1.0), np.float32(2.0), np.float32(1e-12)
    inv = np.empty((height, width), np.float32)
    for i in prange(height):
        for j in range(width):
            x = depth[i, j]
            inv[i, j] = one / max(x, tiny) if x > 0 else zero
    edge = np.zeros((height, width), np.bool_)
    for i in prange(height):
        for j in range(width):
            if not depth[i, j] > 0:
                continue
            p = inv[i, j]
            kink = False
            if 0 < i < height - 1:
                kink |= (not depth[i - 1, j] > 0 or not depth[i + 1, j] > 0
                         or abs(inv[i - 1, j] - two * p + inv[i + 1, j]) > jump * p)
            if 0 < j < width - 1:
                kink |= (not depth[i, j - 1] > 0 or not depth[i, j + 1] > 0
                         or abs(inv[i, j - 1] - two * p + inv[i, j + 1]) > jump * p)
            edge[i, j] = kink
    if band > 1:
        edge = window_any(edge, band - 1)
    far = far_depth(depth, band)
    out = np.empty((height, width), np.bool_)
    for i in prange(height):
        for j in range(width):
            out[i, j] = edge[i, j] and far[i, j] > depth[i, j] * scale and depth[i, j] > 0
    return out


@njit(parallel=True, cache=True)
def colour_blocks(rgb, stride, colour_range):
    """``densify.colour_detail`` of the float32 (H, W, 3) ``rgb``: per ``stride`` x ``stride`` block, whether
    some channel spans more than ``colour_range`` (float32), the blocks on the right and bottom edges
    padded as the torch version pads them (-1 for the maximum, 2 for the minimum). (H, W) bool."""
    height, width = rgb.shape[0], rgb.shape[1]
    blocks_down, blocks_across = -(-height // stride), -(-width // stride)
    out = np.empty((height, width), np.bool_)
    for bi in prange(blocks_down):
        i0 = bi * stride
        i1 = min(height, i0 + stride)
        for bj in range(blocks_across):
            j0 = bj * stride
            j1 = min(width, j0 + stride)
            padded = i1 - i0 < stride or j1 - j0 < stride
            detail = False
            for c in range(3):
                hi = lo = rgb[i0, j0, c]
                for i in range(i0, i1):
                    for j in range(j0, j1):
                        x = rgb[i, j, c]
                        hi = max(hi, x)
                        lo = min(lo, x)
                if padded:
                    hi = max(hi, np.float32(-1.0))
                    lo = min(lo, np.float32(2.0))
                detail |= hi - lo > colour_range
            for i in range(i0, i1):
                for j in range(j0, j1):
                    out[i, j] = detail
    return out


@njit(parallel=True, cache=True)
def floaters(z, u, v, inside, depth, window, margin):
    """``densify.free_space_mask`` from the projected centres (camera depth ``z``, pixel ``u``, ``v``,
    ``inside`` the image): z < (the nearest observed depth within the (2 ``window`` + 1)^2 window, 0 when
    a pixel of it is invalid or the window leaves the image) - ``margin`` (float32), looked up for
    each centre instead of min-pooling the whole image."""
    height, width = depth.shape
    zero = np.float32(0.0)
    out = np.zeros(z.shape[0], dtype=np.bool_)
    for k in prange(z.shape[0]):
        if not inside[k]:
            continue
        ui, vi = u[k], v[k]
        nearest = zero
        if window == 0 or (window <= vi < height - window and window <= ui < width - window):
            nearest = np.float32(np.inf)
            for i in range(vi - window, vi + window + 1):
                for j in range(ui - window, ui + window + 1):
                    x = depth[i, j]
                    nearest = min(nearest, x if x > 0 else zero)
        out[k] = z[k] < nearest - margin
    return out


# --------------------------------------------------------------------------- coarse-Gaussian refresh
@njit(parallel=True, cache=True)
def coarse_rows(means, log_scales, rot, t, fx, fy, cx, cy, depth, factor, radius_per_z, min_radius, sigmas,
                margin):
    """(N,) bool: the Gaussian is seen whole and at a much finer resolution by this view (see
    ``densify.coarse_mask``): its largest scale exceeds ``factor`` x max(``radius_per_z`` x z,
    ``min_radius``), its ``sigmas``-sigma footprint lies inside the image, every observed depth in that
    footprint is valid and none is nearer than its centre by more than max(``margin``, scale), and the
    depth observed at its centre is within that tolerance of the centre (it is the visible surface)."""
    n = means.shape[0]
    height, width = depth.shape
    out = np.zeros(n, dtype=np.bool_)
    rt, tt = pose_tuples(rot, t)
    for i in prange(n):
        xw, yw, z = camera_point(means[i, 0], means[i, 1], means[i, 2], rt, tt)
        if z <= 1e-3:
            continue
        s = math.exp(max(log_scales[i, 0], max(log_scales[i, 1], log_scales[i, 2])))
        if s <= factor * max(radius_per_z * z, min_radius):
            continue
        u = fx * xw / z + cx
        v = fy * yw / z + cy
        r = sigmas * s * max(fx, fy) / z
        if u - r < 0 or u + r >= width or v - r < 0 or v + r >= height:
            continue
        tol = max(margin, s)
        ui = int(math.floor(u))
        vi = int(math.floor(v))
        centre = depth[vi, ui]
        if centre <= 0 or abs(centre - z) > tol:
            continue
        ok = True
        for y in range(int(math.floor(v - r)), int(math.floor(v + r)) + 1):
            for x in range(int(math.floor(u - r)), int(math.floor(u + r)) + 1):
                d = depth[y, x]
                if d <= 0 or d < z - tol:
                    ok = False
                    break
            if not ok:
                break
        out[i] = ok
    return out
