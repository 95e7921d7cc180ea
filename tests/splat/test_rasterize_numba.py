"""The numba rasterizer against the torch reference: outputs to 1e-4, gradients to 1e-3 relative."""

import numpy as np
import pytest
import torch
from raster_scenes import intrinsics, random_scene
from test_rasterize_torch import assert_top_down_pixels

from activesplat.errors import InvalidInputError
from activesplat.splat import rasterize
from activesplat.splat.raster import prepare_backend
from activesplat.splat.raster.numba_tiles import POWER_CAP, exp_neg

W, H = 40, 30  # partial tiles on the right and bottom edges
BG = torch.tensor([0.1, 0.2, 0.3])


def behind_and_off_screen(n, seed):
    means, quats, scales, opacities, colors = random_scene(n, seed, spread=2.0, depth=(-1.0, 4.0))
    means[: n // 4, 2] = torch.linspace(-2.0, 0.005, n // 4)  # behind the camera or inside near
    return means, quats, scales, opacities, colors


def equal_depths(n, seed):
    means, quats, scales, opacities, colors = random_scene(n, seed, opacity=(0.5, 0.95))
    means[:, 2] = torch.tensor([2.0, 3.0])[torch.arange(n) % 2]  # ties: the stable sort keeps index order
    return means, quats, scales, opacities, colors


SCENES = {
    "isotropic": lambda: random_scene(60, 1, iso=True),
    "anisotropic": lambda: random_scene(80, 2, scale=(0.01, 0.4)),
    "large_opaque": lambda: random_scene(40, 3, scale=(0.3, 1.5), opacity=(0.9, 1.0)),
    "behind_and_off_screen": lambda: behind_and_off_screen(80, 4),
    "equal_depths": lambda: equal_depths(30, 5),
    "tiny_splats": lambda: random_scene(200, 6, scale=(0.003, 0.02)),
}


def render_with_grads(params, backend, width=W, height=H, mask=None, background=BG, planar_depth=False):
    params = [p.detach().clone().requires_grad_(True) for p in params]
    out = rasterize(*params, torch.eye(4), intrinsics(width, height), width, height, backend=backend,
                    background=background, mask=mask, planar_depth=planar_depth)
    out.means2d.retain_grad()
    gen = torch.Generator().manual_seed(7)
    weights = [torch.rand(t.shape, generator=gen) for t in (out.rgb, out.depth, out.alpha)]
    loss = sum((w * t).sum() for w, t in zip(weights, (out.rgb, out.depth, out.alpha), strict=True))
    loss.backward()
    return out, [p.grad for p in params] + [out.means2d.grad]


def assert_backends_agree(params, ignore=(), **kwargs):
    """Compare numba with the torch reference; ``ignore`` names gradients that are exactly zero in
    theory (rotations of isotropic Gaussians), where both backends only return float noise."""
    ref, ref_grads = render_with_grads(params, "torch", **kwargs)
    out, grads = render_with_grads(params, "numba", **kwargs)
    assert torch.equal(ref.radii, out.radii)
    for name in ("rgb", "depth", "alpha", "median_depth"):
        torch.testing.assert_close(out[name], ref[name], atol=1e-4, rtol=1e-4, msg=name)
    names = ("means", "quats", "scales", "opacities", "colors", "means2d")
    for name, g, g_ref in zip(names, grads, ref_grads, strict=True):
        if name in ignore:
            continue
        scale = g_ref.abs().max().clamp(min=1e-6)
        assert (g - g_ref).abs().max() <= 1e-3 * scale, (name, (g - g_ref).abs().max(), scale)
    return ref


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_numba_matches_reference(scene):
    ref = assert_backends_agree(SCENES[scene](), ignore=("quats",) if scene == "isotropic" else ())
    assert ref.alpha.max() > 0.3  # the scene is actually visible


@pytest.mark.parametrize("scene", ["anisotropic", "behind_and_off_screen", "tiny_splats"])
def test_numba_matches_reference_with_planar_depth(scene):
    """Planar depth (depth varying over each footprint): outputs and every gradient, including the
    orientation's (it reaches the depth only through the slopes), as the torch reference."""
    ref = assert_backends_agree(SCENES[scene](), planar_depth=True)
    flat = rasterize(*SCENES[scene](), torch.eye(4), intrinsics(W, H), W, H, backend="torch", background=BG)
    assert (ref.depth - flat.depth).abs().max() > 1e-3  # the option changes the depth...
    torch.testing.assert_close(ref.rgb, flat.rgb)  # ...and nothing else
    torch.testing.assert_close(ref.alpha, flat.alpha)


def test_large_opaque_splats_terminate_early():
    ref = assert_backends_agree(SCENES["large_opaque"]())
    assert ref.alpha.max() > 1 - 1e-3  # some pixels reached the 1e-4 transmittance stop


def test_tiles_that_finish_before_their_list_ends():
    """Hundreds of large opaque splats: every pixel stops long before the end of its tile's list, so the
    forward pass's periodic check for live pixels ends the tiles early (the result must not change)."""
    means, quats, scales, opacities, colors = random_scene(300, 8, scale=(0.5, 1.5), opacity=(0.97, 1.0))
    ref = assert_backends_agree((means, quats, scales, opacities, colors))
    assert (ref.alpha > 0.999).float().mean() > 0.9  # nearly every pixel reached the transmittance stop


def test_rows_that_finish_while_their_tile_still_blends():
    """An opaque wall over the top rows of the image, Gaussians hidden behind it and others below it in
    the same tiles: the forward pass leaves out a run's finished rows, so the hidden Gaussians must
    change nothing, bit for bit, and the scene still matches the torch reference."""
    wall = list(random_scene(120, 9, scale=(0.15, 0.3), opacity=(0.99, 1.0)))
    gen = torch.Generator().manual_seed(9)
    wall[0] = torch.stack([torch.rand(120, generator=gen) * 2.4 - 1.2,
                           torch.rand(120, generator=gen) * 0.5 - 0.9, torch.full((120,), 1.0)], dim=1)
    hidden = list(random_scene(60, 10, scale=(0.01, 0.05)))
    hidden[0] = torch.stack([torch.rand(60, generator=gen) * 3 - 1.5,
                             torch.rand(60, generator=gen) * 0.6 - 1.8, torch.full((60,), 3.0)], dim=1)
    below = list(random_scene(60, 11, scale=(0.02, 0.1)))
    below[0][:, 1] = below[0][:, 2] * (0.1 + 0.6 * torch.rand(60, generator=gen))
    scene = [torch.cat(parts) for parts in zip(wall, below, hidden, strict=True)]
    ref = assert_backends_agree(scene)
    assert ref.alpha[3:8].amax() > 0.9998 and ref.alpha[14:16].amin() < 0.9  # tile row 0: both kinds of rows
    without, _ = render_with_grads([torch.cat(parts) for parts in zip(wall, below, strict=True)], "numba")
    out, grads = render_with_grads(scene, "numba")
    for name in ("rgb", "depth", "alpha", "median_depth"):
        assert torch.equal(out[name], without[name]), name
    assert (out.radii[-60:] > 0).any() and grads[3][-60:].abs().max() == 0  # hidden, rendered, no effect


def test_behind_camera_gaussians_are_culled():
    params = behind_and_off_screen(80, 4)
    ref = assert_backends_agree(params)
    assert (ref.radii[: 80 // 4] == 0).all()


def test_mask_renders_subset():
    params = random_scene(60, 8)
    mask = torch.arange(60) % 3 == 0
    out = assert_backends_agree(params, mask=mask)
    subset = render_with_grads([p[mask] for p in params], "numba")[0]
    torch.testing.assert_close(out.rgb, subset.rgb, atol=1e-6, rtol=0)
    assert (out.radii[~mask] == 0).all()


def test_moderate_scene_matches_reference():
    params = random_scene(2000, 9, scale=(0.005, 0.08), depth=(0.5, 6.0))
    assert_backends_agree(params, width=96, height=80, background=torch.tensor([1.0, 1.0, 1.0]))


def test_empty_scene_renders_background_numba():
    empty = [torch.zeros(0, 3), torch.zeros(0, 4), torch.zeros(0, 3), torch.zeros(0), torch.zeros(0, 3)]
    out = rasterize(*empty, torch.eye(4), intrinsics(W, H), W, H, backend="numba", background=BG)
    torch.testing.assert_close(out.rgb, BG.expand(H, W, 3))
    assert out.depth.abs().max() == 0 and out.alpha.abs().max() == 0


def test_numba_top_down_long_focal_length():
    assert_top_down_pixels("numba")


def test_numba_accepts_float64_and_returns_matching_grad_dtype():
    params = [p.double().requires_grad_(True) for p in random_scene(10, 10)]
    out = rasterize(*params, torch.eye(4), intrinsics(W, H), W, H, backend="numba")
    out.rgb.sum().backward()
    assert out.rgb.dtype == torch.float32
    assert all(p.grad.dtype == torch.float64 and torch.isfinite(p.grad).all() for p in params)


def test_vectorisable_exp_matches_numpy():
    """The compositing kernels' inline exp(-x) stays within 5e-6 relative of float64 exp on its range."""
    x = np.linspace(0.0, float(POWER_CAP), 20001, dtype=np.float32)
    got = np.array([exp_neg(v) for v in x[::7]], np.float64)
    ref = np.exp(-x[::7].astype(np.float64))
    assert np.max(np.abs(got - ref) / ref) < 5e-6
    assert exp_neg(np.float32(0.0)) == 1.0


def test_depth_order_is_the_stable_argsort_of_the_candidates():
    """The radix sort equals numpy's stable argsort: ties (a third of the depths repeat) keep the
    candidates' order, and depths over five decades sort as floats (their bit patterns)."""
    from activesplat.splat.raster import numba_tiles as tiles

    rng = np.random.default_rng(5)
    n = 50_000
    depths = (10.0 ** rng.uniform(-2, 3, n)).astype(np.float32)
    depths[rng.random(n) < 0.33] = np.float32(2.5)
    candidates = np.sort(rng.choice(n, 30_000, replace=False))
    order = tiles.stable_depth_order(candidates, depths)
    np.testing.assert_array_equal(order, candidates[np.argsort(depths[candidates], kind="stable")])
    assert tiles.stable_depth_order(candidates[:0], depths).shape == (0,)


def test_parallel_tile_lists_are_stable_and_match_the_binned_rows():
    """Enough Gaussians for several chunks: every tile lists its Gaussians in ``order`` order, and the
    fused binning writes each instance the row of the Gaussian the plain lists name."""
    from activesplat.splat.raster import numba_tiles as tiles

    rng = np.random.default_rng(3)
    n, grid_x, grid_y = 20_000, 7, 5
    x0, y0 = rng.integers(0, grid_x, n), rng.integers(0, grid_y, n)
    rects = np.stack([x0, np.minimum(x0 + rng.integers(1, 4, n), grid_x),
                      y0, np.minimum(y0 + rng.integers(1, 3, n), grid_y)], axis=1).astype(np.int32)
    order = rng.permutation(n)[: n - 100]
    tile_starts, ids, emit_start, slot = tiles.build_tile_lists(order, rects, grid_x, grid_x * grid_y)
    for t in (0, 13, grid_x * grid_y - 1):
        tx, ty = t % grid_x, t // grid_x
        inside = ((rects[order, 0] <= tx) & (tx < rects[order, 1]) & (rects[order, 2] <= ty)
                  & (ty < rects[order, 3]))
        np.testing.assert_array_equal(ids[tile_starts[t]:tile_starts[t + 1]], order[inside])
    np.testing.assert_array_equal(ids[slot], np.repeat(order, np.diff(emit_start)))
    shapes = ((n, 2), (n, 3), (n,), (n, 3), (n,), (n, 2))
    f32 = [rng.random(shape, dtype=np.float32) + 0.5 for shape in shapes]
    f32[1][:] = (1e-6, 0.0, 1e-6)  # alpha >= 1/255 boxes thousands of pixels wide: every rect tile kept
    starts2, feat, emit2, slot2 = tiles.bin_features(order, rects, grid_x, grid_x * grid_y, *f32)
    np.testing.assert_array_equal(starts2, tile_starts)
    np.testing.assert_array_equal(emit2, emit_start)
    np.testing.assert_array_equal(slot2, slot)
    np.testing.assert_array_equal(feat[:, tiles.MX], f32[0][ids, 0])
    np.testing.assert_array_equal(feat[:, tiles.CBL], f32[3][ids, 2])
    np.testing.assert_array_equal(feat[:, tiles.DZ], f32[4][ids])
    np.testing.assert_array_equal(feat[:, tiles.PV], f32[5][ids, 1])


def test_binning_leaves_out_the_tiles_the_alpha_box_misses():
    """A Gaussian's instances are the tiles of its 3-sigma rectangle that hold a pixel centre of its
    alpha >= 1/255 box: a thin or faint footprint gets fewer tiles than its rectangle."""
    from activesplat.splat.raster import numba_tiles as tiles

    grid_x, grid_y = 6, 6
    rects = np.array([[0, 6, 0, 6], [0, 6, 0, 6], [1, 3, 1, 3]], np.int32)
    means2d = np.array([[48.0, 48.0], [40.0, 48.0], [31.5, 31.5]], np.float32)
    # 0: wide and opaque (whole rectangle); 1: thin along x (sigma_x 0.5 px, sigma_y 10 px);
    # 2: centred on a tile corner, small: its box reaches the four tiles around the corner
    conics = np.array([[1e-4, 0.0, 1e-4], [4.0, 0.0, 0.01], [1.0, 0.0, 1.0]], np.float32)
    opacities = np.full(3, 0.99, np.float32)
    args = (means2d, conics, opacities, np.ones((3, 3), np.float32), np.ones(3, np.float32),
            np.zeros((3, 2), np.float32))
    starts, _feat, emit, slot = tiles.bin_features(np.arange(3), rects, grid_x, grid_x * grid_y, *args)
    # 1: columns 38-41 (x within 3.3 sigma), all in tile column 2; rows 15-80, tile rows 0-5
    assert np.diff(emit).tolist() == [36, 6, 4]
    tile_of = np.repeat(np.arange(grid_x * grid_y), np.diff(starts))
    assert (tile_of[slot[emit[1]:emit[2]]] % grid_x).tolist() == [2] * 6
    assert sorted(tile_of[slot[emit[2]:emit[3]]].tolist()) == [7, 8, 13, 14]


def test_binning_a_box_that_starts_far_past_the_grid():
    """A faint Gaussian far right of and below the image whose given rectangle still reaches the last tile:
    its alpha >= 1/255 box starts millions of tiles past the grid, so it gets no instance, and its tile
    counts stay inside the grid (no write far outside the kernel's arrays)."""
    from activesplat.splat.raster import numba_tiles as tiles

    grid_x, grid_y = 4, 3
    rects = np.array([[3, 4, 2, 3], [0, 2, 0, 1]], np.int32)
    means2d = np.array([[1e9, 1e9], [10.0, 8.0]], np.float32)
    args = (means2d, np.ones((2, 3), np.float32) * np.array([1, 0, 1], np.float32),
            np.full(2, 0.5, np.float32), np.ones((2, 3), np.float32), np.ones(2, np.float32),
            np.zeros((2, 2), np.float32))
    starts, feat, emit, slot = tiles.bin_features(np.arange(2), rects, grid_x, grid_x * grid_y, *args)
    assert np.diff(emit).tolist() == [0, 1]
    assert np.diff(starts).tolist() == [1] + [0] * (grid_x * grid_y - 1)
    assert slot.tolist() == [0] and feat[0, tiles.MX] == 10.0


@pytest.mark.parametrize("backend", ["numba", "torch"])
@pytest.mark.parametrize("planar", [False, True])
def test_prepare_backend_renders_a_tiny_image_and_reports_its_time(backend, planar):
    assert 0.0 <= prepare_backend(backend, planar_depth=planar) < 120.0
    with pytest.raises(InvalidInputError, match="unknown rasterizer backend"):
        prepare_backend("opengl")


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_gaussians_centred_outside_the_jacobian_clamp_follow_the_cull_depth(backend):
    """x/z = 1.5 lies beyond the clamp window (1.3 at a 90 deg view) and both such footprints reach the
    image: each is drawn (3DGS) unless RASTER.clamp_cull_depth lies beyond its depth (0.4 m, 2 m); the one
    at x/z = 1.2 is drawn whatever the depth."""
    from activesplat.splat.raster.constants import RASTER

    K = torch.tensor([[16.0, 0, 16], [0, 16, 16], [0, 0, 1]])
    means = torch.tensor([[0.6, 0.0, 0.4], [0.48, 0.0, 0.4], [3.0, 0.0, 2.0]])  # x/z = 1.5, 1.2, 1.5
    scales = torch.tensor([[0.1] * 3, [0.1] * 3, [0.5] * 3])
    n = len(means)
    quats = torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1)
    out = rasterize(means, quats, scales, torch.full((n,), 0.9), torch.ones(n, 3), torch.eye(4), K, 32, 32,
                    backend=backend)
    depth = RASTER.clamp_cull_depth
    assert (out.radii[0] == 0) == (depth > 0.4) and out.radii[1] > 0 and (out.radii[2] == 0) == (depth > 2.0)
    for x, z, s in ((0.6, 0.4, 0.1), (3.0, 2.0, 0.5)):  # 3-sigma footprints reaching into the 32 px image
        assert 16 * x / z + 16 - 3 * 16 * s / z < 32
