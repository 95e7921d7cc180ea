"""The torch reference rasterizer: finite differences, edge cases, validation, long focal length."""

import pytest
import torch
from raster_scenes import intrinsics, look_down_viewmat, random_scene

from activesplat.errors import InvalidInputError
from activesplat.splat import RenderOutput, rasterize

W, H = 24, 20


def _render(params, backend="torch", **kwargs):
    means = params[0]
    K = intrinsics(W, H, dtype=means.dtype)
    view = torch.eye(4, dtype=means.dtype)
    return rasterize(*params, view, K, W, H, backend=backend, **kwargs)


def test_reference_gradients_match_finite_differences():
    params = random_scene(6, seed=1, scale=(0.2, 0.5), opacity=(0.2, 0.8), dtype=torch.float64)
    params = tuple(p.clone().requires_grad_(True) for p in params)
    background = torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64)

    def images(*p):
        out = _render(p, background=background)
        return out.rgb, out.depth, out.alpha

    assert torch.autograd.gradcheck(images, params, eps=1e-6, atol=1e-5, rtol=1e-3, fast_mode=True)


def test_reference_matches_hand_computed_single_gaussian():
    means = torch.tensor([[0.0, 0.0, 2.0]])
    quats = torch.tensor([[1.0, 0, 0, 0]])
    scales = torch.full((1, 3), 0.1)
    out = _render((means, quats, scales, torch.tensor([0.5]), torch.tensor([[1.0, 0.5, 0.0]])))
    f = W / 2  # 90 deg hfov
    var = (f * 0.1 / 2.0) ** 2 + 0.3
    i, j = torch.meshgrid(torch.arange(H) + 0.5, torch.arange(W) + 0.5, indexing="ij")
    g = 0.5 * torch.exp(-0.5 * ((j - W / 2) ** 2 + (i - H / 2) ** 2) / var)
    g = torch.where(g >= 1 / 255, g, torch.zeros_like(g))
    torch.testing.assert_close(out.alpha, g, atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(out.depth, 2.0 * g, atol=1e-6, rtol=1e-5)
    torch.testing.assert_close(out.rgb[..., 1], 0.5 * g, atol=1e-6, rtol=1e-5)
    assert out.median_depth.max() == 0  # T never drops below 0.5 with o = 0.5
    assert out.radii.tolist() == [int(torch.ceil(3 * torch.sqrt(torch.tensor(var))))]


def test_opaque_layers_stop_early_and_set_median_depth():
    means = torch.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, 2.0], [0.0, 0.0, 3.0], [0.0, 0.0, 4.0]])
    scales = torch.full((4, 3), 5.0)  # cover the whole image with ~constant alpha
    colors = torch.tensor([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
    quats = torch.tensor([[1.0, 0, 0, 0]]).repeat(4, 1)
    out = _render((means, quats, scales, torch.full((4,), 0.95), colors))
    centre = (H // 2, W // 2)
    # alpha = 0.95: T = 1 -> 0.05 -> 2.5e-3 -> 1.25e-4; the fourth would give 6e-6 < 1e-4: stop.
    assert out.median_depth[centre] == pytest.approx(1.0)
    assert out.alpha[centre] == pytest.approx(1 - 1.25e-4, abs=1e-5)
    torch.testing.assert_close(out.rgb[centre], torch.tensor([0.95, 0.05 * 0.95, 0.0025 * 0.95]),
                               atol=3e-5, rtol=2e-3)
    torch.testing.assert_close(out.depth[centre], torch.tensor(0.95 + 2 * 0.05 * 0.95 + 3 * 0.0025 * 0.95),
                               atol=3e-5, rtol=2e-3)


def test_empty_scene_renders_background():
    empty = (torch.zeros(0, 3), torch.zeros(0, 4), torch.zeros(0, 3), torch.zeros(0), torch.zeros(0, 3))
    bg = torch.tensor([0.2, 0.4, 0.6])
    out = _render(empty, background=bg)
    assert isinstance(out, RenderOutput)
    torch.testing.assert_close(out.rgb, bg.expand(H, W, 3))
    assert out.depth.abs().max() == 0 and out.alpha.abs().max() == 0 and out.median_depth.abs().max() == 0


@pytest.mark.parametrize("which", range(5))
@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_non_finite_parameters_raise(which, bad):
    params = list(random_scene(4, seed=0))
    params[which] = params[which].clone()
    params[which].view(-1)[0] = bad
    name = ["means", "quats", "scales", "opacities", "colors"][which]
    with pytest.raises(InvalidInputError, match=name):
        _render(tuple(params))


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_values_outside_the_documented_ranges_raise(backend):
    """Opacities in [0, 1], scales >= 0, quaternions that can be normalised, positive focal lengths: what
    would otherwise render silently wrong (nothing, mirrored, or every Gaussian gone)."""
    params = list(random_scene(4, seed=0))

    def with_value(which, value):
        changed = list(params)
        changed[which] = changed[which].clone()
        changed[which][0] = value
        return tuple(changed)

    for which, value, msg in [(3, 1.5, "opacities must be in"), (3, -0.5, "opacities must be in"),
                              (2, -0.01, "scales must be >= 0"), (1, 0.0, "quats must have a non-zero")]:
        with pytest.raises(InvalidInputError, match=msg):
            _render(with_value(which, value), backend=backend)
    K = intrinsics(W, H).clone()
    K[0, 0] = 0.0
    with pytest.raises(InvalidInputError, match="positive focal lengths"):
        rasterize(*params, torch.eye(4), K, W, H, backend=backend)


def test_wrong_shapes_and_backend_raise():
    params = list(random_scene(4, seed=0))
    with pytest.raises(InvalidInputError, match="scales"):
        _render((params[0], params[1], params[2][:, :2], params[3], params[4]))
    with pytest.raises(InvalidInputError, match="mask"):
        _render(tuple(params), mask=torch.ones(3, dtype=torch.bool))
    with pytest.raises(InvalidInputError, match="backend"):
        _render(tuple(params), backend="opengl")
    with pytest.raises(InvalidInputError, match="viewmat"):
        rasterize(*params, torch.eye(3), intrinsics(W, H), W, H, backend="torch")
    with pytest.raises(InvalidInputError, match="width"):
        rasterize(*params, torch.eye(4), intrinsics(W, H), 0, H, backend="torch")


def top_down_layout():
    """Five 1 cm splats on the floor seen from 1000 m above with fx = 1e5 (the workspace view)."""
    width = height = 360
    fx = 1.0e5
    K = torch.tensor([[fx, 0, width / 2], [0, fx, height / 2], [0, 0, 1]])
    centre = (3.0, -2.0)
    floor_xz = torch.tensor([[3.0, -2.0], [4.2, -2.0], [3.0, -0.9], [1.5, -3.1], [4.5, -0.5]])
    n = len(floor_xz)
    means = torch.stack([floor_xz[:, 0], torch.full((n,), 0.05), floor_xz[:, 1]], dim=1)
    params = (means, torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1), torch.full((n, 3), 0.01),
              torch.full((n,), 0.9), torch.rand(n, 3, generator=torch.Generator().manual_seed(0)))
    expected_uv = (floor_xz - torch.tensor(centre)) * fx / (1000.0 - 0.05) + width / 2
    return params, look_down_viewmat(1000.0, centre), K, width, height, expected_uv


def assert_top_down_pixels(backend: str):
    params, view, K, width, height, expected_uv = top_down_layout()
    out = rasterize(*params, view, K, width, height, backend=backend)
    alpha = out.alpha.detach().cpu().double()
    centres = torch.arange(width, dtype=torch.float64) + 0.5
    seen = torch.zeros_like(alpha, dtype=torch.bool)
    for u, v in expected_uv.tolist():
        j, i = int(u), int(v)
        win = alpha[i - 5:i + 6, j - 5:j + 6]
        seen[i - 5:i + 6, j - 5:j + 6] = True
        mass = win.sum()
        assert (win * centres[j - 5:j + 6]).sum() / mass == pytest.approx(u, abs=0.05)
        assert (win * centres[i - 5:i + 6, None]).sum() / mass == pytest.approx(v, abs=0.05)
        assert win.max() > 0.5
        peak = torch.nonzero(win == win.max())[0]
        assert out.median_depth[i - 5 + peak[0], j - 5 + peak[1]] == pytest.approx(1000.0 - 0.05, abs=1e-3)
    assert alpha[~seen].abs().max() == 0
    assert (out.radii > 0).all()


def test_top_down_long_focal_length_puts_splats_at_expected_pixels():
    assert_top_down_pixels("torch")
