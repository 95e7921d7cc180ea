"""numba kernels: EWA projection of 3D Gaussians to 2D conics and its analytic backward pass.

Forward (3DGS ``preprocessCUDA``): p = W m + t; Sigma = R S S^T R^T; Sigma_2D = J W Sigma W^T J^T
+ 0.3 I; conic = Sigma_2D^-1; radius = ceil(3 sqrt(lambda_max)); tile rectangle of mean2d +- radius.
The backward pass is the chain rule of the same formulas, one Gaussian per parallel iteration.
All arithmetic is float32 (constants are np.float32 so nothing promotes to float64).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from activesplat.splat._raster_common import RASTER

F32 = np.float32
NEAR = F32(RASTER.near)
LOW_PASS = F32(RASTER.low_pass)
SIGMAS = F32(RASTER.extent_sigmas)
EIGEN_GAP = F32(RASTER.min_eigen_gap)
TILE = RASTER.tile_size
TILE_F = F32(RASTER.tile_size)
ZERO, HALF, ONE, TWO = F32(0.0), F32(0.5), F32(1.0), F32(2.0)


@njit(cache=True, error_model="numpy")
def quat_rotmat(w, x, y, z):
    """Rotation matrix (row-major 9-tuple) of a unit quaternion wxyz."""
    return (
        ONE - TWO * (y * y + z * z), TWO * (x * y - w * z), TWO * (x * z + w * y),
        TWO * (x * y + w * z), ONE - TWO * (x * x + z * z), TWO * (y * z - w * x),
        TWO * (x * z - w * y), TWO * (y * z + w * x), ONE - TWO * (x * x + y * y),
    )


@njit(cache=True, error_model="numpy")
def matmul3(a, b):
    """3x3 product of row-major 9-tuples."""
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6], a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@njit(cache=True, error_model="numpy")
def transpose3(a):
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


@njit(cache=True, error_model="numpy")
def view_covariance(quat, scale, rot):
    """(unit quaternion, R(q), M = R(q) diag(s), W Sigma W^T) for one Gaussian."""
    norm = np.sqrt(quat[0] * quat[0] + quat[1] * quat[1] + quat[2] * quat[2] + quat[3] * quat[3])
    w, x, y, z = quat[0] / norm, quat[1] / norm, quat[2] / norm, quat[3] / norm
    r = quat_rotmat(w, x, y, z)
    s0, s1, s2 = scale[0], scale[1], scale[2]
    m = (r[0] * s0, r[1] * s1, r[2] * s2, r[3] * s0, r[4] * s1, r[5] * s2, r[6] * s0, r[7] * s1, r[8] * s2)
    cov = matmul3(m, transpose3(m))
    return (w, x, y, z), norm, r, m, matmul3(matmul3(rot, cov), transpose3(rot))


@njit(cache=True, error_model="numpy")
def jacobian(px, py, z, intr):
    """EWA Jacobian entries (j00, j02, j11, j12) at x/z, y/z clamped to the padded image, plus
    whether x and y were inside the clamp (3DGS / gsplat ``persp_proj``)."""
    fx, fy = intr[0], intr[1]
    rx, ry = px / z, py / z
    x_in = rx >= -intr[4] and rx <= intr[5]
    y_in = ry >= -intr[6] and ry <= intr[7]
    tx = z * min(intr[5], max(-intr[4], rx))
    ty = z * min(intr[7], max(-intr[6], ry))
    return fx / z, -fx * tx / (z * z), fy / z, -fy * ty / (z * z), tx, ty, x_in, y_in


@njit(cache=True, error_model="numpy")
def screen_cov(j00, j02, j11, j12, cv):
    """Sigma_2D = J Sigma_view J^T + 0.3 I as (s00, s01, s11), plus A = J Sigma_view (2x3)."""
    a0 = (j00 * cv[0] + j02 * cv[6], j00 * cv[1] + j02 * cv[7], j00 * cv[2] + j02 * cv[8])
    a1 = (j11 * cv[3] + j12 * cv[6], j11 * cv[4] + j12 * cv[7], j11 * cv[5] + j12 * cv[8])
    s00 = a0[0] * j00 + a0[2] * j02 + LOW_PASS
    s01 = a0[1] * j11 + a0[2] * j12
    s11 = a1[1] * j11 + a1[2] * j12 + LOW_PASS
    return s00, s01, s11, a0, a1


@njit(cache=True, parallel=True, error_model="numpy")
def project_forward(means, quats, scales, view, intr, width, height, mask,
                    means2d, conics, depths, radii, rects):
    """Fill means2d (N,2), conics (N,3), depths (N,), radii (N,) and tile rects (N,4) [x0,x1,y0,y1)."""
    rot = (view[0, 0], view[0, 1], view[0, 2], view[1, 0], view[1, 1], view[1, 2],
           view[2, 0], view[2, 1], view[2, 2])
    grid_x, grid_y = (width + TILE - 1) // TILE, (height + TILE - 1) // TILE
    for i in prange(means.shape[0]):
        m = means[i]
        px = view[0, 0] * m[0] + view[0, 1] * m[1] + view[0, 2] * m[2] + view[0, 3]
        py = view[1, 0] * m[0] + view[1, 1] * m[1] + view[1, 2] * m[2] + view[1, 3]
        z = view[2, 0] * m[0] + view[2, 1] * m[1] + view[2, 2] * m[2] + view[2, 3]
        depths[i] = z
        radii[i] = 0
        if not mask[i] or not z > NEAR:
            continue
        _q, _n, _r, _m, cv = view_covariance(quats[i], scales[i], rot)
        j00, j02, j11, j12, _tx, _ty, _xin, _yin = jacobian(px, py, z, intr)
        s00, s01, s11, _a0, _a1 = screen_cov(j00, j02, j11, j12, cv)
        det = s00 * s11 - s01 * s01
        if not det > ZERO:
            continue
        conics[i, 0], conics[i, 1], conics[i, 2] = s11 / det, -s01 / det, s00 / det
        mx, my = intr[0] * px / z + intr[2], intr[1] * py / z + intr[3]
        means2d[i, 0], means2d[i, 1] = mx, my
        mid = HALF * (s00 + s11)
        radius = np.ceil(SIGMAS * np.sqrt(mid + np.sqrt(max(EIGEN_GAP, mid * mid - det))))
        x0 = min(max(np.floor((mx - radius) / TILE_F), ZERO), F32(grid_x))
        x1 = min(max(np.ceil((mx + radius) / TILE_F), ZERO), F32(grid_x))
        y0 = min(max(np.floor((my - radius) / TILE_F), ZERO), F32(grid_y))
        y1 = min(max(np.ceil((my + radius) / TILE_F), ZERO), F32(grid_y))
        if x1 > x0 and y1 > y0:
            radii[i] = int(radius)
            rects[i, 0], rects[i, 1], rects[i, 2], rects[i, 3] = int(x0), int(x1), int(y0), int(y1)


@njit(cache=True, error_model="numpy")
def conic_vjp(a, b, c, va, vb, vc):
    """Gradient on Sigma_2D (g00, g01, g11; symmetric matrix entries) from the conic gradient, with
    power = 0.5 (a dx^2 + c dy^2) + b dx dy: dL/dSigma = -C G C, G = [[va, vb/2], [vb/2, vc]]."""
    hb = HALF * vb
    cg00, cg01 = a * va + b * hb, a * hb + b * vc
    cg10, cg11 = b * va + c * hb, b * hb + c * vc
    return -(cg00 * a + cg01 * b), -(cg00 * b + cg01 * c), -(cg10 * b + cg11 * c)


@njit(cache=True, error_model="numpy")
def quat_vjp(q, norm, v_r):
    """Gradient on the raw quaternion from the gradient on R(q / |q|)."""
    w, x, y, z = q
    gw = TWO * (-z * v_r[1] + y * v_r[2] + z * v_r[3] - x * v_r[5] - y * v_r[6] + x * v_r[7])
    gx = TWO * (y * v_r[1] + z * v_r[2] + y * v_r[3] - TWO * x * v_r[4] - w * v_r[5] + z * v_r[6]
                + w * v_r[7] - TWO * x * v_r[8])
    gy = TWO * (-TWO * y * v_r[0] + x * v_r[1] + w * v_r[2] + x * v_r[3] + z * v_r[5] - w * v_r[6]
                + z * v_r[7] - TWO * y * v_r[8])
    gz = TWO * (-TWO * z * v_r[0] - w * v_r[1] + x * v_r[2] + w * v_r[3] - TWO * z * v_r[4] + y * v_r[5]
                + x * v_r[6] + y * v_r[7])
    dot = w * gw + x * gx + y * gy + z * gz
    return (gw - w * dot) / norm, (gx - x * dot) / norm, (gy - y * dot) / norm, (gz - z * dot) / norm


@njit(cache=True, parallel=True, error_model="numpy")
def project_backward(means, quats, scales, view, intr, radii, conics, v_means2d, v_conics, v_depths,
                     v_means, v_quats, v_scales):
    """Chain rule of :func:`project_forward` for every rendered Gaussian (radius > 0)."""
    rot = (view[0, 0], view[0, 1], view[0, 2], view[1, 0], view[1, 1], view[1, 2],
           view[2, 0], view[2, 1], view[2, 2])
    fx, fy = intr[0], intr[1]
    for i in prange(means.shape[0]):
        if radii[i] == 0:
            continue
        m = means[i]
        px = view[0, 0] * m[0] + view[0, 1] * m[1] + view[0, 2] * m[2] + view[0, 3]
        py = view[1, 0] * m[0] + view[1, 1] * m[1] + view[1, 2] * m[2] + view[1, 3]
        z = view[2, 0] * m[0] + view[2, 1] * m[1] + view[2, 2] * m[2] + view[2, 3]
        q, norm, r, mm, cv = view_covariance(quats[i], scales[i], rot)
        j00, j02, j11, j12, tx, ty, x_in, y_in = jacobian(px, py, z, intr)
        _s00, _s01, _s11, a0, a1 = screen_cov(j00, j02, j11, j12, cv)
        g00, g01, g11 = conic_vjp(conics[i, 0], conics[i, 1], conics[i, 2],
                                  v_conics[i, 0], v_conics[i, 1], v_conics[i, 2])
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
        v_cov = matmul3(matmul3(transpose3(rot), v_cv), rot)
        v_m = matmul3(v_cov, mm)
        s = scales[i]
        v_r = (TWO * v_m[0] * s[0], TWO * v_m[1] * s[1], TWO * v_m[2] * s[2],
               TWO * v_m[3] * s[0], TWO * v_m[4] * s[1], TWO * v_m[5] * s[2],
               TWO * v_m[6] * s[0], TWO * v_m[7] * s[1], TWO * v_m[8] * s[2])
        for k in range(3):
            v_scales[i, k] = TWO * (v_m[k] * r[k] + v_m[3 + k] * r[3 + k] + v_m[6 + k] * r[6 + k])
        v_quats[i, 0], v_quats[i, 1], v_quats[i, 2], v_quats[i, 3] = quat_vjp(q, norm, v_r)
        vu, vv = v_means2d[i, 0], v_means2d[i, 1]
        rz2 = ONE / (z * z)
        vx = vu * fx / z - (vj02 * fx * rz2 if x_in else ZERO)
        vy = vv * fy / z - (vj12 * fy * rz2 if y_in else ZERO)
        kx = TWO if x_in else ONE
        ky = TWO if y_in else ONE
        vz = (v_depths[i] - (vu * fx * px + vv * fy * py + vj00 * fx + vj11 * fy) * rz2
              + (kx * vj02 * fx * tx + ky * vj12 * fy * ty) * rz2 / z)
        for k in range(3):
            v_means[i, k] = view[0, k] * vx + view[1, k] * vy + view[2, k] * vz
