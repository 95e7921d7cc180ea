"""numba kernels of the online mapper (CPU): the view culling of
:func:`activesplat.splat.gaussians.frustum_rows` and the row-sparse Adam update of
:class:`activesplat.splat.optim.RowAdam`, each one parallel pass over the rows, where the torch
versions (kept for other devices, and compared in the tests) make a dozen passes and temporaries; and the
mapping loss of eqs. 5-7 with its gradient (:func:`activesplat.splat.losses.mapping_loss`) in three
parallel passes over the image rows instead of pytorch-msssim's ten convolutions and autograd."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(inline="always", cache=True)
def camera_point(means, i, rot, t):
    """Row ``i`` of ``means`` in the camera frame of a camera-to-world (``rot``, ``t``): R^T (p - t)."""
    dx = means[i, 0] - t[0]
    dy = means[i, 1] - t[1]
    dz = means[i, 2] - t[2]
    return (dx * rot[0, 0] + dy * rot[1, 0] + dz * rot[2, 0],
            dx * rot[0, 1] + dy * rot[1, 1] + dz * rot[2, 1],
            dx * rot[0, 2] + dy * rot[1, 2] + dz * rot[2, 2])


@njit(inline="always", cache=True)
def _drawn(means, log_scales, i, rot, t, fx, fy, cx, cy, width, height, near, lim_x, lim_y, sigmas, low_pass,
           far, window, margin, use_depth):
    """The test of :func:`cull_rows` for row ``i``."""
    xw, yw, z = camera_point(means, i, rot, t)
    if z <= near:
        return False
    x = xw / z
    y = yw / z
    xc = min(max(x, -lim_x), lim_x)
    yc = min(max(y, -lim_y), lim_y)
    stretch = 1.0 + xc * xc + yc * yc
    s = math.exp(max(log_scales[i, 0], max(log_scales[i, 1], log_scales[i, 2]))) * max(fx, fy) / z
    radius = sigmas * math.sqrt(s * s * stretch + low_pass) + 1.0
    u = fx * x + cx
    v = fy * y + cy
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
    for i in prange(n):
        keep[i] = _drawn(means, log_scales, i, rot, t, fx, fy, cx, cy, width, height, near, lim_x, lim_y,
                         sigmas, low_pass, far, window, margin, use_depth)
    return keep


@njit(parallel=True, cache=True)
def cull_some_rows(rows, means, log_scales, rot, t, fx, fy, cx, cy, width, height, near, lim_x, lim_y,
                   sigmas, low_pass, far, window, margin, use_depth):
    """(len(rows),) bool: the test of :func:`cull_rows` for the rows ``rows`` only."""
    keep = np.zeros(rows.shape[0], dtype=np.bool_)
    for k in prange(rows.shape[0]):
        keep[k] = _drawn(means, log_scales, rows[k], rot, t, fx, fy, cx, cy, width, height, near, lim_x,
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


# --------------------------------------------------------------------------- the mapping loss, eqs. 5-7
@njit(parallel=True, cache=True, error_model="numpy")
def loss_rows(rgb, depth, obs_rgb, obs_depth, win):
    """Pass 1 of :func:`mapping_loss_grad`, parallel over image rows: the masked images X = rgb * valid,
    Y = obs_rgb * valid blurred along the rows (valid convolution with ``win``) into h (5, 3, H, Wo) =
    (X, Y, XX, YY, XY); per-row sums of the colour L1 (mean over channels), depth L1 and valid pixels."""
    height, width = depth.shape
    nw = win.shape[0]
    wo = width - nw + 1
    h = np.empty((5, 3, height, wo), np.float32)
    sums = np.zeros((height, 3))
    for i in prange(height):
        x = np.empty(width, np.float32)
        y = np.empty(width, np.float32)
        c_sum = 0.0
        d_sum = 0.0
        n_valid = 0
        for j in range(width):
            if obs_depth[i, j] > 0:
                n_valid += 1
                d_sum += abs(depth[i, j] - obs_depth[i, j])
                c_sum += (abs(rgb[i, j, 0] - obs_rgb[i, j, 0]) + abs(rgb[i, j, 1] - obs_rgb[i, j, 1])
                          + abs(rgb[i, j, 2] - obs_rgb[i, j, 2])) / 3.0
        sums[i, 0], sums[i, 1], sums[i, 2] = c_sum, d_sum, n_valid
        for c in range(3):
            for j in range(width):
                ok = obs_depth[i, j] > 0
                x[j] = rgb[i, j, c] if ok else np.float32(0.0)
                y[j] = obs_rgb[i, j, c] if ok else np.float32(0.0)
            for q in range(5):
                for j in range(wo):
                    h[q, c, i, j] = 0.0
            for k in range(nw):
                g = win[k]
                for j in range(wo):
                    xv, yv = x[j + k], y[j + k]
                    h[0, c, i, j] += g * xv
                    h[1, c, i, j] += g * yv
                    h[2, c, i, j] += g * (xv * xv)
                    h[3, c, i, j] += g * (yv * yv)
                    h[4, c, i, j] += g * (xv * yv)
    return h, sums


@njit(parallel=True, cache=True, error_model="numpy")
def ssim_columns(h, win, c1, c2):
    """Pass 2, parallel over output rows: the blur along the columns, the SSIM map and its derivatives
    with respect to the blurred X, XX and XY (d (3, 3, Ho, Wo)); per-row sums of the SSIM map (3 Ho,)."""
    nw = win.shape[0]
    _, nc, height, wo = h.shape
    ho = height - nw + 1
    d = np.empty((3, nc, ho, wo), np.float32)
    row_sum = np.zeros(nc * ho)
    for r in prange(nc * ho):
        c, io = r // ho, r % ho
        acc = np.zeros((5, wo), np.float32)
        for k in range(nw):
            g = win[k]
            for q in range(5):
                for j in range(wo):
                    acc[q, j] += g * h[q, c, io + k, j]
        ssim_row = np.empty(wo, np.float32)
        for j in range(wo):  # no reduction in this loop, so that it vectorises
            m1, m2 = acc[0, j], acc[1, j]
            s11, s22, s12 = acc[2, j] - m1 * m1, acc[3, j] - m2 * m2, acc[4, j] - m1 * m2
            a1, b1 = np.float32(2.0) * m1 * m2 + c1, m1 * m1 + m2 * m2 + c1
            a2, b2 = np.float32(2.0) * s12 + c2, s11 + s22 + c2
            inv = np.float32(1.0) / (b1 * b2)
            ssim = a1 * a2 * inv
            ssim_row[j] = ssim
            d[0, c, io, j] = (np.float32(2.0) * m2 * (a2 - a1) * inv
                              - np.float32(2.0) * m1 * ssim * (np.float32(1.0) / b1 - np.float32(1.0) / b2))
            d[1, c, io, j] = -ssim / b2
            d[2, c, io, j] = np.float32(2.0) * a1 * inv
        s = 0.0
        for j in range(wo):
            s += ssim_row[j]
        row_sum[r] = s
    return d, row_sum


@njit(parallel=True, cache=True, error_model="numpy")
def loss_grad_rows(d, win, rgb, depth, obs_rgb, obs_depth, w_ssim, w_color, w_depth):
    """Pass 3, parallel over image rows: the transposed blurs of the SSIM derivatives back to the image,
    chained through X, XX = X^2 and XY, plus the L1 terms: dL/drgb (H, W, 3) and dL/ddepth (H, W) of
    L = w_ssim * SSIM + w_color * sum |rgb - obs| / 3 + w_depth * sum |depth - obs_depth| over valid pixels
    (the caller folds the means into the weights)."""
    height, width = depth.shape
    nw = win.shape[0]
    nc, ho, wo = d.shape[1], d.shape[2], d.shape[3]
    g_rgb = np.empty((height, width, 3), np.float32)
    g_depth = np.empty((height, width), np.float32)
    for i in prange(height):
        col = np.empty((3, wo), np.float32)
        full = np.empty((3, width), np.float32)
        for c in range(nc):
            for q in range(3):
                for j in range(wo):
                    col[q, j] = 0.0
            for k in range(max(0, i - ho + 1), min(nw, i + 1)):  # output rows io = i - k in [0, Ho)
                g = win[k]
                for q in range(3):
                    for j in range(wo):
                        col[q, j] += g * d[q, c, i - k, j]
            for q in range(3):
                for j in range(width):
                    full[q, j] = 0.0
            for k in range(nw):
                g = win[k]
                for q in range(3):
                    for j in range(wo):
                        full[q, j + k] += g * col[q, j]
            for j in range(width):
                ok = obs_depth[i, j] > 0
                xv = rgb[i, j, c] if ok else np.float32(0.0)
                yv = obs_rgb[i, j, c] if ok else np.float32(0.0)
                diff = rgb[i, j, c] - obs_rgb[i, j, c]
                sign = np.float32(1.0) if diff > 0 else (np.float32(-1.0) if diff < 0 else np.float32(0.0))
                gx = w_ssim * (full[0, j] + np.float32(2.0) * xv * full[1, j] + yv * full[2, j])
                g_rgb[i, j, c] = gx + w_color * sign if ok else np.float32(0.0)
        for j in range(width):
            diff = depth[i, j] - obs_depth[i, j]
            sign = np.float32(1.0) if diff > 0 else (np.float32(-1.0) if diff < 0 else np.float32(0.0))
            g_depth[i, j] = w_depth * sign if obs_depth[i, j] > 0 else np.float32(0.0)
    return g_rgb, g_depth


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
    for i in prange(n):
        xw, yw, z = camera_point(means, i, rot, t)
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
