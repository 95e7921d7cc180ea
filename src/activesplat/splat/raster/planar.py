"""Planar depth: each Gaussian's depth varies over its footprint (project default; 3DGS: constant).

3DGS blends one depth per Gaussian, the view z of its centre, over every pixel it covers. On a wall
seen at an angle, a flat Gaussian 3 cm wide then renders a step of up to a few centimetres across its
footprint, and the blended depth of a surface is a staircase of such steps.

With ``planar_depth`` every Gaussian renders, at pixel (u, v), the depth at which the density along
that pixel's ray is largest, linearised at its projected centre (RaDe-GS, Zhang et al. 2024, do the
same in ray space):

    z_i(u, v) = z_i + p_i . ((u, v) - mean2d_i),
    p_i = -(Sigma^-1 mu)_(x, y) z_i^2 / (mu^T Sigma^-1 mu) / (fx, fy) * (1 - (s_min / s_mid)^2),

with mu the centre and Sigma the covariance in camera coordinates. Along the ray d = (x, y, 1) of a
pixel the density is largest at t*(d) = d^T Sigma^-1 mu / d^T Sigma^-1 d; p is its derivative at the
centre's ray, d = mu / z. For a flat Gaussian Sigma^-1 is dominated by n n^T / s_n^2 and p is the
slope of the tangent plane (exact to first order: 1 / z is affine in (u, v) on a plane). For an
isotropic one it would be the slope of the closest point on each ray, a plane facing the camera
centre, which off the image axis is tilted against a wall the Gaussian lies on (a frontal wall of
19 cm Gaussians in a 32 px test image rendered up to 10 cm off): the last factor, the flatness from
the smallest and middle scales, keeps the centre's depth for isotropic Gaussians (0.99 of the slope
for the mapper's flat ones, scale ratio 0.1; 13 % of a medium-house map stays isotropic).

The slope is bounded by that of a plane turned ``MAX_TILT_DEG`` = 45 degrees away from facing the
camera, |p| <= z / f. A plane seen edge-on has an unbounded slope; the formula bounds itself near
tan = s_tangent / (2 s_normal), 5 for the mapper's flat Gaussians, but measured, steep slopes cost
colour: mapping 700 frames of a look-around of medium-1, keyframe PSNR 34.08 dB and depth L1 1.61 cm
with centre depths; 33.10 dB / 1.16 cm with a bound at 84 degrees, 33.67 / 1.19 at 60, 34.03 / 1.28 at
45, 34.08 / 1.35 at 30 (steep slopes extrapolated past silhouettes give large depth residuals, whose
gradient lowers opacities); with the flatness factor at 45 degrees 34.06 / 1.28. The footprint is not
a bound: the mapper's Gaussians are about a pixel wide, so the 0.3 px low-pass sets their footprint, and
over the blurred part of it the plane's continuation is the depth the neighbouring Gaussians of the
same surface render there.

Sorting, opacity and colour are unchanged; the depth and the median depth of every backend use
z_i(u, v). The slopes carry no gradient: the depth loss moves a Gaussian (its centre's depth and its
projected centre) but turns it only through colour, as with centre depths. Letting the depth loss turn
it through p gave the same map (33.13 against 33.10 dB, 1.15 against 1.16 cm, same 700 frames).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from activesplat.splat.kernels import quat_to_rotmat

MIN_SCALE = 1e-6
"""Scales are floored at this (metres) before 1 / s^2, against overflow in float32."""
MAX_TILT_DEG = 45.0
"""The steepest slope a Gaussian renders: that of a plane at this angle to the image plane (see above)."""


@torch.no_grad()
def depth_slopes(means: Tensor, quats: Tensor, scales: Tensor, viewmat: Tensor, K: Tensor,
                 radii: Tensor) -> Tensor:
    """(N, 2) dz/du, dz/dv in metres per pixel of every rendered Gaussian (``radii`` > 0), 0 elsewhere;
    no gradient (module docstring). The numba backend computes the same in its projection kernel."""
    slopes = torch.zeros(means.shape[0], 2, dtype=means.dtype, device=means.device)
    vis = torch.nonzero(radii > 0).squeeze(1)
    if vis.numel() == 0:
        return slopes
    rot_view, trans = viewmat[:3, :3].to(means.dtype), viewmat[:3, 3].to(means.dtype)
    mu = means[vis] @ rot_view.T + trans
    axes = rot_view @ quat_to_rotmat(quats[vis])  # columns: the Gaussian's axes in camera coordinates
    s = scales[vis].clamp_min(MIN_SCALE)
    local = (axes.transpose(1, 2) @ mu[:, :, None]).squeeze(-1)  # mu in the Gaussian's frame
    w = local / (s * s)
    a_mu = (axes @ w[:, :, None]).squeeze(-1)  # Sigma^-1 mu
    q = (local * w).sum(-1)  # mu^T Sigma^-1 mu
    z = mu[:, 2]
    focal = torch.stack([K[0, 0], K[1, 1]]).to(means.dtype)
    ordered = s.sort(dim=-1).values
    flatness = 1.0 - (ordered[:, 0] / ordered[:, 1]) ** 2
    p = -a_mu[:, :2] * (z * z / q * flatness)[:, None] / focal
    limit = math.tan(math.radians(MAX_TILT_DEG)) * z / focal.min()
    shrink = torch.clamp(limit / p.norm(dim=-1).clamp_min(1e-30), max=1.0)
    return slopes.index_put((vis,), p * shrink[:, None])


def pixel_depths(depths: Tensor, slopes: Tensor | None, means2d: Tensor, pix: Tensor) -> Tensor:
    """(P, M) depth of M Gaussians (``depths`` (M,), ``slopes`` (M, 2) or None, ``means2d`` (M, 2)) at
    P pixel centres ``pix`` (P, 2): z_i + p_i . (pix - mean2d_i)."""
    if slopes is None:
        return depths[None, :].expand(pix.shape[0], -1)
    offset = pix[:, None, :] - means2d[None, :, :]
    return depths[None, :] + (offset * slopes[None, :, :]).sum(-1)
