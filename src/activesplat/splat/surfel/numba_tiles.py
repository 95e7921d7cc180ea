"""numba kernels: front-to-back compositing of 2DGS surfels per 16x16 tile and its reverse-order backward.

Tile lists, the stable depth sort and the per-tile pixel ranges are those of the 3D rasterizer
(``splat.raster.numba_tiles``). Ray-splat intersection in relative pixel coordinates (dx, dy) = x - c:
with the surfel's M (see ``numba_project``) the cross product c = h_u x h_v of the paper
reduces to c = (z (B1 dx - B0 dy), z (A0 dy - A1 dx), D0 + E dx + F dy), D0 = A0 B1 - A1 B0,
E = A1 B2 - B1 A2, F = B0 A2 - A0 B2, so (u, v) = c_xy / c_z costs a few multiply-adds per pixel.
The backward pass accumulates, per instance, sums over pixels of the gradients on the numerators
P, Q and the denominator times (1, dx, dy) and turns them into gradients on M, c and z once.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from activesplat.splat.raster.numba_tiles import (
    ALPHA_MAX,
    ALPHA_MIN,
    T_MEDIAN,
    T_MIN,
    TILE,
    pixel_range,
    tile_bounds,
)
from activesplat.splat.surfel.constants import SURFEL

F32 = np.float32
LOG_255 = F32(SURFEL.log_255)
FILTER = F32(SURFEL.filter_inv_square)
POWER_PAD = F32(SURFEL.power_pad)
ZERO, HALF, ONE, TWO = F32(0.0), F32(0.5), F32(1.0), F32(2.0)
# columns of the per-instance feature rows
U, V, Z, A0, A1, A2, B0, B1, B2, D0, EE, FF, OP, PMAX, BX, BY, HX, HY, NX, NY, NZ, CR, CG, CB = range(24)
N_FEAT = 24
N_GRAD = 16  # v_mean2d (2), v_depth, v_tmat (6: A0 A1 A2 B0 B1 B2), v_normal (3), v_opacity, v_colour (3)


@njit(cache=True, parallel=True, error_model="numpy")
def gather_features(order, ids, means2d, depths, tmat, normals, opacities, colors, boxes):
    """Instance rows (n_inst, 24), contiguous per tile: centre, depth, M, the intersection
    coefficients D0, E, F, normal, opacity, colour, pixel box and the power above which alpha < 1/255
    for sure (ln(255 o) plus a margin)."""
    feat = np.empty((ids.shape[0], N_FEAT), F32)
    for k in prange(ids.shape[0]):
        g = ids[k]
        a0, a1, a2, b0, b1, b2 = tmat[g, 0], tmat[g, 1], tmat[g, 2], tmat[g, 3], tmat[g, 4], tmat[g, 5]
        feat[k, U], feat[k, V], feat[k, Z] = means2d[g, 0], means2d[g, 1], depths[g]
        feat[k, A0], feat[k, A1], feat[k, A2], feat[k, B0], feat[k, B1], feat[k, B2] = a0, a1, a2, b0, b1, b2
        feat[k, D0], feat[k, EE], feat[k, FF] = a0 * b1 - a1 * b0, a1 * b2 - b1 * a2, b0 * a2 - a0 * b2
        feat[k, NX], feat[k, NY], feat[k, NZ] = normals[g, 0], normals[g, 1], normals[g, 2]
        feat[k, OP] = opacities[g]
        feat[k, CR], feat[k, CG], feat[k, CB] = colors[g, 0], colors[g, 1], colors[g, 2]
        for c in range(4):
            feat[k, BX + c] = boxes[g, c]
        feat[k, PMAX] = np.log(max(opacities[g], ALPHA_MIN)) + LOG_255 + POWER_PAD
    return feat


@njit(cache=True, error_model="numpy")
def surfel_pixel(s, j, i):
    """(alpha, G, ray_wins, u, v, c_z, z_k, dx, dy) of the surfel with feature row ``s`` (the tuple
    of :func:`row`) at pixel (row i, column j). alpha = 0 when skipped (power above the cut-off
    or alpha < 1/255); forward and backward share it so they skip the same terms. z_k: intersection
    depth where the ray-splat term wins, else the centre's."""
    dx = F32(j) + HALF - s[U]
    dy = F32(i) + HALF - s[V]
    z = s[Z]
    den = s[D0] + dx * s[EE] + dy * s[FF]
    su = sv = ZERO
    wins = False
    rho = FILTER * (dx * dx + dy * dy)
    if den != ZERO:
        scale = z / den
        su = (s[B1] * dx - s[B0] * dy) * scale
        sv = (s[A0] * dy - s[A1] * dx) * scale
        rho3d = su * su + sv * sv
        if rho3d <= rho:
            wins = True
            rho = rho3d
    power = HALF * rho
    zk = z + s[A2] * su + s[B2] * sv if wins else z
    if power > s[PMAX]:
        return ZERO, ZERO, wins, su, sv, den, zk, dx, dy
    gauss = np.exp(-power)
    alpha = min(ALPHA_MAX, s[OP] * gauss)
    if alpha < ALPHA_MIN:
        alpha = ZERO
    return alpha, gauss, wins, su, sv, den, zk, dx, dy


@njit(cache=True, error_model="numpy")
def row(feat, k):
    """The first 18 feature columns (geometry, opacity, cut-off, box) as a tuple held in registers."""
    return (feat[k, 0], feat[k, 1], feat[k, 2], feat[k, 3], feat[k, 4], feat[k, 5], feat[k, 6], feat[k, 7],
            feat[k, 8], feat[k, 9], feat[k, 10], feat[k, 11], feat[k, 12], feat[k, 13], feat[k, 14],
            feat[k, 15], feat[k, 16], feat[k, 17])


@njit(cache=True, parallel=True, error_model="numpy")
def composite_forward(tile_starts, feat, width, height, background, rgb, depth, trans, median, normal,
                      dist, m2, last):
    """Front-to-back blending per tile; fills rgb (H,W,3), depth (sum w z), final T, median depth,
    normal (H,W,3), distortion, m2 (sum w z^2, kept for the backward) and the list position of the last
    blended instance (-1 if none)."""
    grid_x = (width + TILE - 1) // TILE
    for t in prange(tile_starts.shape[0] - 1):
        x0, x1, y0, y1 = tile_bounds(t, grid_x, width, height)
        for i in range(y0, y1):
            for j in range(x0, x1):
                trans[i, j], depth[i, j], median[i, j], last[i, j] = ONE, ZERO, ZERO, -1
                dist[i, j], m2[i, j] = ZERO, ZERO
                for ch in range(3):
                    rgb[i, j, ch], normal[i, j, ch] = ZERO, ZERO
        done = np.zeros((TILE, TILE), np.bool_)
        n_left = (x1 - x0) * (y1 - y0)
        for k in range(tile_starts[t], tile_starts[t + 1]):
            if n_left == 0:
                break
            s = row(feat, k)
            cr, cg, cb = feat[k, CR], feat[k, CG], feat[k, CB]
            nx, ny, nz = feat[k, NX], feat[k, NY], feat[k, NZ]
            jx0, jx1 = pixel_range(s[BX], s[HX], x0, x1)
            iy0, iy1 = pixel_range(s[BY], s[HY], y0, y1)
            for i in range(iy0, iy1 + 1):
                for j in range(jx0, jx1 + 1):
                    if done[i - y0, j - x0]:
                        continue
                    alpha, _g, _wins, _su, _sv, _den, zk, _dx, _dy = surfel_pixel(s, j, i)
                    if alpha == ZERO:
                        continue
                    t_now = trans[i, j]
                    t_next = t_now * (ONE - alpha)
                    if t_next < T_MIN:
                        done[i - y0, j - x0] = True
                        n_left -= 1
                        continue
                    w = alpha * t_now
                    d1, d2 = depth[i, j], m2[i, j]
                    dist[i, j] += w * (zk * zk * (ONE - t_now) - TWO * zk * d1 + d2)
                    depth[i, j] = d1 + w * zk
                    m2[i, j] = d2 + w * zk * zk
                    rgb[i, j, 0] += w * cr
                    rgb[i, j, 1] += w * cg
                    rgb[i, j, 2] += w * cb
                    normal[i, j, 0] += w * nx
                    normal[i, j, 1] += w * ny
                    normal[i, j, 2] += w * nz
                    if t_now >= T_MEDIAN and t_next < T_MEDIAN:
                        median[i, j] = zk
                    trans[i, j] = t_next
                    last[i, j] = k
        for i in range(y0, y1):
            for j in range(x0, x1):
                for ch in range(3):
                    rgb[i, j, ch] += background[ch] * trans[i, j]


@njit(cache=True, parallel=True, error_model="numpy")
def composite_backward(tile_starts, feat, width, height, background, trans_final, depth, m2, last,
                       v_rgb, v_depth, v_alpha, v_normal, v_dist):
    """Reverse-order pass of :func:`composite_forward`. Returns one gradient row per instance (N_GRAD).

    Per pixel every output is a function of the weights w_k = alpha_k T_k and the depths z_k. With
    g_k = dL/dw_k = v_rgb.c_k + v_depth z_k + v_normal.n_k + v_alpha + v_dist (z_k^2 W - 2 z_k D1 + D2)
    (W = sum w, D1 = sum w z, D2 = sum w z^2 of the pixel: the partial derivative of
    sum_{i<j} w_i w_j (z_i - z_j)^2) and S_k = sum_{j>k} g_j w_j:
    dL/dalpha_k = g_k T_k - (S_k + v_rgb.bg T_final) / (1 - alpha_k), and
    dL/dz_k = w_k (v_depth + 2 v_dist (z_k W - D1)).
    """
    grid_x = (width + TILE - 1) // TILE
    grads = np.zeros((feat.shape[0], N_GRAD), F32)
    for t in prange(tile_starts.shape[0] - 1):
        x0, x1, y0, y1 = tile_bounds(t, grid_x, width, height)
        trans = np.empty((TILE, TILE), F32)
        suffix = np.zeros((TILE, TILE), F32)
        k_end = tile_starts[t] - 1
        for i in range(y0, y1):
            for j in range(x0, x1):
                trans[i - y0, j - x0] = trans_final[i, j]
                k_end = max(k_end, last[i, j])
        acc = np.zeros(24, F32)
        for k in range(k_end, tile_starts[t] - 1, -1):
            acc[:] = ZERO
            s = row(feat, k)
            jx0, jx1 = pixel_range(s[BX], s[HX], x0, x1)
            iy0, iy1 = pixel_range(s[BY], s[HY], y0, y1)
            o, z, a2, b2 = s[OP], s[Z], s[A2], s[B2]
            cr, cg, cb = feat[k, CR], feat[k, CG], feat[k, CB]
            nx, ny, nz = feat[k, NX], feat[k, NY], feat[k, NZ]
            for i in range(iy0, iy1 + 1):
                pi = i - y0
                for j in range(jx0, jx1 + 1):
                    if last[i, j] < k:
                        continue
                    alpha, gauss, wins, su, sv, den, zk, dx, dy = surfel_pixel(s, j, i)
                    if alpha == ZERO:
                        continue
                    pj = j - x0
                    inv_one_minus = ONE / (ONE - alpha)
                    t_before = trans[pi, pj] * inv_one_minus
                    trans[pi, pj] = t_before
                    w = alpha * t_before
                    t_fin = trans_final[i, j]
                    big_w, d1, d2 = ONE - t_fin, depth[i, j], m2[i, j]
                    vr, vg, vb, vd = v_rgb[i, j, 0], v_rgb[i, j, 1], v_rgb[i, j, 2], v_depth[i, j]
                    vnx, vny, vnz = v_normal[i, j, 0], v_normal[i, j, 1], v_normal[i, j, 2]
                    vdist = v_dist[i, j]
                    g = (vr * cr + vg * cg + vb * cb + vd * zk + vnx * nx + vny * ny + vnz * nz
                         + v_alpha[i, j] + vdist * (zk * zk * big_w - TWO * zk * d1 + d2))
                    bg_term = (vr * background[0] + vg * background[1] + vb * background[2]) * t_fin
                    v_al = g * t_before - (suffix[pi, pj] + bg_term) * inv_one_minus
                    suffix[pi, pj] += g * w
                    v_zk = w * (vd + TWO * vdist * (zk * big_w - d1))
                    acc[13] += w * vr
                    acc[14] += w * vg
                    acc[15] += w * vb
                    acc[16] += w * vnx
                    acc[17] += w * vny
                    acc[18] += w * vnz
                    acc[11] += v_zk
                    v_pow = ZERO
                    if o * gauss <= ALPHA_MAX:  # clamped at 0.99: no gradient to opacity or the footprint
                        acc[12] += gauss * v_al
                        v_pow = -alpha * v_al
                    if wins:
                        acc[19] += v_zk * su
                        acc[20] += v_zk * sv
                        v_su = v_pow * su + v_zk * a2
                        v_sv = v_pow * sv + v_zk * b2
                        ratio = z / den
                        v_p, v_q = v_su * ratio, v_sv * ratio
                        dot = v_su * su + v_sv * sv
                        v_den = -dot / den
                        acc[11] += dot / z
                        acc[0] += v_p
                        acc[1] += v_p * dx
                        acc[2] += v_p * dy
                        acc[3] += v_q
                        acc[4] += v_q * dx
                        acc[5] += v_q * dy
                        acc[6] += v_den
                        acc[7] += v_den * dx
                        acc[8] += v_den * dy
                    else:
                        acc[9] += v_pow * FILTER * dx
                        acc[10] += v_pow * FILTER * dy
            write_instance_grads(feat, k, acc, grads)
    return grads


@njit(cache=True, error_model="numpy")
def write_instance_grads(feat, k, acc, grads):
    """Gradient row of instance k from its pixel sums ``acc``: [0:3] sum of dL/dP (times 1, dx, dy),
    [3:6] dL/dQ, [6:9] dL/dc_z, [9:11] filter terms, [11] z, [12] opacity, [13:16] colour,
    [16:19] normal, [19:21] direct depth terms of A2, B2 (P = B1 dx - B0 dy, Q = A0 dy - A1 dx)."""
    a0, a1, a2, b0, b1, b2 = feat[k, A0], feat[k, A1], feat[k, A2], feat[k, B0], feat[k, B1], feat[k, B2]
    s_p, s_pdx, s_pdy, s_q, s_qdx, s_qdy, s_d, s_ddx, s_ddy = (acc[0], acc[1], acc[2], acc[3], acc[4],
                                                               acc[5], acc[6], acc[7], acc[8])
    grads[k, 0] = -(b1 * s_p - a1 * s_q + feat[k, EE] * s_d) - acc[9]
    grads[k, 1] = -(a0 * s_q - b0 * s_p + feat[k, FF] * s_d) - acc[10]
    grads[k, 2] = acc[11]
    grads[k, 3] = s_qdy + b1 * s_d - b2 * s_ddy
    grads[k, 4] = -s_qdx - b0 * s_d + b2 * s_ddx
    grads[k, 5] = b0 * s_ddy - b1 * s_ddx + acc[19]
    grads[k, 6] = -s_pdy - a1 * s_d + a2 * s_ddy
    grads[k, 7] = s_pdx + a0 * s_d - a2 * s_ddx
    grads[k, 8] = a1 * s_ddx - a0 * s_ddy + acc[20]
    for c in range(3):
        grads[k, 9 + c] = acc[16 + c]
        grads[k, 13 + c] = acc[13 + c]
    grads[k, 12] = acc[12]


@njit(cache=True, parallel=True, error_model="numpy")
def sum_instance_rows(order, emit_start, slot, grads, n):
    """Per-surfel sums of the instance gradient rows, parallel over surfels (no atomics)."""
    out = np.zeros((n, grads.shape[1]), F32)
    for r in prange(order.shape[0]):
        g = order[r]
        for e in range(emit_start[r], emit_start[r + 1]):
            k = slot[e]
            for c in range(grads.shape[1]):
                out[g, c] += grads[k, c]
    return out
