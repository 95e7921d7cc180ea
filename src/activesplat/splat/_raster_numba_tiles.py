"""numba kernels: tile binning, front-to-back compositing and its reverse-order backward pass.

Every instance (Gaussian, tile) is one entry of the per-tile lists, depth-sorted with a stable sort.
Within a tile each Gaussian only visits the pixels where alpha can reach 1/255 (the bounding box of
the ellipse o exp(-power) = 1/255), which gives exactly the 3DGS result with far less work than
testing all 256 pixels. Tiles run in parallel (prange, static schedule); the backward pass writes
one gradient row per instance and a second parallel loop sums them per Gaussian (no atomics).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from activesplat.splat._raster_common import RASTER

F32 = np.float32
TILE = RASTER.tile_size
ALPHA_MAX = F32(RASTER.alpha_max)
ALPHA_MIN = F32(RASTER.alpha_min)
T_MIN = F32(RASTER.transmittance_min)
T_MEDIAN = F32(RASTER.median_transmittance)
LOG_255 = F32(np.log(1.0 / RASTER.alpha_min))
ZERO, HALF, ONE, TWO = F32(0.0), F32(0.5), F32(1.0), F32(2.0)
BOX_PAD = F32(0.01)  # pixels added to the alpha >= 1/255 box against rounding
# columns of the per-instance feature rows
MX, MY, CA, CB, CC, OP, CR, CG, CBL, DZ, HX, HY, PMAX = range(13)
N_FEAT = 13
POWER_PAD = F32(1e-3)  # margin on the power cut-off so rounding never skips a term the exact test keeps
N_GRAD = 10  # v_mean2d (2), v_conic (3), v_opacity, v_colour (3), v_depth


@njit(cache=True, error_model="numpy")
def build_tile_lists(order, rects, grid_x, n_tiles):
    """Counting sort of (Gaussian, tile) instances by tile. ``order`` lists the rendered Gaussians
    front to back, so each tile's list stays depth-sorted (the sort is stable). Returns
    tile_starts (n_tiles+1,), ids (n_inst,) and, per Gaussian in ``order``, the CSR emit_start with
    slot[e] = list position of its e-th instance (used to sum instance gradients per Gaussian)."""
    n_vis = order.shape[0]
    emit_start = np.zeros(n_vis + 1, np.int64)
    counts = np.zeros(n_tiles + 1, np.int64)
    for r in range(n_vis):
        g = order[r]
        emit_start[r + 1] = emit_start[r] + (rects[g, 1] - rects[g, 0]) * (rects[g, 3] - rects[g, 2])
        for ty in range(rects[g, 2], rects[g, 3]):
            for tx in range(rects[g, 0], rects[g, 1]):
                counts[ty * grid_x + tx + 1] += 1
    tile_starts = np.cumsum(counts)
    fill = tile_starts[:-1].copy()
    ids = np.empty(emit_start[-1], np.int64)
    slot = np.empty(emit_start[-1], np.int64)
    e = 0
    for r in range(n_vis):
        g = order[r]
        for ty in range(rects[g, 2], rects[g, 3]):
            for tx in range(rects[g, 0], rects[g, 1]):
                t = ty * grid_x + tx
                ids[fill[t]] = g
                slot[e] = fill[t]
                fill[t] += 1
                e += 1
    return tile_starts, ids, emit_start, slot


@njit(cache=True, error_model="numpy")
def stable_depth_order(candidates, depths):
    """``candidates`` sorted by depth (all > 0), stable: LSD radix sort on the float32 bit patterns
    (order-preserving for positive floats), 3 passes of 11 bits; equals np.argsort(kind="stable")."""
    keys = depths.view(np.uint32)
    order = candidates.copy()
    scratch = np.empty_like(order)
    for shift in (0, 11, 22):
        counts = np.zeros(2049, np.int64)
        for r in range(order.shape[0]):
            counts[((keys[order[r]] >> shift) & 2047) + 1] += 1
        for d in range(2048):
            counts[d + 1] += counts[d]
        for r in range(order.shape[0]):
            digit = (keys[order[r]] >> shift) & 2047
            scratch[counts[digit]] = order[r]
            counts[digit] += 1
        order, scratch = scratch, order
    return order


@njit(cache=True, parallel=True, error_model="numpy")
def gather_features(order, ids, means2d, conics, opacities, colors, depths):
    """Instance rows (n_inst, 13), contiguous per tile: mean2d, conic, opacity, colour, depth, the
    half extents of the box where alpha can reach 1/255 (|dx| <= sqrt(2 ln(255 o) Sigma_xx)) and the
    power above which alpha < 1/255 for sure (ln(255 o) plus a margin), saving most skipped exps."""
    aux = np.zeros((means2d.shape[0], 3), F32)
    for r in prange(order.shape[0]):
        g = order[r]
        a, b, c = conics[g, 0], conics[g, 1], conics[g, 2]
        level = TWO * (np.log(max(opacities[g], ALPHA_MIN)) + LOG_255)
        det = a * c - b * b
        aux[g, 0] = np.sqrt(max(ZERO, level * c / det)) + BOX_PAD
        aux[g, 1] = np.sqrt(max(ZERO, level * a / det)) + BOX_PAD
        aux[g, 2] = HALF * level + POWER_PAD
    feat = np.empty((ids.shape[0], N_FEAT), F32)
    for k in prange(ids.shape[0]):
        g = ids[k]
        feat[k, MX], feat[k, MY] = means2d[g, 0], means2d[g, 1]
        feat[k, CA], feat[k, CB], feat[k, CC] = conics[g, 0], conics[g, 1], conics[g, 2]
        feat[k, OP], feat[k, CR], feat[k, CG] = opacities[g], colors[g, 0], colors[g, 1]
        feat[k, CBL], feat[k, DZ] = colors[g, 2], depths[g]
        feat[k, HX], feat[k, HY], feat[k, PMAX] = aux[g, 0], aux[g, 1], aux[g, 2]
    return feat


@njit(cache=True, error_model="numpy")
def pixel_range(centre, half, lo, hi):
    """Pixel indices [p0, p1] of [lo, hi) whose centres p + 0.5 lie within centre +- half."""
    p0 = max(F32(lo), np.ceil(centre - HALF - half))
    p1 = min(F32(hi - 1), np.floor(centre - HALF + half))
    return int(p0), int(p1)


@njit(cache=True, error_model="numpy")
def splat_alpha(mx, my, a, b, c, o, pmax, j, i):
    """(alpha, G, dx, dy) of one Gaussian at pixel (row i, column j); alpha = 0 when skipped
    (power < 0 or alpha < 1/255). Forward and backward share it so they skip the same terms."""
    dx = mx - (F32(j) + HALF)
    dy = my - (F32(i) + HALF)
    power = HALF * (a * dx * dx + c * dy * dy) + b * dx * dy
    if power < ZERO or power > pmax:
        return ZERO, ZERO, dx, dy
    gauss = np.exp(-power)
    alpha = min(ALPHA_MAX, o * gauss)
    if alpha < ALPHA_MIN:
        return ZERO, gauss, dx, dy
    return alpha, gauss, dx, dy


@njit(cache=True, error_model="numpy")
def tile_bounds(t, grid_x, width, height):
    x0, y0 = (t % grid_x) * TILE, (t // grid_x) * TILE
    return x0, min(x0 + TILE, width), y0, min(y0 + TILE, height)


@njit(cache=True, parallel=True, error_model="numpy")
def composite_forward(tile_starts, feat, width, height, background, rgb, depth, trans, median, last):
    """Front-to-back blending per tile; fills rgb (H,W,3), depth, final T, median depth and the list
    position of the last blended instance (-1 if none)."""
    grid_x = (width + TILE - 1) // TILE
    for t in prange(tile_starts.shape[0] - 1):
        x0, x1, y0, y1 = tile_bounds(t, grid_x, width, height)
        for i in range(y0, y1):
            for j in range(x0, x1):
                trans[i, j], depth[i, j], median[i, j], last[i, j] = ONE, ZERO, ZERO, -1
                rgb[i, j, 0], rgb[i, j, 1], rgb[i, j, 2] = ZERO, ZERO, ZERO
        done = np.zeros((TILE, TILE), np.bool_)
        n_left = (x1 - x0) * (y1 - y0)
        for k in range(tile_starts[t], tile_starts[t + 1]):
            if n_left == 0:
                break
            mx, my, a, b, c, o = feat[k, MX], feat[k, MY], feat[k, CA], feat[k, CB], feat[k, CC], feat[k, OP]
            cr, cg, cb, z, pmax = feat[k, CR], feat[k, CG], feat[k, CBL], feat[k, DZ], feat[k, PMAX]
            jx0, jx1 = pixel_range(mx, feat[k, HX], x0, x1)
            iy0, iy1 = pixel_range(my, feat[k, HY], y0, y1)
            for i in range(iy0, iy1 + 1):
                for j in range(jx0, jx1 + 1):
                    if done[i - y0, j - x0]:
                        continue
                    alpha, _g, _dx, _dy = splat_alpha(mx, my, a, b, c, o, pmax, j, i)
                    if alpha == ZERO:
                        continue
                    t_now = trans[i, j]
                    t_next = t_now * (ONE - alpha)
                    if t_next < T_MIN:
                        done[i - y0, j - x0] = True
                        n_left -= 1
                        continue
                    w = alpha * t_now
                    rgb[i, j, 0] += w * cr
                    rgb[i, j, 1] += w * cg
                    rgb[i, j, 2] += w * cb
                    depth[i, j] += w * z
                    if t_now >= T_MEDIAN and t_next < T_MEDIAN:
                        median[i, j] = z
                    trans[i, j] = t_next
                    last[i, j] = k
        for i in range(y0, y1):
            for j in range(x0, x1):
                for ch in range(3):
                    rgb[i, j, ch] += background[ch] * trans[i, j]


@njit(cache=True, parallel=True, error_model="numpy")
def composite_backward(tile_starts, feat, width, height, background, trans_final, last,
                       v_rgb, v_depth, v_alpha):
    """Reverse-order pass of :func:`composite_forward` (3DGS ``renderCUDA`` backward). Returns one
    gradient row per instance: v_mean2d (2), v_conic (3), v_opacity, v_colour (3), v_depth.

    Per pixel, with T_i the transmittance before Gaussian i and S_i the sums of w_j c_j (w_j z_j)
    over the Gaussians behind it: dC/dalpha_i = c_i T_i - (S_i + bg T_final) / (1 - alpha_i),
    dD/dalpha_i = z_i T_i - S_i / (1 - alpha_i), d(1 - T_final)/dalpha_i = T_final / (1 - alpha_i).
    """
    grid_x = (width + TILE - 1) // TILE
    grads = np.zeros((feat.shape[0], N_GRAD), F32)
    for t in prange(tile_starts.shape[0] - 1):
        x0, x1, y0, y1 = tile_bounds(t, grid_x, width, height)
        trans = np.empty((TILE, TILE), F32)
        suffix = np.zeros((4, TILE, TILE), F32)  # S for r, g, b and depth
        k_end = tile_starts[t] - 1
        for i in range(y0, y1):
            for j in range(x0, x1):
                trans[i - y0, j - x0] = trans_final[i, j]
                k_end = max(k_end, last[i, j])
        for k in range(k_end, tile_starts[t] - 1, -1):
            mx, my, a, b, c, o = feat[k, MX], feat[k, MY], feat[k, CA], feat[k, CB], feat[k, CC], feat[k, OP]
            cr, cg, cb, z, pmax = feat[k, CR], feat[k, CG], feat[k, CBL], feat[k, DZ], feat[k, PMAX]
            jx0, jx1 = pixel_range(mx, feat[k, HX], x0, x1)
            iy0, iy1 = pixel_range(my, feat[k, HY], y0, y1)
            g_mx = g_my = g_a = g_b = g_c = g_o = g_r = g_g = g_bl = g_z = ZERO
            for i in range(iy0, iy1 + 1):
                pi = i - y0
                for j in range(jx0, jx1 + 1):
                    if last[i, j] < k:
                        continue
                    alpha, gauss, dx, dy = splat_alpha(mx, my, a, b, c, o, pmax, j, i)
                    if alpha == ZERO:
                        continue
                    pj = j - x0
                    inv_one_minus = ONE / (ONE - alpha)
                    t_before = trans[pi, pj] * inv_one_minus
                    trans[pi, pj] = t_before
                    w = alpha * t_before
                    t_fin = trans_final[i, j]
                    vr, vg, vb, vd = v_rgb[i, j, 0], v_rgb[i, j, 1], v_rgb[i, j, 2], v_depth[i, j]
                    sr, sg = suffix[0, pi, pj], suffix[1, pi, pj]
                    sb, sd = suffix[2, pi, pj], suffix[3, pi, pj]
                    v_al = (v_alpha[i, j] * t_fin
                            - vr * (sr + background[0] * t_fin) - vg * (sg + background[1] * t_fin)
                            - vb * (sb + background[2] * t_fin) - vd * sd) * inv_one_minus
                    v_al += (vr * cr + vg * cg + vb * cb + vd * z) * t_before
                    g_r += w * vr
                    g_g += w * vg
                    g_bl += w * vb
                    g_z += w * vd
                    suffix[0, pi, pj], suffix[1, pi, pj] = sr + w * cr, sg + w * cg
                    suffix[2, pi, pj], suffix[3, pi, pj] = sb + w * cb, sd + w * z
                    if o * gauss > ALPHA_MAX:
                        continue  # alpha clamped at 0.99: no gradient to opacity or the footprint
                    g_o += gauss * v_al
                    v_pow = -alpha * v_al
                    g_mx += v_pow * (a * dx + b * dy)
                    g_my += v_pow * (b * dx + c * dy)
                    g_a += v_pow * HALF * dx * dx
                    g_b += v_pow * dx * dy
                    g_c += v_pow * HALF * dy * dy
            grads[k, 0], grads[k, 1], grads[k, 2], grads[k, 3], grads[k, 4] = g_mx, g_my, g_a, g_b, g_c
            grads[k, 5], grads[k, 6], grads[k, 7], grads[k, 8], grads[k, 9] = g_o, g_r, g_g, g_bl, g_z
    return grads


@njit(cache=True, parallel=True, error_model="numpy")
def sum_instance_grads(order, emit_start, slot, grads, n):
    """Per-Gaussian sums of the instance gradient rows, parallel over Gaussians (no atomics)."""
    out = np.zeros((n, N_GRAD), F32)
    for r in prange(order.shape[0]):
        g = order[r]
        for e in range(emit_start[r], emit_start[r + 1]):
            k = slot[e]
            for c in range(N_GRAD):
                out[g, c] += grads[k, c]
    return out
