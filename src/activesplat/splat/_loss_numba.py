"""numba kernels of the mapping loss of eqs. 5-7 and its gradient
(:func:`activesplat.splat.losses.mapping_loss`): three parallel passes over the image rows instead of
pytorch-msssim's ten convolutions and autograd, with pytorch-msssim's window and constants (the tests
compare the two)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


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
