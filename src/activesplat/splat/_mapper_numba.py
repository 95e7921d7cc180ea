"""numba kernels of the online mapper (CPU): the view culling of
:func:`activesplat.splat.gaussians.frustum_rows` and the row-sparse Adam update of
:class:`activesplat.splat.optim.RowAdam`, each one parallel pass over the rows, where the torch
versions (kept for other devices, and compared in the tests) make a dozen passes and temporaries; and the
mapping loss of eqs. 5-7 with its gradient (:func:`activesplat.splat.losses.mapping_loss`) in three
parallel passes over the image rows instead of pytorch-msssim's ten convolutions and autograd; and the
per-frame masks of :mod:`activesplat.splat.densify` that torch computes with max-pools over the whole
image (the depth-edge band, the colour-detail blocks, the floater test of the pruning), which give the
torch versions' masks bit for bit (the tests compare them)."""

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


# --------------------------------------------------------------------------- the mapping loss, eqs. 5-7
@njit(inline="always", cache=True)
def blur_taps(src, start, step, win, out):
    """In place: out[j] = the sum over k = 0, 1, ... of win[k] * src[start + step k + j], taken in that order
    from 0 (float32), ``src`` 1-D: one row of a valid convolution with ``win``, along a row (``step`` 1),
    down a column of a flattened image (``step`` its width) or transposed (``step`` negative). With the
    11 taps of pytorch-msssim's default window the sum is kept in a register over k, so that the loop over
    j vectorises (a loop over k inside it would not, and k outside it stores every partial sum); any other
    window takes the plain loops, which add the same products in the same order."""
    n = out.shape[0]
    if win.shape[0] == 11:
        g0, g1, g2, g3, g4, g5 = win[0], win[1], win[2], win[3], win[4], win[5]
        g6, g7, g8, g9, g10 = win[6], win[7], win[8], win[9], win[10]
        # unsigned offsets: every index is >= 0, and numba then leaves out its negative-index wraparound,
        # which would keep the loop from vectorising
        u0, u1, u2 = np.uint64(start), np.uint64(start + step), np.uint64(start + 2 * step)
        u3, u4, u5 = np.uint64(start + 3 * step), np.uint64(start + 4 * step), np.uint64(start + 5 * step)
        u6, u7, u8 = np.uint64(start + 6 * step), np.uint64(start + 7 * step), np.uint64(start + 8 * step)
        u9, u10 = np.uint64(start + 9 * step), np.uint64(start + 10 * step)
        for j in range(n):
            c = np.uint64(j)
            acc = np.float32(0.0)
            acc += g0 * src[u0 + c]
            acc += g1 * src[u1 + c]
            acc += g2 * src[u2 + c]
            acc += g3 * src[u3 + c]
            acc += g4 * src[u4 + c]
            acc += g5 * src[u5 + c]
            acc += g6 * src[u6 + c]
            acc += g7 * src[u7 + c]
            acc += g8 * src[u8 + c]
            acc += g9 * src[u9 + c]
            acc += g10 * src[u10 + c]
            out[j] = acc
        return
    for j in range(n):
        out[j] = 0.0
    for k in range(win.shape[0]):
        g = win[k]
        offset = start + step * k
        for j in range(n):
            out[j] += g * src[offset + j]


@njit(inline="always", cache=True)
def sign(x):
    """np.sign of a float32 as a float32 (0 for 0 and NaN), without branches: the sign of a colour or depth
    difference is as good as random, and a branch on it is mispredicted half of the time."""
    return np.float32(x > 0) - np.float32(x < 0)


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
    zero = np.float32(0.0)
    for i in prange(height):
        src = np.empty((3, 5, width), np.float32)  # per channel: X, Y, XX, YY, XY of this row
        c_sum = 0.0
        d_sum = 0.0
        n_valid = 0
        for j in range(width):
            ok = obs_depth[i, j] > 0
            if ok:
                n_valid += 1
                d_sum += abs(depth[i, j] - obs_depth[i, j])
                c_sum += (abs(rgb[i, j, 0] - obs_rgb[i, j, 0]) + abs(rgb[i, j, 1] - obs_rgb[i, j, 1])
                          + abs(rgb[i, j, 2] - obs_rgb[i, j, 2])) / 3.0
            for c in range(3):
                xv = rgb[i, j, c] if ok else zero
                yv = obs_rgb[i, j, c] if ok else zero
                src[c, 0, j] = xv
                src[c, 1, j] = yv
                src[c, 2, j] = xv * xv
                src[c, 3, j] = yv * yv
                src[c, 4, j] = xv * yv
        sums[i, 0], sums[i, 1], sums[i, 2] = c_sum, d_sum, n_valid
        for c in range(3):
            for q in range(5):
                blur_taps(src[c, q], 0, 1, win, h[q, c, i])
    return h, sums


@njit(parallel=True, cache=True, error_model="numpy")
def ssim_columns(h, win, c1, c2):
    """Pass 2, parallel over output rows: the blur along the columns, the SSIM map and its derivatives
    with respect to the blurred X, XX and XY; per-row sums of the SSIM map (3 Ho,). The derivatives d
    (3, 3, Ho + 2 (nw - 1), Wo + 2 (nw - 1)) come with a border of nw - 1 zeros on each side of both image
    axes, so that the transposed blurs of pass 3 need no bounds (a zero term leaves a sum that started
    from 0 as it was, bit for bit)."""
    nw = win.shape[0]
    _, nc, height, wo = h.shape
    ho = height - nw + 1
    p = nw - 1
    d = np.zeros((3, nc, ho + 2 * p, wo + 2 * p), np.float32)
    row_sum = np.zeros(nc * ho)
    flat = h.reshape(5, nc, height * wo)
    for r in prange(nc * ho):
        c, io = r // ho, r % ho
        acc = np.empty((5, wo), np.float32)
        for q in range(5):
            blur_taps(flat[q, c], io * wo, wo, win, acc[q])
        ssim_row = np.empty(wo, np.float32)
        d0, d1, d2 = d[0, c, io + p, p:p + wo], d[1, c, io + p, p:p + wo], d[2, c, io + p, p:p + wo]
        for j in range(wo):  # no reduction in this loop, so that it vectorises
            m1, m2 = acc[0, j], acc[1, j]
            s11, s22, s12 = acc[2, j] - m1 * m1, acc[3, j] - m2 * m2, acc[4, j] - m1 * m2
            a1, b1 = np.float32(2.0) * m1 * m2 + c1, m1 * m1 + m2 * m2 + c1
            a2, b2 = np.float32(2.0) * s12 + c2, s11 + s22 + c2
            inv = np.float32(1.0) / (b1 * b2)
            ssim = a1 * a2 * inv
            ssim_row[j] = ssim
            d0[j] = (np.float32(2.0) * m2 * (a2 - a1) * inv
                     - np.float32(2.0) * m1 * ssim * (np.float32(1.0) / b1 - np.float32(1.0) / b2))
            d1[j] = -ssim / b2
            d2[j] = np.float32(2.0) * a1 * inv
        s = 0.0
        for j in range(wo):
            s += ssim_row[j]
        row_sum[r] = s
    return d, row_sum


@njit(parallel=True, cache=True, error_model="numpy")
def loss_grad_rows(d, win, rgb, depth, obs_rgb, obs_depth, w_ssim, w_color, w_depth):
    """Pass 3, parallel over image rows: the transposed blurs of the SSIM derivatives ``d`` (zero-bordered,
    from :func:`ssim_columns`) back to the image, chained through X, XX = X^2 and XY, plus the L1 terms:
    dL/drgb (H, W, 3) and dL/ddepth (H, W) of L = w_ssim * SSIM + w_color * sum |rgb - obs| / 3 + w_depth
    * sum |depth - obs_depth| over valid pixels (the caller folds the means into the weights)."""
    height, width = depth.shape
    nw = win.shape[0]
    p = nw - 1
    nc, hp, wp = d.shape[1], d.shape[2], d.shape[3]
    flat = d.reshape(3, nc, hp * wp)
    g_rgb = np.empty((height, width, 3), np.float32)
    g_depth = np.empty((height, width), np.float32)
    zero, two = np.float32(0.0), np.float32(2.0)
    for i in prange(height):
        col = np.empty((3, wp), np.float32)
        full = np.empty((nc, 3, width), np.float32)
        for c in range(nc):
            for q in range(3):  # over the output rows io = i - k, k = 0, 1, ... (rows outside are zeros)
                blur_taps(flat[q, c], (i + p) * wp, -wp, win, col[q])
            for q in range(3):  # over the output columns jo = j - k
                blur_taps(col[q], p, -1, win, full[c, q])
        for j in range(width):
            ok = obs_depth[i, j] > 0
            for c in range(3):
                x = rgb[i, j, c]
                y = obs_rgb[i, j, c]
                xv = x if ok else zero
                yv = y if ok else zero
                gx = w_ssim * (full[c, 0, j] + two * xv * full[c, 1, j] + yv * full[c, 2, j])
                g_rgb[i, j, c] = gx + w_color * sign(x - y) if ok else zero
            g_depth[i, j] = w_depth * sign(depth[i, j] - obs_depth[i, j]) if ok else zero
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
