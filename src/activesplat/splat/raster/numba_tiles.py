"""numba kernels: tile binning, front-to-back compositing and its reverse-order backward pass.

Every instance (Gaussian, tile) is one entry of the per-tile lists, depth-sorted with a stable sort.
Within a tile each Gaussian only visits the rows where alpha can reach 1/255 (the bounding box of
the ellipse o exp(-power) = 1/255) and, of those rows, the 8-pixel-wide half tiles the box touches.
A Gaussian is listed only in the tiles of its 3-sigma rectangle (3DGS) that hold a pixel centre of
that box: a thin, slanted or faint footprint gets a quarter fewer instances on a house map, and the
tiles left out are those where it would have visited no pixel, so nothing rendered changes.
Binning (:func:`bin_features`) is bound by memory rather than arithmetic: it asks for the scattered
values of a Gaussian well before it reads them, counts tiles without a loop over them and copies each
feature row as one block.
The per-pixel work is branch-free so that LLVM vectorises it (SIMD over pixels): a tile keeps its
running state in one local float32 array, each half tile stored row-major, so the pixels a Gaussian
visits in one half are a single contiguous run; skips (alpha < 1/255, finished pixels) are masks,
not branches, and exp is an inline polynomial. Pixels outside the box would be skipped anyway, so
the result is the 3DGS one. The forward pass also leaves out the rows at either end of a run whose
pixels have all finished (it notes which rows still blend whenever it checks whether the tile is done):
they would blend nothing (about 6 % less forward compositing on a 200k-Gaussian room view). Tiles run
in parallel (prange, static schedule); the backward pass writes one gradient row per instance and a
second parallel loop sums them per Gaussian (no atomics).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from activesplat.splat.raster.constants import RASTER
from activesplat.splat.raster.intrinsics import copy_row, fma, prefetch

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
MX, MY, CA, CB, CC, OP, CR, CG, CBL, DZ, HX, HY, PMAX, PU, PV = range(15)
N_FEAT = 15
POWER_PAD = F32(1e-3)  # margin on the power cut-off so rounding never skips a term the exact test keeps
N_GRAD = 10  # v_mean2d (2), v_conic (3), v_opacity, v_colour (3), v_depth (the slopes have no gradient)
NEG1 = F32(-1.0)
HW = 8  # width of a half tile: its pixel q sits at row q >> 3, column q & 7
NH = TILE // HW  # half tiles per tile
HP = TILE * HW  # pixels per half tile
LANE_X = np.array([q & (HW - 1) for q in range(HP)], F32)  # column of half-tile pixel q
LANE_Y = np.array([q // HW for q in range(HP)], F32)  # its row
POWER_CAP = F32(16.0)  # exp_neg is valid on [0, 16]: covers the cut-off ln(255 o) for o up to 3e4
# exp(-x) on [0, 1] (x = power / 16): Chebyshev fit of degree 7 in the power basis, constant first
EXP_C = tuple(F32(v) for v in (1.00000000e00, -9.99999939e-01, 4.99998700e-01, -1.66656130e-01,
                                4.16245036e-02, -8.24086645e-03, 1.27445920e-03, -1.21286891e-04))
SIXTEENTH = F32(1.0 / 16.0)
# rows of the per-tile state arrays (each (rows, NH, HP) float32)
F_T, F_R, F_G, F_B, F_D, F_MED, F_LAST, F_LIVE = range(8)  # forward: T, rgb, depth, median, last, alive
N_FWD = 8
B_T, B_SR, B_SG, B_SB, B_SD, B_VR, B_VG, B_VB, B_VD, B_Q, B_LAST = range(11)
N_BWD = 11  # backward: T, suffix sums (rgb, depth), output gradients (rgb, depth), Q, last
MAX_CHUNKS = 16  # chunks of the depth order in the parallel tile-list build (fixed: deterministic)
MIN_CHUNK = 2048  # Gaussians per chunk at least
PREFETCH_AHEAD = 16  # bin_features requests the values of the Gaussian this many places ahead
MAX_TILE_LIST = 1 << 24  # list positions are held as float32 in the tile state: exact below 2^24
# the forward pass checks every this many instances which half-tile rows still blend (and whether the
# tile is finished); counting the finished pixels inside the pixel loop (an int64 reduction) kept LLVM
# at 4 lanes instead of 8
LIVE_CHECK_EVERY = 32


@njit(cache=True, error_model="numpy")
def list_positions(counts):
    """From the instance counts per chunk and tile (n_chunks, n_tiles): tile_starts (n_tiles+1,), where
    each tile's list begins, and fill (n_chunks, n_tiles), where each chunk's first instance in each tile
    goes (the chunks in order within a tile, so the lists keep the depth order)."""
    n_chunks, n_tiles = counts.shape
    tile_starts = np.zeros(n_tiles + 1, np.int64)
    fill = np.empty((n_chunks, n_tiles), np.int64)
    for t in range(n_tiles):
        pos = tile_starts[t]
        for c in range(n_chunks):
            fill[c, t] = pos
            pos += counts[c, t]
        tile_starts[t + 1] = pos
    return tile_starts, fill


@njit(cache=True, parallel=True, error_model="numpy")
def tile_offsets(order, rects, grid_x, n_tiles):
    """Counting pass of a stable, parallel counting sort of (Gaussian, tile) instances by tile.

    ``order`` (the rendered Gaussians front to back) is cut into chunks counted in parallel.
    Returns tile_starts (n_tiles+1,), the CSR emit_start (per Gaussian in ``order``: its first
    instance), chunk bounds and fill (n_chunks, n_tiles): the list position where each chunk's
    first instance in each tile goes, so that chunks filled in parallel keep the depth order."""
    n_vis = order.shape[0]
    n_chunks = max(1, min(MAX_CHUNKS, n_vis // MIN_CHUNK))
    bounds = np.empty(n_chunks + 1, np.int64)
    for c in range(n_chunks + 1):
        bounds[c] = (n_vis * c) // n_chunks
    per_gauss = np.zeros(n_vis + 1, np.int64)
    counts = np.zeros((n_chunks, n_tiles), np.int64)
    for c in prange(n_chunks):
        for r in range(bounds[c], bounds[c + 1]):
            g = order[r]
            per_gauss[r + 1] = (rects[g, 1] - rects[g, 0]) * (rects[g, 3] - rects[g, 2])
            for ty in range(rects[g, 2], rects[g, 3]):
                for tx in range(rects[g, 0], rects[g, 1]):
                    counts[c, ty * grid_x + tx] += 1
    emit_start = np.cumsum(per_gauss)
    tile_starts, fill = list_positions(counts)
    return tile_starts, emit_start, bounds, fill


@njit(cache=True, parallel=True, error_model="numpy")
def build_tile_lists(order, rects, grid_x, n_tiles):
    """Stable counting sort of (Gaussian, tile) instances by tile (parallel, see :func:`tile_offsets`).
    ``order`` lists the rendered Gaussians front to back, so each tile's list stays depth-sorted.
    Returns tile_starts (n_tiles+1,), ids (n_inst,) and, per Gaussian in ``order``, the CSR emit_start
    with slot[e] = list position of its e-th instance (used to sum instance gradients per Gaussian)."""
    tile_starts, emit_start, bounds, fill = tile_offsets(order, rects, grid_x, n_tiles)
    ids = np.empty(emit_start[-1], np.int64)
    slot = np.empty(emit_start[-1], np.int64)
    for c in prange(bounds.shape[0] - 1):
        for r in range(bounds[c], bounds[c + 1]):
            g = order[r]
            e = emit_start[r]
            for ty in range(rects[g, 2], rects[g, 3]):
                for tx in range(rects[g, 0], rects[g, 1]):
                    t = ty * grid_x + tx
                    ids[fill[c, t]] = g
                    slot[e] = fill[c, t]
                    fill[c, t] += 1
                    e += 1
    return tile_starts, ids, emit_start, slot


@njit(cache=True, error_model="numpy")
def stable_depth_order(candidates, depths):
    """``candidates`` sorted by depth (all > 0), stable: LSD radix sort on the float32 bit patterns
    (order-preserving for positive floats), 3 passes of 11 bits; equals np.argsort(kind="stable").
    Each key travels with its candidate, so the passes read sequentially instead of looking the key up
    in ``depths`` at a random place (one thread, 20 views of an 866k-Gaussian medium-house map, 120 x 150
    panorama camera: 30.4 -> 20.0 ms with the whole map handed over, 16.8 -> 13.5 ms with its own rows)."""
    n = candidates.shape[0]
    bits = depths.view(np.uint32)
    keys = np.empty(n, np.uint32)
    for r in range(n):
        keys[r] = bits[candidates[r]]
    order = candidates.copy()
    order_next, keys_next = np.empty_like(order), np.empty_like(keys)
    for shift in (0, 11, 22):
        counts = np.zeros(2049, np.int64)
        for r in range(n):
            counts[((keys[r] >> shift) & 2047) + 1] += 1
        for d in range(2048):
            counts[d + 1] += counts[d]
        for r in range(n):
            digit = (keys[r] >> shift) & 2047
            slot = counts[digit]
            order_next[slot], keys_next[slot] = order[r], keys[r]
            counts[digit] = slot + 1
        order, order_next = order_next, order
        keys, keys_next = keys_next, keys
    return order


@njit(cache=True, parallel=True, error_model="numpy")
def bin_features(order, rects, grid_x, n_tiles, means2d, conics, opacities, colors, depths, slopes):
    """:func:`build_tile_lists` that writes the instance rows directly: feat (n_inst, 15), contiguous
    per tile: mean2d, conic, opacity, colour, depth, the half extents of the box where alpha can reach
    1/255 (|dx| <= sqrt(2 ln(255 o) Sigma_xx)) and the power above which alpha < 1/255 for sure
    (ln(255 o) plus a margin, at most ``POWER_CAP``), the depth slope (dz/du, dz/dv; zero unless planar
    depth, :mod:`activesplat.splat.raster.planar`). Returns tile_starts, feat, emit_start, slot.

    Two passes over ``order``, in the chunks of :func:`tile_offsets` (in parallel): the first gathers each
    Gaussian's row in depth order (its values are read at random places, so the reads of the Gaussian
    ``PREFETCH_AHEAD`` places further on are requested ahead) and counts its tiles per chunk as the four
    corners of its tile rectangle (+1, -1, -1, +1; a 2D prefix sum over the tile grid turns them into
    counts, with no loop over the tiles); the second copies each row to its tiles' list positions, one
    loop over its instances. The same lists as :func:`build_tile_lists` (one thread, 19 renders of a
    house replay, caches flushed: 101 -> 69 ms)."""
    n_vis = order.shape[0]
    grid_y = n_tiles // grid_x
    n_chunks = max(1, min(MAX_CHUNKS, n_vis // MIN_CHUNK))
    bounds = np.empty(n_chunks + 1, np.int64)
    for c in range(n_chunks + 1):
        bounds[c] = (n_vis * c) // n_chunks
    rows = np.empty((n_vis, N_FEAT), F32)
    rects_o = np.empty((n_vis, 4), rects.dtype)
    emit_start = np.empty(n_vis + 1, np.int64)
    emit_start[0] = 0
    gx1 = grid_x + 1
    corners = np.zeros((n_chunks, (grid_y + 1) * gx1), np.int64)  # per chunk, on the (grid + 1) corner grid
    for ch in prange(n_chunks):
        for r in range(bounds[ch], bounds[ch + 1]):
            if r + PREFETCH_AHEAD < n_vis:
                ahead = order[r + PREFETCH_AHEAD]
                prefetch(means2d, ahead)
                prefetch(conics, ahead)
                prefetch(opacities, ahead)
                prefetch(colors, ahead)
                prefetch(depths, ahead)
                prefetch(slopes, ahead)
                prefetch(rects, ahead)
            g = order[r]
            a, b, c, o = conics[g, 0], conics[g, 1], conics[g, 2], opacities[g]
            level = TWO * (np.log(max(o, ALPHA_MIN)) + LOG_255)
            det = a * c - b * b
            rows[r, MX], rows[r, MY], rows[r, DZ] = means2d[g, 0], means2d[g, 1], depths[g]
            rows[r, CA], rows[r, CB], rows[r, CC] = a, b, c
            rows[r, OP], rows[r, CR], rows[r, CG], rows[r, CBL] = o, colors[g, 0], colors[g, 1], colors[g, 2]
            rows[r, HX] = np.sqrt(max(ZERO, level * c / det)) + BOX_PAD
            rows[r, HY] = np.sqrt(max(ZERO, level * a / det)) + BOX_PAD
            rows[r, PMAX] = min(HALF * level + POWER_PAD, POWER_CAP)
            rows[r, PU], rows[r, PV] = slopes[g, 0], slopes[g, 1]
            # the tiles of the projection's 3-sigma rectangle that hold a pixel centre of the alpha >= 1/255
            # box, found as visit_range finds them: the others would visit no pixel, so they get no instance
            jx0, jx1 = pixel_range(rows[r, MX], rows[r, HX], 0, grid_x * TILE)
            iy0, iy1 = pixel_range(rows[r, MY], rows[r, HY], 0, grid_y * TILE)
            tx0, ty0 = max(rects[g, 0], jx0 // TILE), max(rects[g, 2], iy0 // TILE)
            tx1 = max(tx0, min(rects[g, 1], jx1 // TILE + 1))
            ty1 = max(ty0, min(rects[g, 3], iy1 // TILE + 1))
            rects_o[r, 0], rects_o[r, 1], rects_o[r, 2], rects_o[r, 3] = tx0, tx1, ty0, ty1
            emit_start[r + 1] = (tx1 - tx0) * (ty1 - ty0)
            # a box right of or below the image can start past the grid: clamped, an empty rectangle's
            # corners still cancel (and a non-empty one already ends inside the grid)
            cx0, cx1, cy0, cy1 = min(tx0, grid_x), min(tx1, grid_x), min(ty0, grid_y), min(ty1, grid_y)
            corners[ch, cy0 * gx1 + cx0] += 1
            corners[ch, cy0 * gx1 + cx1] -= 1
            corners[ch, cy1 * gx1 + cx0] -= 1
            corners[ch, cy1 * gx1 + cx1] += 1
    for r in range(n_vis):
        emit_start[r + 1] += emit_start[r]
    counts = np.zeros((n_chunks, n_tiles), np.int64)
    for c in range(n_chunks):
        for ty in range(grid_y):
            run = 0
            for tx in range(grid_x):
                run += corners[c, ty * gx1 + tx]
                counts[c, ty * grid_x + tx] = run + (counts[c, (ty - 1) * grid_x + tx] if ty > 0 else 0)
    tile_starts, fill = list_positions(counts)
    feat = np.empty((emit_start[-1], N_FEAT), F32)
    slot = np.empty(emit_start[-1], np.int64)
    for ch in prange(n_chunks):
        for r in range(bounds[ch], bounds[ch + 1]):
            tx0, tx1, ty = rects_o[r, 0], rects_o[r, 1], rects_o[r, 2]
            tx = tx0
            for e in range(emit_start[r], emit_start[r + 1]):  # its tiles row by row, without nested loops
                t = ty * grid_x + tx
                k = fill[ch, t]
                copy_row(feat, k, rows, r, N_FEAT)
                slot[e] = k
                fill[ch, t] = k + 1
                tx += 1
                wrap = tx == tx1
                ty = ty + 1 if wrap else ty
                tx = tx0 if wrap else tx
    return tile_starts, feat, emit_start, slot


@njit(cache=True, error_model="numpy")
def pixel_range(centre, half, lo, hi):
    """Pixel indices [p0, p1] of [lo, hi) whose centres p + 0.5 lie within centre +- half."""
    p0 = max(F32(lo), np.ceil(centre - HALF - half))
    p1 = min(F32(hi - 1), np.floor(centre - HALF + half))
    return int(p0), int(p1)


@njit(cache=True, error_model="numpy")
def exp_neg(power):
    """exp(-power) for 0 <= power <= 16, vectorisable (no libm call): p(power / 16)^16 with p the
    degree-7 fit of exp(-x) on [0, 1]; relative error below 5e-6 in float32 (below 2e-6 up to 5.6)."""
    x = power * SIXTEENTH
    p = fma(EXP_C[7], x, EXP_C[6])
    p = fma(p, x, EXP_C[5])
    p = fma(p, x, EXP_C[4])
    p = fma(p, x, EXP_C[3])
    p = fma(p, x, EXP_C[2])
    p = fma(p, x, EXP_C[1])
    p = fma(p, x, EXP_C[0])
    p = p * p
    p = p * p
    p = p * p
    return p * p


@njit(cache=True, error_model="numpy")
def pixel_alpha(q, mxl, myl, ha, b, hc, o, pmax):
    """(alpha, G, dx, dy) of one Gaussian at pixel q of a half tile, with (mxl, myl) its mean relative
    to the centre of the half tile's pixel 0, ha = a / 2, hc = c / 2; alpha = 0 when skipped (power
    < 0 or above the cut-off, alpha < 1/255). Forward and backward share it (compiled without
    fastmath) so they make bit-identical skip decisions."""
    dx = mxl - LANE_X[q]  # = F32(q & 7), F32(q >> 3): table loads, not int64 -> float32 conversions, which
    dy = myl - LANE_Y[q]  # cost two vector halves each (the composite loops ran ~1.7x slower)
    power = fma(fma(ha, dx, b * dy), dx, hc * dy * dy)
    gauss = exp_neg(min(max(power, ZERO), POWER_CAP))
    alpha = min(ALPHA_MAX, o * gauss)
    keep = (power >= ZERO) & (power <= pmax) & (alpha >= ALPHA_MIN)
    return (alpha if keep else ZERO), gauss, dx, dy


@njit(cache=True, error_model="numpy")
def half_q(i, j, x0, y0):
    """(half tile, pixel index q) of image pixel (i, j) in the tile at (x0, y0)."""
    return (j - x0) // HW, (i - y0) * HW + (j - x0) % HW


@njit(cache=True, error_model="numpy")
def visit_range(feat, k, x0, x1, y0, y1):
    """Half tiles [h0, h1] and the run [q0, q1) of half-tile pixels (whole rows) that instance k
    visits; h1 < h0 when its alpha >= 1/255 box misses the tile's pixel centres."""
    jx0, jx1 = pixel_range(feat[k, MX], feat[k, HX], x0, x1)
    iy0, iy1 = pixel_range(feat[k, MY], feat[k, HY], y0, y1)
    if jx1 < jx0 or iy1 < iy0:
        return 1, 0, np.uint32(0), np.uint32(0)
    return (jx0 - x0) // HW, (jx1 - x0) // HW, np.uint32((iy0 - y0) * HW), np.uint32((iy1 - y0 + 1) * HW)


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
        k0 = tile_starts[t]
        s = np.zeros((N_FWD, NH, HP), F32)
        for h in range(NH):
            for q in range(HP):
                s[F_T, h, q], s[F_LAST, h, q] = ONE, NEG1
                inside = (q >> 3) < y1 - y0 and h * HW + (q & 7) < x1 - x0
                s[F_LIVE, h, q] = ONE if inside else ZERO
        row_live = np.empty((NH, TILE), F32)  # per half-tile row: 1 while one of its pixels is blending
        for k in range(k0, tile_starts[t + 1]):
            if (k - k0) % LIVE_CHECK_EVERY == 0:  # now and then: between checks a row may have finished
                live = ZERO
                for h in range(NH):
                    for r in range(TILE):
                        m = ZERO
                        for lane in range(HW):
                            m = max(m, s[F_LIVE, h, r * HW + lane])
                        row_live[h, r] = m
                        live = max(live, m)
                if live == ZERO:
                    break  # every pixel is finished: later instances would change nothing
            h0, h1, q0, q1 = visit_range(feat, k, x0, x1, y0, y1)
            b, o, pmax, kk = feat[k, CB], feat[k, OP], feat[k, PMAX], F32(k - k0)
            ha, hc, myl = HALF * feat[k, CA], HALF * feat[k, CC], feat[k, MY] - F32(y0) - HALF
            cr, cg, cb, z = feat[k, CR], feat[k, CG], feat[k, CBL], feat[k, DZ]
            pu, pv = feat[k, PU], feat[k, PV]
            for h in range(h0, h1 + 1):
                mxl = feat[k, MX] - F32(x0 + h * HW) - HALF
                qa, qb = q0, q1  # without the finished rows at either end (they would blend nothing)
                while qa < qb and row_live[h, qa >> 3] == ZERO:
                    qa += np.uint32(HW)
                while qb > qa and row_live[h, (qb >> 3) - 1] == ZERO:
                    qb -= np.uint32(HW)
                for q in range(qa, qb):
                    alpha, _g, dx, dy = pixel_alpha(q, mxl, myl, ha, b, hc, o, pmax)
                    zp = z - pu * dx - pv * dy  # depth at this pixel (dx = mean - pixel)
                    hit = (s[F_LIVE, h, q] != ZERO) & (alpha != ZERO)
                    t_now = s[F_T, h, q]
                    t_next = t_now * (ONE - alpha)
                    stop = hit & (t_next < T_MIN)  # the pixel is finished, this Gaussian not blended
                    blend = hit & (t_next >= T_MIN)
                    w = alpha * t_now if blend else ZERO
                    s[F_R, h, q] += w * cr
                    s[F_G, h, q] += w * cg
                    s[F_B, h, q] += w * cb
                    s[F_D, h, q] += w * zp
                    crosses = blend & (t_now >= T_MEDIAN) & (t_next < T_MEDIAN)
                    s[F_MED, h, q] = zp if crosses else s[F_MED, h, q]
                    s[F_T, h, q] = t_next if blend else t_now
                    s[F_LAST, h, q] = kk if blend else s[F_LAST, h, q]
                    s[F_LIVE, h, q] = ZERO if stop else s[F_LIVE, h, q]
        for i in range(y0, y1):
            for j in range(x0, x1):
                h, q = half_q(i, j, x0, y0)
                tr = s[F_T, h, q]
                trans[i, j], depth[i, j], median[i, j] = tr, s[F_D, h, q], s[F_MED, h, q]
                last[i, j] = k0 + int(s[F_LAST, h, q]) if s[F_LAST, h, q] >= ZERO else -1
                rgb[i, j, 0] = s[F_R, h, q] + background[0] * tr
                rgb[i, j, 1] = s[F_G, h, q] + background[1] * tr
                rgb[i, j, 2] = s[F_B, h, q] + background[2] * tr


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"reassoc"})
def composite_backward(tile_starts, feat, width, height, background, trans_final, last,
                       v_rgb, v_depth, v_alpha):
    """Reverse-order pass of :func:`composite_forward` (3DGS ``renderCUDA`` backward). Returns one
    gradient row per instance: v_mean2d (2), v_conic (3), v_opacity, v_colour (3), v_depth.

    Per pixel, with T_i the transmittance before Gaussian i and S_i the sums of w_j c_j (w_j z_j)
    over the Gaussians behind it: dC/dalpha_i = c_i T_i - (S_i + bg T_final) / (1 - alpha_i),
    dD/dalpha_i = z_i T_i - S_i / (1 - alpha_i) (z_i: the Gaussian's depth at the pixel),
    d(1 - T_final)/dalpha_i = T_final / (1 - alpha_i).
    A skipped pixel has alpha = 0, which leaves T and S unchanged and adds nothing. ``reassoc`` lets
    LLVM vectorise the per-instance gradient sums; alpha itself comes from :func:`pixel_alpha`,
    compiled without it, so the skips are those of the forward pass.
    """
    grid_x = (width + TILE - 1) // TILE
    grads = np.zeros((feat.shape[0], N_GRAD), F32)
    for t in prange(tile_starts.shape[0] - 1):
        x0, x1, y0, y1 = tile_bounds(t, grid_x, width, height)
        k0 = tile_starts[t]
        s = np.zeros((N_BWD, NH, HP), F32)
        s[B_LAST] = NEG1
        k_end = k0 - 1
        for i in range(y0, y1):
            for j in range(x0, x1):
                h, q = half_q(i, j, x0, y0)
                t_fin, vr, vg, vb = trans_final[i, j], v_rgb[i, j, 0], v_rgb[i, j, 1], v_rgb[i, j, 2]
                s[B_T, h, q], s[B_VR, h, q], s[B_VG, h, q], s[B_VB, h, q] = t_fin, vr, vg, vb
                s[B_VD, h, q] = v_depth[i, j]
                # the T_final terms of dL/dalpha: (v_alpha - v_rgb . bg) T_final, divided by 1 - alpha_i
                s[B_Q, h, q] = t_fin * (v_alpha[i, j] - vr * background[0] - vg * background[1]
                                        - vb * background[2])
                s[B_LAST, h, q] = F32(last[i, j] - k0) if last[i, j] >= k0 else NEG1
                k_end = max(k_end, last[i, j])
        for k in range(k_end, k0 - 1, -1):
            h0, h1, q0, q1 = visit_range(feat, k, x0, x1, y0, y1)
            a, b, c, o, pmax = feat[k, CA], feat[k, CB], feat[k, CC], feat[k, OP], feat[k, PMAX]
            kk = F32(k - k0)
            ha, hc, myl = HALF * a, HALF * c, feat[k, MY] - F32(y0) - HALF
            cr, cg, cb, z = feat[k, CR], feat[k, CG], feat[k, CBL], feat[k, DZ]
            pu, pv = feat[k, PU], feat[k, PV]
            g_mx = g_my = g_a = g_b = g_c = g_o = g_r = g_g = g_bl = g_z = ZERO
            for h in range(h0, h1 + 1):
                mxl = feat[k, MX] - F32(x0 + h * HW) - HALF
                for q in range(q0, q1):
                    alpha, gauss, dx, dy = pixel_alpha(q, mxl, myl, ha, b, hc, o, pmax)
                    alpha = alpha if s[B_LAST, h, q] >= kk else ZERO  # behind the pixel's last blend
                    inv_one_minus = ONE / (ONE - alpha)
                    t_before = s[B_T, h, q] * inv_one_minus
                    s[B_T, h, q] = t_before
                    w = alpha * t_before
                    zp = z - pu * dx - pv * dy
                    vr, vg, vb, vd = s[B_VR, h, q], s[B_VG, h, q], s[B_VB, h, q], s[B_VD, h, q]
                    sr, sg, sb, sd = s[B_SR, h, q], s[B_SG, h, q], s[B_SB, h, q], s[B_SD, h, q]
                    v_al = ((s[B_Q, h, q] - vr * sr - vg * sg - vb * sb - vd * sd) * inv_one_minus
                            + (vr * cr + vg * cg + vb * cb + vd * zp) * t_before)
                    g_r += w * vr
                    g_g += w * vg
                    g_bl += w * vb
                    wd = w * vd
                    g_z += wd
                    s[B_SR, h, q], s[B_SG, h, q] = sr + w * cr, sg + w * cg
                    s[B_SB, h, q], s[B_SD, h, q] = sb + w * cb, sd + w * zp
                    # alpha clamped at 0.99: no gradient to opacity or the footprint
                    v_al = v_al if (alpha != ZERO) & (o * gauss <= ALPHA_MAX) else ZERO
                    g_o += gauss * v_al
                    v_pow = -alpha * v_al
                    g_mx += v_pow * (a * dx + b * dy) - wd * pu
                    g_my += v_pow * (b * dx + c * dy) - wd * pv
                    g_a += v_pow * dx * dx
                    g_b += v_pow * dx * dy
                    g_c += v_pow * dy * dy
            grads[k, 0], grads[k, 1], grads[k, 2], grads[k, 3] = g_mx, g_my, HALF * g_a, g_b
            grads[k, 4], grads[k, 5], grads[k, 6], grads[k, 7] = HALF * g_c, g_o, g_r, g_g
            grads[k, 8], grads[k, 9] = g_bl, g_z
    return grads


@njit(cache=True, parallel=True, error_model="numpy")
def sum_instance_grads(order, emit_start, slot, grads, n):
    """Per-Gaussian sums of the instance gradient rows, parallel over Gaussians (no atomics), as the
    contiguous arrays v_means2d (n,2), v_conics (n,3), v_opacities (n,), v_colors (n,3), v_depths (n,);
    zero for Gaussians that were not rendered."""
    v_means2d, v_conics = np.zeros((n, 2), F32), np.zeros((n, 3), F32)
    v_opacities, v_colors, v_depths = np.zeros(n, F32), np.zeros((n, 3), F32), np.zeros(n, F32)
    for r in prange(order.shape[0]):
        s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = s8 = s9 = ZERO
        for e in range(emit_start[r], emit_start[r + 1]):
            k = slot[e]
            s0, s1, s2 = s0 + grads[k, 0], s1 + grads[k, 1], s2 + grads[k, 2]
            s3, s4, s5 = s3 + grads[k, 3], s4 + grads[k, 4], s5 + grads[k, 5]
            s6, s7, s8, s9 = s6 + grads[k, 6], s7 + grads[k, 7], s8 + grads[k, 8], s9 + grads[k, 9]
        g = order[r]
        v_means2d[g, 0], v_means2d[g, 1] = s0, s1
        v_conics[g, 0], v_conics[g, 1], v_conics[g, 2] = s2, s3, s4
        v_opacities[g] = s5
        v_colors[g, 0], v_colors[g, 1], v_colors[g, 2] = s6, s7, s8
        v_depths[g] = s9
    return v_means2d, v_conics, v_opacities, v_colors, v_depths
