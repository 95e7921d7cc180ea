"""2DGS surfel rasterizer: numba vs the torch reference, finite differences, geometry, edge cases."""

import math

import pytest
import torch
from raster_scenes import intrinsics

from activesplat.errors import InvalidInputError
from activesplat.splat import RenderOutput, SurfelRenderOutput, rasterize_surfels
from activesplat.splat.surfel.torch_ref import rasterize_surfels_torch

W, H = 40, 30  # partial tiles on the right and bottom edges
BG = torch.tensor([0.1, 0.2, 0.3])
IMAGES = ("rgb", "depth", "alpha", "normal", "distortion")


@pytest.fixture(scope="module", autouse=True)
def warm_surfel_kernels():
    """Compile (or load from numba's disk cache) the surfel kernels once for this module."""
    from activesplat.splat.surfel.numba_backend import warm_up

    warm_up()


def random_surfels(n, seed, *, scale=(0.05, 0.3), opacity=(0.05, 0.95), depth=(1.0, 4.0), spread=1.0,
                   dtype=torch.float32):
    """N surfels in front of a camera at the origin looking down +z (viewmat = identity)."""
    g = torch.Generator().manual_seed(seed)
    z = depth[0] + (depth[1] - depth[0]) * torch.rand(n, generator=g, dtype=dtype)
    xy = (torch.rand(n, 2, generator=g, dtype=dtype) * 2 - 1) * spread * z[:, None]
    means = torch.cat([xy, z[:, None]], dim=1)
    quats = torch.randn(n, 4, generator=g, dtype=dtype)
    scales = scale[0] + (scale[1] - scale[0]) * torch.rand(n, 2, generator=g, dtype=dtype)
    opacities = opacity[0] + (opacity[1] - opacity[0]) * torch.rand(n, generator=g, dtype=dtype)
    colors = torch.rand(n, 3, generator=g, dtype=dtype)
    return means, quats, scales, opacities, colors


def behind_and_off_screen(n, seed):
    params = random_surfels(n, seed, spread=2.0, depth=(-1.0, 4.0))
    params[0][: n // 4, 2] = torch.linspace(-2.0, 0.005, n // 4)  # behind the camera or inside near
    return params


def equal_depths(n, seed):
    params = random_surfels(n, seed, opacity=(0.5, 0.95))
    params[0][:, 2] = torch.tensor([2.0, 3.0])[torch.arange(n) % 2]  # ties: the stable sort keeps index order
    return params


def grazing(n, seed):
    """Surfels whose normals are nearly perpendicular to the view ray: thin slivers plus the low-pass."""
    means, quats, scales, opacities, colors = random_surfels(n, seed, scale=(0.1, 0.5), opacity=(0.5, 0.95))
    angle = torch.linspace(-0.2, 0.2, n) + math.pi / 2  # tilt about x close to 90 degrees
    quats = torch.stack([torch.cos(angle / 2), torch.sin(angle / 2), torch.zeros(n), torch.zeros(n)], dim=1)
    return means, quats, scales, opacities, colors


SCENES = {
    "random": lambda: random_surfels(60, 1),
    "large_opaque": lambda: random_surfels(40, 3, scale=(0.3, 1.5), opacity=(0.9, 1.0)),
    "behind_and_off_screen": lambda: behind_and_off_screen(48, 4),
    "equal_depths": lambda: equal_depths(30, 5),
    "tiny_splats": lambda: random_surfels(120, 6, scale=(0.003, 0.02)),
    "grazing": lambda: grazing(40, 7),
}


def render_with_grads(params, backend, width=W, height=H, background=BG, view=None):
    params = [p.detach().clone().requires_grad_(True) for p in params]
    view = torch.eye(4) if view is None else view
    out = rasterize_surfels(*params, view, intrinsics(width, height), width, height, background=background,
                            backend=backend)
    out.means2d.retain_grad()
    gen = torch.Generator().manual_seed(7)
    loss = sum((torch.rand(out[name].shape, generator=gen) * out[name]).sum() for name in IMAGES)
    loss.backward()
    return out, [p.grad for p in params] + [out.means2d.grad]


def assert_backends_agree(params, **kwargs):
    """numba vs the torch reference: images to 1e-4, gradients to 1e-3 of the largest reference entry."""
    ref, ref_grads = render_with_grads(params, "torch", **kwargs)
    out, grads = render_with_grads(params, "numba", **kwargs)
    assert torch.equal(ref.radii, out.radii)
    for name in (*IMAGES, "median_depth"):
        torch.testing.assert_close(out[name], ref[name], atol=1e-4, rtol=1e-4, msg=name)
    names = ("means", "quats", "scales", "opacities", "colors", "means2d")
    for name, g, g_ref in zip(names, grads, ref_grads, strict=True):
        scale = g_ref.abs().max().clamp(min=1e-6)
        assert (g - g_ref).abs().max() <= 1e-3 * scale, (name, (g - g_ref).abs().max(), scale)
    return ref


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_numba_matches_reference(scene):
    ref = assert_backends_agree(SCENES[scene]())
    assert ref.alpha.max() > 0.3  # the scene is actually visible
    assert ref.distortion.max() > 0 or scene == "tiny_splats"
    if scene == "large_opaque":
        assert ref.alpha.max() > 1 - 1e-3  # some pixels reached the 1e-4 transmittance stop


def test_moderate_scene_and_rotated_camera_match_reference():
    params = random_surfels(600, 9, scale=(0.005, 0.08), depth=(0.5, 6.0))
    c2w = torch.eye(4)
    skew = torch.tensor([[0.0, -0.1, 0.2], [0.1, 0.0, -0.3], [-0.2, 0.3, 0.0]])
    c2w[:3, :3] = torch.linalg.matrix_exp(skew)
    c2w[:3, 3] = torch.tensor([0.1, -0.2, -0.3])
    assert_backends_agree(params, width=64, height=48, background=torch.ones(3), view=torch.linalg.inv(c2w))


def test_screen_boxes_never_clip_a_contribution():
    """The reference evaluated densely (every surfel at every pixel) equals the tile-binned one."""
    means, quats, scales, opacities, colors = SCENES["grazing"]()
    args = (means, quats, scales, opacities, colors, torch.eye(4), intrinsics(W, H), BG, W, H)
    binned, dense = rasterize_surfels_torch(*args), rasterize_surfels_torch(*args, bin_tiles=False)
    for name in (*IMAGES, "median_depth"):
        torch.testing.assert_close(binned[name], dense[name], atol=1e-6, rtol=0, msg=name)


def test_reference_gradients_match_finite_differences():
    params = random_surfels(4, seed=1, scale=(0.2, 0.5), opacity=(0.2, 0.8), depth=(1.5, 3.0), spread=0.4,
                            dtype=torch.float64)
    params = tuple(p.clone().requires_grad_(True) for p in params)
    width, height = 16, 12
    K = intrinsics(width, height, dtype=torch.float64)
    background = torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64)

    def images(*p):
        out = rasterize_surfels(*p, torch.eye(4, dtype=torch.float64), K, width, height,
                                background=background, backend="torch")
        assert out.alpha.max() > 0.3 and out.distortion.max() > 0
        return tuple(out[name] for name in IMAGES)

    assert torch.autograd.gradcheck(images, params, eps=1e-6, atol=1e-5, rtol=1e-3, fast_mode=True)


def plane_scene(quat, opacity=0.9, scale=(0.8, 0.6), centre=(0.1, -0.05, 2.0)):
    return (torch.tensor([centre]), torch.tensor([quat]), torch.tensor([scale]), torch.tensor([opacity]),
            torch.tensor([[1.0, 0.5, 0.25]]))


def pixel_rays(width, height):
    """(H, W, 3) camera-space ray directions with z = 1 through the pixel centres."""
    K = intrinsics(width, height)
    i, j = torch.meshgrid(torch.arange(height) + 0.5, torch.arange(width) + 0.5, indexing="ij")
    return torch.stack([(j - K[0, 2]) / K[0, 0], (i - K[1, 2]) / K[1, 1], torch.ones_like(i)], dim=-1)


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_disc_facing_camera_renders_analytic_alpha_depth_normal(backend):
    params = plane_scene([1.0, 0.0, 0.0, 0.0])
    out = rasterize_surfels(*params, torch.eye(4), intrinsics(W, H), W, H, backend=backend)
    hit = 2.0 * pixel_rays(W, H)  # the plane z = 2
    u, v = (hit[..., 0] - 0.1) / 0.8, (hit[..., 1] + 0.05) / 0.6
    alpha = 0.9 * torch.exp(-0.5 * (u * u + v * v))
    alpha = torch.where(alpha >= 1 / 255, alpha, torch.zeros_like(alpha))
    torch.testing.assert_close(out.alpha, alpha, atol=2e-6, rtol=1e-5)
    torch.testing.assert_close(out.depth, 2.0 * alpha, atol=5e-6, rtol=1e-5)
    towards_camera, colour = torch.tensor([0.0, 0.0, -1.0]), torch.tensor([1.0, 0.5, 0.25])
    torch.testing.assert_close(out.normal, alpha[..., None] * towards_camera, atol=2e-6, rtol=0)
    torch.testing.assert_close(out.rgb, alpha[..., None] * colour, atol=2e-6, rtol=1e-5)
    assert out.distortion.abs().max() == 0  # a single surfel has no spread in depth
    assert (out.median_depth[alpha > 0.5] == 2.0).all() and (out.median_depth[alpha <= 0.5] == 0).all()


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_tilted_disc_depth_and_normal_follow_the_plane(backend):
    angle = math.radians(35.0)  # rotation about x: normal (0, -sin, cos), seen from the front
    params = plane_scene([math.cos(angle / 2), math.sin(angle / 2), 0.0, 0.0], scale=(0.8, 0.8))
    out = rasterize_surfels(*params, torch.eye(4), intrinsics(W, H), W, H, backend=backend)
    normal = torch.tensor([0.0, -math.sin(angle), math.cos(angle)])
    rays = pixel_rays(W, H)
    plane_z = (normal @ torch.tensor([0.1, -0.05, 2.0])) / (rays @ normal)  # ray-plane intersection depth
    seen = out.alpha > 0.05
    assert seen.sum() > 200
    torch.testing.assert_close((out.depth / out.alpha)[seen], plane_z[seen], atol=1e-5, rtol=1e-5)
    facing = (out.normal / out.alpha[..., None])[seen]
    torch.testing.assert_close(facing, (-normal).expand_as(facing), atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_two_parallel_discs_give_analytic_distortion(backend):
    z = (1.0, 2.5)
    params = [torch.cat(p) for p in zip(plane_scene([1.0, 0, 0, 0], 0.6, (50.0, 50.0), (0.0, 0.0, z[0])),
                                        plane_scene([1.0, 0, 0, 0], 0.7, (80.0, 80.0), (0.0, 0.0, z[1])),
                                        strict=True)]
    out = rasterize_surfels(*params, torch.eye(4), intrinsics(W, H), W, H, backend=backend)
    rays = pixel_rays(W, H)
    g1 = torch.exp(-0.5 * (z[0] / 50.0) ** 2 * (rays[..., :2] ** 2).sum(-1))
    g2 = torch.exp(-0.5 * (z[1] / 80.0) ** 2 * (rays[..., :2] ** 2).sum(-1))
    w1, w2 = 0.6 * g1, 0.7 * g2 * (1 - 0.6 * g1)
    torch.testing.assert_close(out.distortion, w1 * w2 * (z[0] - z[1]) ** 2, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(out.depth, w1 * z[0] + w2 * z[1], atol=1e-5, rtol=1e-5)


def test_edge_on_surfel_shows_only_the_low_pass():
    """The camera centre lies in the surfel's plane: every ray meets the plane at the camera, so only
    the screen-space low-pass exp(-|x - c|^2) around the projected centre is drawn, at the centre's depth."""
    params = plane_scene([math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0], centre=(0.0, 0.0, 2.0))
    ref = assert_backends_agree(params)
    i, j = torch.meshgrid(torch.arange(H) + 0.5, torch.arange(W) + 0.5, indexing="ij")
    low_pass = 0.9 * torch.exp(-((j - W / 2) ** 2 + (i - H / 2) ** 2))
    low_pass = torch.where(low_pass >= 1 / 255, low_pass, torch.zeros_like(low_pass))
    torch.testing.assert_close(ref.alpha.detach(), low_pass, atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(ref.depth.detach(), 2.0 * low_pass, atol=1e-6, rtol=1e-5)
    assert ref.radii.item() > 0


def test_culling_behind_through_near_plane_and_off_screen():
    means = torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.0, 0.3], [50.0, 0.0, 2.0], [0.0, 0.0, 0.005],
                          [0.0, 0.0, 2.0]])
    quats = torch.tensor([[1.0, 0, 0, 0], [0.9, 0.4, 0, 0], [1.0, 0, 0, 0], [1.0, 0, 0, 0], [1.0, 0, 0, 0]])
    scales = torch.tensor([[0.2, 0.2], [1.0, 1.0], [0.2, 0.2], [0.2, 0.2], [0.2, 0.2]])
    opacities = torch.tensor([0.9, 0.9, 0.9, 0.9, 0.003])  # the last one is below 1/255
    params = (means, quats, scales, opacities, torch.rand(5, 3, generator=torch.Generator().manual_seed(0)))
    for backend in ("numba", "torch"):
        out = rasterize_surfels(*params, torch.eye(4), intrinsics(W, H), W, H, background=BG, backend=backend)
        assert out.radii.tolist() == [0, 0, 0, 0, 0], backend  # tilted disc 2 reaches z < 0.01
        torch.testing.assert_close(out.rgb, BG.expand(H, W, 3))
    visible = (means[1:2], quats[1:2], torch.tensor([[0.1, 0.1]]), opacities[1:2], params[4][1:2])
    assert_backends_agree(visible)  # the same disc made small enough is drawn


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_empty_scene_renders_background(backend):
    empty = [torch.zeros(0, 3), torch.zeros(0, 4), torch.zeros(0, 2), torch.zeros(0), torch.zeros(0, 3)]
    out = rasterize_surfels(*empty, torch.eye(4), intrinsics(W, H), W, H, background=BG, backend=backend)
    assert isinstance(out, SurfelRenderOutput) and isinstance(out, RenderOutput)
    torch.testing.assert_close(out.rgb, BG.expand(H, W, 3))
    for name in ("depth", "alpha", "normal", "distortion", "median_depth"):
        assert out[name].abs().max() == 0, name


@pytest.mark.parametrize("which", range(5))
@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_non_finite_parameters_raise(which, bad):
    params = list(random_surfels(4, seed=0))
    params[which] = params[which].clone()
    params[which].view(-1)[0] = bad
    name = ["means", "quats", "scales", "opacities", "colors"][which]
    with pytest.raises(InvalidInputError, match=f"{name} contains NaN or inf"):
        rasterize_surfels(*params, torch.eye(4), intrinsics(W, H), W, H)


def test_wrong_shapes_and_backend_raise():
    params = list(random_surfels(4, seed=0))
    K = intrinsics(W, H)
    with pytest.raises(InvalidInputError, match="scales"):
        rasterize_surfels(params[0], params[1], torch.ones(4, 3), *params[3:], torch.eye(4), K, W, H)
    with pytest.raises(InvalidInputError, match="viewmat"):
        rasterize_surfels(*params, torch.eye(3), K, W, H)
    with pytest.raises(InvalidInputError, match="background"):
        rasterize_surfels(*params, torch.eye(4), K, W, H, background=torch.zeros(4))
    with pytest.raises(InvalidInputError, match="backend"):
        rasterize_surfels(*params, torch.eye(4), K, W, H, backend="gsplat")
    with pytest.raises(InvalidInputError, match="height"):
        rasterize_surfels(*params, torch.eye(4), K, W, 0)


def test_numba_accepts_float64_and_returns_matching_grad_dtype():
    params = [p.double().requires_grad_(True) for p in random_surfels(10, 10)]
    out = rasterize_surfels(*params, torch.eye(4, dtype=torch.float64), intrinsics(W, H), W, H)
    (out.rgb.sum() + out.distortion.sum() + out.normal.sum()).backward()
    assert out.rgb.dtype == torch.float32
    assert all(p.grad.dtype == torch.float64 and torch.isfinite(p.grad).all() for p in params)
