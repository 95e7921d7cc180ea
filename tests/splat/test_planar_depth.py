"""Planar depth (:mod:`activesplat.splat.raster.planar`): a slanted wall of flat Gaussians renders the
wall's depth, not a staircase of centre depths."""

import math

import pytest
import torch
from raster_scenes import intrinsics

from activesplat.splat import rasterize
from activesplat.splat.kernels import rotmat_to_quat
from activesplat.splat.raster.planar import depth_slopes

W, H = 64, 48


def slanted_wall(slope_deg: float, spacing: float = 0.04):
    """Flat Gaussians tiling the plane z = 2 + tan(slope) x in front of a camera at the origin."""
    t = math.tan(math.radians(slope_deg))
    u = torch.arange(-1.6, 1.6, spacing)
    gx, gy = torch.meshgrid(u, u[: len(u) * 3 // 4], indexing="ij")
    x, y = gx.reshape(-1), gy.reshape(-1)
    means = torch.stack([x, y, 2.0 + t * x], dim=1)
    tangent = torch.tensor([1.0, 0.0, t]) / math.hypot(1.0, t)
    normal = torch.linalg.cross(tangent, torch.tensor([0.0, 1.0, 0.0]))
    rot = torch.stack([tangent, torch.tensor([0.0, 1.0, 0.0]), normal], dim=1)  # columns: the axes
    n = len(means)
    quats = rotmat_to_quat(rot[None].expand(n, 3, 3).contiguous())
    scales = torch.tensor([spacing * 0.7 * math.hypot(1.0, t), spacing * 0.7, 0.002]).expand(n, 3).clone()
    colors = torch.rand(n, 3, generator=torch.Generator().manual_seed(0))
    return means, quats, scales, torch.full((n,), 0.9), colors


def wall_depth_error(slope_deg: float, planar: bool) -> float:
    params = slanted_wall(slope_deg)
    K = intrinsics(W, H)
    out = rasterize(*params, torch.eye(4), K, W, H, backend="numba", planar_depth=planar)
    t = math.tan(math.radians(slope_deg))
    u = (torch.arange(W) + 0.5 - K[0, 2]) / K[0, 0]
    true = (2.0 / (1.0 - t * u))[None, :].expand(H, W)  # ray (u, v, 1) meets z = 2 + t x at z = 2 / (1 - t u)
    covered = out.alpha > 0.99
    assert covered.float().mean() > 0.5
    return float(((out.depth / out.alpha - true).abs())[covered].mean())


@pytest.mark.parametrize(("slope_deg", "gain", "bound_m"), [(20.0, 0.05, 0.001), (30.0, 0.05, 0.002),
                                                           (60.0, 0.5, 0.05)])
def test_slanted_wall_renders_its_depth(slope_deg, gain, bound_m):
    """Half-pixel Gaussians (the low-pass filter sets their footprint): with centre depths the front ones
    pull every pixel forward by 2 cm (20 degrees) to 9 cm (60). With planar depth a wall turned less
    than the 45 degree bound renders within a millimetre or two; at 60 degrees the slopes are capped
    (planar.MAX_TILT_DEG) and the error shrinks by half."""
    centre, planar = wall_depth_error(slope_deg, False), wall_depth_error(slope_deg, True)
    assert planar < gain * centre, (planar, centre)
    assert planar < bound_m, planar


def test_slopes_of_a_flat_gaussian_are_its_tangent_plane():
    """dz/du of a flat Gaussian equals that of its plane, -z^2 n_x / (fx n . mu) (the wall is turned 20
    degrees, less than the bound); zero where not rendered."""
    means, quats, scales, *_ = slanted_wall(20.0, spacing=0.5)
    K = intrinsics(W, H)
    radii = torch.full((len(means),), 5, dtype=torch.int32)
    radii[0] = 0
    p = depth_slopes(means, quats, scales * torch.tensor([1.0, 1.0, 0.01]), torch.eye(4), K, radii)
    t = math.tan(math.radians(20.0))
    normal = torch.tensor([-t, 0.0, 1.0])  # of z - t x = 2
    z = means[:, 2]
    expected = -z * z * normal[0] / (K[0, 0] * (means @ normal))
    torch.testing.assert_close(p[1:, 0], expected[1:], rtol=2e-3, atol=1e-7)
    assert torch.all(p[0] == 0) and p[1:, 1].abs().max() < 1e-6


def test_blended_features_give_the_planar_depth():
    """The gsplat backend renders planar depth as three blended features (z - p . mean2d, p_u, p_v)
    combined per pixel; the same features through the torch reference give its planar depth."""
    from raster_scenes import random_scene

    from activesplat.splat.raster.gsplat_backend import _planar_depth_image

    params = random_scene(60, 3, scale=(0.02, 0.3))
    K = intrinsics(W, H)
    ref = rasterize(*params, torch.eye(4), K, W, H, backend="torch", planar_depth=True)
    p = depth_slopes(*params[:3], torch.eye(4), K, ref.radii)
    features = torch.cat([(ref.depths - (p * ref.means2d).sum(-1))[:, None], p], dim=1)
    blended = rasterize(*params[:4], features, torch.eye(4), K, W, H, backend="torch")
    image = torch.cat([blended.rgb, blended.rgb], dim=-1)  # channels 3-5 are read
    torch.testing.assert_close(_planar_depth_image(image), ref.depth, atol=1e-4, rtol=1e-4)


def test_isotropic_gaussians_keep_their_centre_depth():
    """The flatness factor: an isotropic Gaussian off the image axis has no slope (its densest point along
    each ray would tilt it towards the camera centre), a flat one has its plane's."""
    K = intrinsics(W, H)
    means = torch.tensor([[1.0, 0.5, 2.0], [1.0, 0.5, 2.0]])
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    scales = torch.tensor([[0.05, 0.05, 0.05], [0.05, 0.05, 0.0005]])
    p = depth_slopes(means, quats, scales, torch.eye(4), K, torch.ones(2, dtype=torch.int32))
    assert torch.all(p[0] == 0)
    assert p[1].abs().max() < 1e-4  # a frontal plane (normal along z): next to none (z / f = 0.06)
    one = (means[:1], quats[:1], scales[:1], torch.full((1,), 0.9), torch.ones(1, 3))
    out = rasterize(*one, torch.eye(4), K, W, H, backend="numba", planar_depth=True)
    covered = out.alpha > 0.1
    depth = out.depth[covered] / out.alpha[covered]
    torch.testing.assert_close(depth, torch.full_like(depth, 2.0))
