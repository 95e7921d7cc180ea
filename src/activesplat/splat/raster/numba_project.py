"""numba kernels: EWA projection of 3D Gaussians to 2D conics and its analytic backward pass.

Forward (3DGS ``preprocessCUDA``): p = W m + t; Sigma = R S S^T R^T; Sigma_2D = J W Sigma W^T J^T
+ 0.3 I; conic = Sigma_2D^-1; radius = ceil(3 sqrt(lambda_max)); tile rectangle of mean2d +- radius.
The backward pass is the chain rule of the same formulas.

Both run over blocks of ``BLOCK`` Gaussians in parallel. A block is copied into a flat float32
scratch array (one run of ``BLOCK`` per field) and computed there branch-free, culled Gaussians
masked rather than skipped, by a serial kernel whose helpers are inlined (``inline="always"``): its
loop reads and writes nothing but the scratch at constant offsets and calls nothing, so LLVM
vectorises it. All arithmetic is float32 (constants are np.float32 so nothing promotes to float64).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from activesplat.splat.kernels import (
    F32,
    HALF,
    ONE,
    TWO,
    ZERO,
    inlined,
    matmul3,
    quat_rotmat,
    quat_vjp,
    transpose3,
)
from activesplat.splat.raster.constants import RASTER
from activesplat.splat.raster.planar import MAX_TILT_DEG, MIN_SCALE

NEAR = F32(RASTER.near)
CULL_DEPTH = F32(RASTER.clamp_cull_depth)  # compile-time constant (see RASTER)
LOW_PASS = F32(RASTER.low_pass)
SIGMAS = F32(RASTER.extent_sigmas)
EIGEN_GAP = F32(RASTER.min_eigen_gap)
TILE = RASTER.tile_size
TILE_F = F32(RASTER.tile_size)
BLOCK = 256  # Gaussians per parallel block
# offsets of the fields in the scratch array (uint64 so the indices need no negative wrap-around)
(M0, M1, M2, QW, QX, QY, QZ, S0, S1, S2, KEEP,  # inputs of both passes
 MX, MY, CA, CB, CC, DZ, RAD, X0, X1, Y0, Y1, PU, PV,  # forward outputs
 ) = (np.uint64(k * BLOCK) for k in range(24))
N_FWD = 24
(VU, VV, VA, VB, VC, VZ,  # backward inputs after M0..KEEP and CA..CC
 GM0, GM1, GM2, GQW, GQX, GQY, GQZ, GS0, GS1, GS2) = (np.uint64(k * BLOCK) for k in range(24, 40))
N_BWD = 40
MAX_SLOPE = F32(math.tan(math.radians(MAX_TILT_DEG)))  # planar depth: |p| <= MAX_SLOPE z / f
MIN_SCALE_F = F32(MIN_SCALE)


@njit(cache=True, error_model="numpy")
def conic_vjp(a, b, c, va, vb, vc):
    """Gradient on Sigma_2D (g00, g01, g11; symmetric matrix entries) from the conic gradient, with
    power = 0.5 (a dx^2 + c dy^2) + b dx dy: dL/dSigma = -C G C, G = [[va, vb/2], [vb/2, vc]]."""
    hb = HALF * vb
    cg00, cg01 = a * va + b * hb, a * hb + b * vc
    cg10, cg11 = b * va + c * hb, b * hb + c * vc
    return -(cg00 * a + cg01 * b), -(cg00 * b + cg01 * c), -(cg10 * b + cg11 * c)


_quat_rotmat, _matmul3, _transpose3 = inlined(quat_rotmat), inlined(matmul3), inlined(transpose3)
_conic_vjp, _quat_vjp = inlined(conic_vjp), inlined(quat_vjp)


@njit(cache=True, error_model="numpy", inline="always")
def view_covariance(qw, qx, qy, qz, s0, s1, s2, rot):
    """(unit quaternion, |q|, R(q), M = R(q) diag(s), W Sigma W^T) for one Gaussian."""
    norm = np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    w, x, y, z = qw / norm, qx / norm, qy / norm, qz / norm
    r = _quat_rotmat(w, x, y, z)
    m = (r[0] * s0, r[1] * s1, r[2] * s2, r[3] * s0, r[4] * s1, r[5] * s2, r[6] * s0, r[7] * s1, r[8] * s2)
    cov = _matmul3(m, _transpose3(m))
    return (w, x, y, z), norm, r, m, _matmul3(_matmul3(rot, cov), _transpose3(rot))


@njit(cache=True, error_model="numpy", inline="always")
def jacobian(px, py, z, intr):
    """EWA Jacobian entries (j00, j02, j11, j12) at x/z, y/z clamped to the padded image, plus
    whether x and y were inside the clamp (3DGS / gsplat ``persp_proj``). ``intr`` is the 8-tuple
    (fx, fy, cx, cy, lim_x-, lim_x+, lim_y-, lim_y+)."""
    fx, fy = intr[0], intr[1]
    rx, ry = px / z, py / z
    x_in = (rx >= -intr[4]) & (rx <= intr[5])
    y_in = (ry >= -intr[6]) & (ry <= intr[7])
    tx = z * min(intr[5], max(-intr[4], rx))
    ty = z * min(intr[7], max(-intr[6], ry))
    return fx / z, -fx * tx / (z * z), fy / z, -fy * ty / (z * z), tx, ty, x_in, y_in


@njit(cache=True, error_model="numpy", inline="always")
def screen_cov(j00, j02, j11, j12, cv):
    """Sigma_2D = J Sigma_view J^T + 0.3 I as (s00, s01, s11), plus A = J Sigma_view (2x3)."""
    a0 = (j00 * cv[0] + j02 * cv[6], j00 * cv[1] + j02 * cv[7], j00 * cv[2] + j02 * cv[8])
    a1 = (j11 * cv[3] + j12 * cv[6], j11 * cv[4] + j12 * cv[7], j11 * cv[5] + j12 * cv[8])
    s00 = a0[0] * j00 + a0[2] * j02 + LOW_PASS
    s01 = a0[1] * j11 + a0[2] * j12
    s11 = a1[1] * j11 + a1[2] * j12 + LOW_PASS
    return s00, s01, s11, a0, a1


@njit(cache=True, error_model="numpy", inline="always")
def depth_slope(ax, px, py, z, s0, s1, s2, intr):
    """Planar depth (:mod:`activesplat.splat.raster.planar`): (dz/du, dz/dv) at the projected centre of
    the Gaussian at (px, py, z) with axes ``ax`` (row-major, columns in camera coordinates) and scales
    s0..s2: -(Sigma^-1 mu)_(x, y) z^2 / (mu^T Sigma^-1 mu) / (fx, fy) times the flatness
    1 - (s_min / s_mid)^2, at most MAX_SLOPE z / f long."""
    l0 = ax[0] * px + ax[3] * py + ax[6] * z  # mu in the Gaussian's frame
    l1 = ax[1] * px + ax[4] * py + ax[7] * z
    l2 = ax[2] * px + ax[5] * py + ax[8] * z
    t0, t1, t2 = max(s0, MIN_SCALE_F), max(s1, MIN_SCALE_F), max(s2, MIN_SCALE_F)
    w0, w1, w2 = l0 / (t0 * t0), l1 / (t1 * t1), l2 / (t2 * t2)
    q = max(l0 * w0 + l1 * w1 + l2 * w2, F32(1e-30))
    s_min, s_max = min(t0, min(t1, t2)), max(t0, max(t1, t2))
    ratio = s_min / (t0 + t1 + t2 - s_min - s_max)
    k = z * z / q * (ONE - ratio * ratio)
    pu = -(ax[0] * w0 + ax[1] * w1 + ax[2] * w2) * k / intr[0]
    pv = -(ax[3] * w0 + ax[4] * w1 + ax[5] * w2) * k / intr[1]
    limit = MAX_SLOPE * z / min(intr[0], intr[1])
    shrink = min(ONE, limit / max(np.sqrt(pu * pu + pv * pv), F32(1e-30)))
    return pu * shrink, pv * shrink


@njit(cache=True, error_model="numpy", inline="always")
def camera_point(view, m0, m1, m2):
    """W m + t for the 12-tuple ``view`` (the top three rows of the 4x4 world-to-camera matrix)."""
    return (view[0] * m0 + view[1] * m1 + view[2] * m2 + view[3],
            view[4] * m0 + view[5] * m1 + view[6] * m2 + view[7],
            view[8] * m0 + view[9] * m1 + view[10] * m2 + view[11])


@njit(cache=True, error_model="numpy")
def camera_tuples(view, intr):
    """The world-to-camera rows (12-tuple), their rotation (row-major 9-tuple) and the intrinsics
    (8-tuple) as scalars, so the vectorised loops read no array but the scratch."""
    rows = (view[0, 0], view[0, 1], view[0, 2], view[0, 3], view[1, 0], view[1, 1], view[1, 2], view[1, 3],
            view[2, 0], view[2, 1], view[2, 2], view[2, 3])
    rot = (rows[0], rows[1], rows[2], rows[4], rows[5], rows[6], rows[8], rows[9], rows[10])
    return rows, rot, (intr[0], intr[1], intr[2], intr[3], intr[4], intr[5], intr[6], intr[7])


@njit(cache=True, error_model="numpy")
def load_block(blk, n_fields, means, quats, scales):
    """(first Gaussian, count, scratch of ``n_fields`` runs) of block ``blk``, with the means,
    quaternions and scales of its Gaussians copied in."""
    lo = blk * BLOCK
    cnt = min(BLOCK, means.shape[0] - lo)
    s = np.empty(n_fields * BLOCK, F32)
    for u in range(cnt):
        i = lo + u
        s[M0 + u], s[M1 + u], s[M2 + u] = means[i, 0], means[i, 1], means[i, 2]
        s[QW + u], s[QX + u], s[QY + u], s[QZ + u] = quats[i, 0], quats[i, 1], quats[i, 2], quats[i, 3]
        s[S0 + u], s[S1 + u], s[S2 + u] = scales[i, 0], scales[i, 1], scales[i, 2]
    return lo, cnt, s


@njit(cache=True, error_model="numpy")
def project_block(s, cnt, view, rot, intr, grid_x, grid_y):
    """The forward pass on the first ``cnt`` scratch columns (see :func:`project_forward`)."""
    for u in range(np.uint64(cnt)):
        px, py, z = camera_point(view, s[M0 + u], s[M1 + u], s[M2 + u])
        front = (s[KEEP + u] != ZERO) & (z > NEAR)
        zs = z if front else ONE  # culled lanes stay finite
        _q, _n, r, _m, cv = view_covariance(s[QW + u], s[QX + u], s[QY + u], s[QZ + u],
                                            s[S0 + u], s[S1 + u], s[S2 + u], rot)
        j00, j02, j11, j12, _tx, _ty, _xin, _yin = jacobian(px, py, zs, intr)
        s00, s01, s11, _a0, _a1 = screen_cov(j00, j02, j11, j12, cv)
        det = s00 * s11 - s01 * s01
        ok = front & (det > ZERO) & ((_xin & _yin) | (z >= CULL_DEPTH))
        det_ok = det if ok else ONE
        mx, my = intr[0] * px / zs + intr[2], intr[1] * py / zs + intr[3]
        s[CA + u] = s11 / det_ok if ok else ZERO
        s[CB + u] = -s01 / det_ok if ok else ZERO
        s[CC + u] = s00 / det_ok if ok else ZERO
        s[MX + u], s[MY + u], s[DZ + u] = (mx if ok else ZERO), (my if ok else ZERO), z
        mid = HALF * (s00 + s11)
        radius = np.ceil(SIGMAS * np.sqrt(max(ZERO, mid + np.sqrt(max(EIGEN_GAP, mid * mid - det)))))
        x0 = min(max(np.floor((mx - radius) / TILE_F), ZERO), grid_x)
        x1 = min(max(np.ceil((mx + radius) / TILE_F), ZERO), grid_x)
        y0 = min(max(np.floor((my - radius) / TILE_F), ZERO), grid_y)
        y1 = min(max(np.ceil((my + radius) / TILE_F), ZERO), grid_y)
        ok = ok & (radius > ZERO) & (x1 > x0) & (y1 > y0)
        s[RAD + u] = radius if ok else ZERO
        s[X0 + u], s[X1 + u] = (x0 if ok else ZERO), (x1 if ok else ZERO)
        s[Y0 + u], s[Y1 + u] = (y0 if ok else ZERO), (y1 if ok else ZERO)
        pu, pv = depth_slope(_matmul3(rot, r), px, py, zs, s[S0 + u], s[S1 + u], s[S2 + u], intr)
        s[PU + u], s[PV + u] = (pu if ok else ZERO), (pv if ok else ZERO)


@njit(cache=True, parallel=True, error_model="numpy")
def project_forward(means, quats, scales, view, intr, width, height, mask,
                    means2d, conics, depths, radii, rects, slopes):
    """Fill means2d (N,2), conics (N,3), depths (N,), radii (N,), tile rects (N,4) [x0,x1,y0,y1) and the
    planar-depth slopes (N,2) (:func:`depth_slope`, zero where culled).
    A culled Gaussian (masked, z <= near, singular, off-screen) gets radius 0 and a zero rect; its
    means2d / conic are zero too unless only its rectangle missed the screen."""
    rows, rot, lim = camera_tuples(view, intr)
    grid_x, grid_y = F32((width + TILE - 1) // TILE), F32((height + TILE - 1) // TILE)
    for blk in prange((means.shape[0] + BLOCK - 1) // BLOCK):
        lo, cnt, s = load_block(blk, N_FWD, means, quats, scales)
        for u in range(cnt):
            s[KEEP + u] = ONE if mask[lo + u] else ZERO
        project_block(s, cnt, rows, rot, lim, grid_x, grid_y)
        for u in range(cnt):
            i = lo + u
            means2d[i, 0], means2d[i, 1], depths[i] = s[MX + u], s[MY + u], s[DZ + u]
            conics[i, 0], conics[i, 1], conics[i, 2] = s[CA + u], s[CB + u], s[CC + u]
            radii[i] = int(s[RAD + u])
            slopes[i, 0], slopes[i, 1] = s[PU + u], s[PV + u]
            rects[i, 0], rects[i, 1], rects[i, 2], rects[i, 3] = (int(s[X0 + u]), int(s[X1 + u]),
                                                                  int(s[Y0 + u]), int(s[Y1 + u]))


@njit(cache=True, error_model="numpy")
def project_block_backward(s, cnt, view, rot, intr):
    """The backward pass on the first ``cnt`` scratch columns (see :func:`project_backward`)."""
    fx, fy = intr[0], intr[1]
    for u in range(np.uint64(cnt)):
        keep = s[KEEP + u] != ZERO
        px, py, z = camera_point(view, s[M0 + u], s[M1 + u], s[M2 + u])
        z = z if keep else ONE  # culled lanes stay finite
        sc = (s[S0 + u], s[S1 + u], s[S2 + u])
        q, norm, r, mm, cv = view_covariance(s[QW + u], s[QX + u], s[QY + u], s[QZ + u], sc[0], sc[1], sc[2],
                                             rot)
        norm = norm if keep else ONE
        j00, j02, j11, j12, tx, ty, x_in, y_in = jacobian(px, py, z, intr)
        _s00, _s01, _s11, a0, a1 = screen_cov(j00, j02, j11, j12, cv)
        g00, g01, g11 = _conic_vjp(s[CA + u], s[CB + u], s[CC + u], s[VA + u], s[VB + u], s[VC + u])
        # dL/dJ = 2 G J Sigma_view  (rows of J Sigma_view are a0, a1)
        vj00 = TWO * (g00 * a0[0] + g01 * a1[0])
        vj02 = TWO * (g00 * a0[2] + g01 * a1[2])
        vj11 = TWO * (g01 * a0[1] + g11 * a1[1])
        vj12 = TWO * (g01 * a0[2] + g11 * a1[2])
        # dL/dSigma_view = J^T G J, J = [[j00, 0, j02], [0, j11, j12]]
        b0 = (g00 * j00, g01 * j11, g00 * j02 + g01 * j12)
        b1 = (g01 * j00, g11 * j11, g01 * j02 + g11 * j12)
        v_cv = (j00 * b0[0], j00 * b0[1], j00 * b0[2],
                j11 * b1[0], j11 * b1[1], j11 * b1[2],
                j02 * b0[0] + j12 * b1[0], j02 * b0[1] + j12 * b1[1], j02 * b0[2] + j12 * b1[2])
        v_cov = _matmul3(_matmul3(_transpose3(rot), v_cv), rot)
        v_m = _matmul3(v_cov, mm)
        v_r = (TWO * v_m[0] * sc[0], TWO * v_m[1] * sc[1], TWO * v_m[2] * sc[2],
               TWO * v_m[3] * sc[0], TWO * v_m[4] * sc[1], TWO * v_m[5] * sc[2],
               TWO * v_m[6] * sc[0], TWO * v_m[7] * sc[1], TWO * v_m[8] * sc[2])
        gqw, gqx, gqy, gqz = _quat_vjp(q, norm, v_r)
        vu, vv = s[VU + u], s[VV + u]
        rz2 = ONE / (z * z)
        vx = vu * fx / z - (vj02 * fx * rz2 if x_in else ZERO)
        vy = vv * fy / z - (vj12 * fy * rz2 if y_in else ZERO)
        kx = TWO if x_in else ONE
        ky = TWO if y_in else ONE
        vz = (s[VZ + u] - (vu * fx * px + vv * fy * py + vj00 * fx + vj11 * fy) * rz2
              + (kx * vj02 * fx * tx + ky * vj12 * fy * ty) * rz2 / z)
        s[GM0 + u] = rot[0] * vx + rot[3] * vy + rot[6] * vz if keep else ZERO
        s[GM1 + u] = rot[1] * vx + rot[4] * vy + rot[7] * vz if keep else ZERO
        s[GM2 + u] = rot[2] * vx + rot[5] * vy + rot[8] * vz if keep else ZERO
        s[GQW + u], s[GQX + u] = (gqw if keep else ZERO), (gqx if keep else ZERO)
        s[GQY + u], s[GQZ + u] = (gqy if keep else ZERO), (gqz if keep else ZERO)
        for k in range(3):
            g_s = TWO * (v_m[k] * r[k] + v_m[3 + k] * r[3 + k] + v_m[6 + k] * r[6 + k])
            s[GS0 + np.uint64(k * BLOCK) + u] = g_s if keep else ZERO


@njit(cache=True, parallel=True, error_model="numpy")
def project_backward(means, quats, scales, view, intr, radii, conics, v_means2d, v_conics, v_depths,
                     v_means, v_quats, v_scales):
    """Chain rule of :func:`project_forward` for every rendered Gaussian (radius > 0); the others get
    zero gradients."""
    rows, rot, lim = camera_tuples(view, intr)
    for blk in prange((means.shape[0] + BLOCK - 1) // BLOCK):
        lo, cnt, s = load_block(blk, N_BWD, means, quats, scales)
        for u in range(cnt):
            i = lo + u
            s[KEEP + u] = ONE if radii[i] > 0 else ZERO
            s[CA + u], s[CB + u], s[CC + u] = conics[i, 0], conics[i, 1], conics[i, 2]
            s[VU + u], s[VV + u], s[VZ + u] = v_means2d[i, 0], v_means2d[i, 1], v_depths[i]
            s[VA + u], s[VB + u], s[VC + u] = v_conics[i, 0], v_conics[i, 1], v_conics[i, 2]
        project_block_backward(s, cnt, rows, rot, lim)
        for u in range(cnt):
            i = lo + u
            v_means[i, 0], v_means[i, 1], v_means[i, 2] = s[GM0 + u], s[GM1 + u], s[GM2 + u]
            v_quats[i, 0], v_quats[i, 1], v_quats[i, 2], v_quats[i, 3] = (s[GQW + u], s[GQX + u],
                                                                          s[GQY + u], s[GQZ + u])
            v_scales[i, 0], v_scales[i, 1], v_scales[i, 2] = s[GS0 + u], s[GS1 + u], s[GS2 + u]
