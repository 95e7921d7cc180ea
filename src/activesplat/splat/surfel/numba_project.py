"""numba kernels: 2DGS surfel projection (the KWH transform, screen box, facing normal) and its backward.

Per surfel, in camera space: p = W m + t, a = s_u R_v t_u, b = s_v R_v t_v, n = +-R_v t_n. The
transform T = K [a | b | p] is handed to the compositor as the projected centre c = (u, v) =
(T_02 / z, T_12 / z), the centre depth z = T_22 and the 3x2 matrix M of the tangent columns in pixel
coordinates relative to c: M = [[A0, B0], [A1, B1], [A2, B2]] with A0 = T_00 - u T_20 = fx (a_x - x a_z / z),
A1 = fy (a_y - y a_z / z), A2 = a_z (B likewise from b), i.e. T = [[M_0 + u M_2, z u], [M_1 + v M_2, z v],
[M_2, z]]. Shifting c at fixed M translates the footprint on screen, which makes the gradient of c the
densification statistic, and the relative coordinates keep float32 well conditioned.
All arithmetic is float32 (constants are np.float32 so nothing promotes to float64).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from activesplat.splat.kernels import matmul3, quat_rotmat, quat_vjp, transpose3
from activesplat.splat.raster.constants import RASTER
from activesplat.splat.surfel.constants import SURFEL

F32 = np.float32
NEAR = F32(SURFEL.near)
ALPHA_MIN = F32(RASTER.alpha_min)
LOG_255 = F32(SURFEL.log_255)
INV_FILTER = F32(1.0 / SURFEL.filter_inv_square)
BOX_PAD = F32(SURFEL.box_pad)
TILE = RASTER.tile_size
ZERO, HALF, ONE, TWO = F32(0.0), F32(0.5), F32(1.0), F32(2.0)


@njit(cache=True, error_model="numpy")
def surfel_frame(quat, rot):
    """(unit quaternion, |q|, camera-space axes C = R_v R(q) as a row-major 9-tuple: columns t_u, t_v, n)."""
    norm = np.sqrt(quat[0] * quat[0] + quat[1] * quat[1] + quat[2] * quat[2] + quat[3] * quat[3])
    w, x, y, z = quat[0] / norm, quat[1] / norm, quat[2] / norm, quat[3] / norm
    return (w, x, y, z), norm, matmul3(rot, quat_rotmat(w, x, y, z))


@njit(cache=True, error_model="numpy")
def view_point(view, m):
    """p = W m + t (view-space point) of a world point m (3,)."""
    return (view[0, 0] * m[0] + view[0, 1] * m[1] + view[0, 2] * m[2] + view[0, 3],
            view[1, 0] * m[0] + view[1, 1] * m[1] + view[1, 2] * m[2] + view[1, 3],
            view[2, 0] * m[0] + view[2, 1] * m[1] + view[2, 2] * m[2] + view[2, 3])


@njit(cache=True, error_model="numpy")
def relative_column(c0, c1, c2, px, py, z, fx, fy):
    """Tangent column (c0, c1, c2) in pixel coordinates relative to the projected centre (see module doc)."""
    return fx * (c0 - px * c2 / z), fy * (c1 - py * c2 / z), c2


@njit(cache=True, error_model="numpy")
def box_axis(r2, z, c22, a, b, a2, b2, r_low):
    """[lo, hi] offsets from the centre, along one screen axis, of the box of the projected disc
    u^2 + v^2 <= r2 (tangents of the dual conic T diag(r2, r2, -1) T^T; the half width follows from
    Cauchy-Binet without cancellation) union the low-pass disc of radius r_low."""
    mid = r2 * (a * a2 + b * b2) / c22
    cross = a * b2 - b * a2
    half = np.sqrt(max(ZERO, (r2 * z * z * (a * a + b * b) - r2 * r2 * cross * cross) / (c22 * c22)))
    return min(mid - half, -r_low) - BOX_PAD, max(mid + half, r_low) + BOX_PAD


@njit(cache=True, error_model="numpy")
def pixel_span(centre, lo, hi, size):
    """First and last pixel index (clamped to the image) whose centre lies in [centre + lo, centre + hi]."""
    first = max(ZERO, np.ceil(centre + lo - HALF))
    last = min(F32(size - 1), np.floor(centre + hi - HALF))
    return first, last


@njit(cache=True, parallel=True, error_model="numpy")
def project_forward(means, quats, scales, opacities, view, intr, width, height,
                    means2d, depths, tmat, normals, boxes, radii, rects):
    """Fill means2d (N,2), depths (N,), tmat (N,6) = [A0, A1, A2, B0, B1, B2], facing normals (N,3),
    pixel boxes (N,4) [centre x, centre y, half x, half y], radii (N,) and tile rects (N,4) [x0,x1,y0,y1)."""
    rot = (view[0, 0], view[0, 1], view[0, 2], view[1, 0], view[1, 1], view[1, 2],
           view[2, 0], view[2, 1], view[2, 2])
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    for i in prange(means.shape[0]):
        px, py, z = view_point(view, means[i])
        depths[i] = z
        radii[i] = 0
        o = opacities[i]
        if not z > NEAR or not o > ALPHA_MIN:
            continue
        r2 = TWO * (np.log(o) + LOG_255)
        _q, _norm, c = surfel_frame(quats[i], rot)
        su, sv = scales[i, 0], scales[i, 1]
        a0, a1, a2 = relative_column(su * c[0], su * c[3], su * c[6], px, py, z, fx, fy)
        b0, b1, b2 = relative_column(sv * c[1], sv * c[4], sv * c[7], px, py, z, fx, fy)
        tilt = a2 * a2 + b2 * b2
        if not z - np.sqrt(r2 * tilt) > NEAR:
            continue  # the footprint disc reaches the near plane
        u, v = fx * px / z + cx, fy * py / z + cy
        c22 = r2 * tilt - z * z
        r_low = np.sqrt(r2 * INV_FILTER)
        xlo, xhi = box_axis(r2, z, c22, a0, b0, a2, b2, r_low)
        ylo, yhi = box_axis(r2, z, c22, a1, b1, a2, b2, r_low)
        jx0, jx1 = pixel_span(u, xlo, xhi, width)
        iy0, iy1 = pixel_span(v, ylo, yhi, height)
        if jx0 > jx1 or iy0 > iy1:
            continue
        means2d[i, 0], means2d[i, 1] = u, v
        tmat[i, 0], tmat[i, 1], tmat[i, 2], tmat[i, 3], tmat[i, 4], tmat[i, 5] = a0, a1, a2, b0, b1, b2
        flip = c[2] * px + c[5] * py + c[8] * z > ZERO
        sign = -ONE if flip else ONE
        normals[i, 0], normals[i, 1], normals[i, 2] = sign * c[2], sign * c[5], sign * c[8]
        boxes[i, 0], boxes[i, 1] = u + HALF * (xlo + xhi), v + HALF * (ylo + yhi)
        boxes[i, 2], boxes[i, 3] = HALF * (xhi - xlo), HALF * (yhi - ylo)
        radii[i] = int(np.ceil(max(max(-xlo, xhi), max(-ylo, yhi))))
        rects[i, 0], rects[i, 1] = int(jx0) // TILE, int(jx1) // TILE + 1
        rects[i, 2], rects[i, 3] = int(iy0) // TILE, int(iy1) // TILE + 1


@njit(cache=True, error_model="numpy")
def relative_column_vjp(c2, px, py, z, fx, fy, va0, va1, va2):
    """Gradient on the camera-space column (c0, c1, c2) and on (x, y, z) from that on
    :func:`relative_column`'s output."""
    vc = (fx * va0, fy * va1, va2 - (fx * px * va0 + fy * py * va1) / z)
    vp = (-fx * c2 * va0 / z, -fy * c2 * va1 / z, (fx * px * va0 + fy * py * va1) * c2 / (z * z))
    return vc, vp


@njit(cache=True, parallel=True, error_model="numpy")
def project_backward(means, quats, scales, view, intr, radii, v_means2d, v_depths, v_tmat, v_normals,
                     v_means, v_quats, v_scales):
    """Chain rule of :func:`project_forward` for every rendered surfel (radius > 0)."""
    rot = (view[0, 0], view[0, 1], view[0, 2], view[1, 0], view[1, 1], view[1, 2],
           view[2, 0], view[2, 1], view[2, 2])
    fx, fy = intr[0], intr[1]
    for i in prange(means.shape[0]):
        if radii[i] == 0:
            continue
        px, py, z = view_point(view, means[i])
        q, norm, c = surfel_frame(quats[i], rot)
        su, sv = scales[i, 0], scales[i, 1]
        vt = v_tmat[i]
        va, vpa = relative_column_vjp(su * c[6], px, py, z, fx, fy, vt[0], vt[1], vt[2])
        vb, vpb = relative_column_vjp(sv * c[7], px, py, z, fx, fy, vt[3], vt[4], vt[5])
        vu, vv = v_means2d[i, 0], v_means2d[i, 1]
        vx = vpa[0] + vpb[0] + vu * fx / z
        vy = vpa[1] + vpb[1] + vv * fy / z
        vz = vpa[2] + vpb[2] + v_depths[i] - (vu * fx * px + vv * fy * py) / (z * z)
        for k in range(3):
            v_means[i, k] = view[0, k] * vx + view[1, k] * vy + view[2, k] * vz
        v_scales[i, 0] = c[0] * va[0] + c[3] * va[1] + c[6] * va[2]
        v_scales[i, 1] = c[1] * vb[0] + c[4] * vb[1] + c[7] * vb[2]
        sign = -ONE if c[2] * px + c[5] * py + c[8] * z > ZERO else ONE
        vn = v_normals[i]
        v_axes = (su * va[0], sv * vb[0], sign * vn[0],
                  su * va[1], sv * vb[1], sign * vn[1],
                  su * va[2], sv * vb[2], sign * vn[2])
        v_rq = matmul3(transpose3(rot), v_axes)
        v_quats[i, 0], v_quats[i, 1], v_quats[i, 2], v_quats[i, 3] = quat_vjp(q, norm, v_rq)
