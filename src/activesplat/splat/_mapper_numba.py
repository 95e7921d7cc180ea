"""numba kernels of the online mapper's per-Gaussian bookkeeping (CPU): the view culling of
:func:`activesplat.splat.gaussians.frustum_rows` and the row-sparse Adam update of
:class:`activesplat.splat.optim.RowAdam`. Each is one parallel pass over the rows, where the torch
versions (kept for other devices, and compared in the tests) make a dozen passes and temporaries."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(parallel=True, cache=True)
def cull_rows(means, log_scales, rot, t, fx, fy, cx, cy, width, height, near, lim_x, lim_y, sigmas,
              low_pass, far, window, margin, use_depth):
    """(N,) bool: the Gaussian's conservative footprint reaches the image and, with ``use_depth``, the
    observed surface (``far``: window maxima of the depth, inf where unknown) does not hide it."""
    n = means.shape[0]
    keep = np.zeros(n, dtype=np.bool_)
    for i in prange(n):
        dx = means[i, 0] - t[0]
        dy = means[i, 1] - t[1]
        dz = means[i, 2] - t[2]
        z = dx * rot[0, 2] + dy * rot[1, 2] + dz * rot[2, 2]
        if z <= near:
            continue
        x = (dx * rot[0, 0] + dy * rot[1, 0] + dz * rot[2, 0]) / z
        y = (dx * rot[0, 1] + dy * rot[1, 1] + dz * rot[2, 1]) / z
        xc = min(max(x, -lim_x), lim_x)
        yc = min(max(y, -lim_y), lim_y)
        stretch = 1.0 + xc * xc + yc * yc
        s = math.exp(max(log_scales[i, 0], max(log_scales[i, 1], log_scales[i, 2]))) * max(fx, fy) / z
        radius = sigmas * math.sqrt(s * s * stretch + low_pass) + 1.0
        u = fx * x + cx
        v = fy * y + cy
        if u + radius < 0 or u - radius > width or v + radius < 0 or v - radius > height:
            continue
        if use_depth and radius <= window:
            ui = int(math.floor(u))
            vi = int(math.floor(v))
            if 0 <= ui < width and 0 <= vi < height and z > far[vi, ui] + margin:
                continue
        keep[i] = True
    return keep


@njit(parallel=True, cache=True)
def adam_rows(param, exp_avg, exp_avg_sq, grad, rows, step_size, bias2_sqrt, beta1, beta2, eps):
    """In place, for every k: Adam on row ``rows[k]`` of the (N, D) arrays with gradient ``grad[k]``;
    ``step_size[k]`` = lr / (1 - beta1^t), ``bias2_sqrt[k]`` = sqrt(1 - beta2^t) of the row's own t."""
    for k in prange(rows.shape[0]):
        i = rows[k]
        for d in range(param.shape[1]):
            g = grad[k, d]
            m = beta1 * exp_avg[i, d] + (1.0 - beta1) * g
            v = beta2 * exp_avg_sq[i, d] + (1.0 - beta2) * g * g
            exp_avg[i, d] = m
            exp_avg_sq[i, d] = v
            param[i, d] -= step_size[k] * m / (math.sqrt(v) / bias2_sqrt[k] + eps)


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
