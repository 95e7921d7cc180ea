"""Adaptive density control on constructed cases: clone, split, prune, opacity reset, the Gaussian cap,
and the view-space gradient it accumulates (from the rasterizer, and by the chain rule)."""

import math

import pytest
import torch

from activesplat.refine.adc import (
    DensityControl,
    clone,
    ndc_grad_norm,
    prune,
    reset_opacity,
    scene_extent,
    split,
)
from activesplat.refine.config import RefineConfig
from activesplat.splat import GaussianMap, rasterize
from activesplat.splat.config import LearningRates

EXTENT = 5.0  # percent_dense 0.01 -> clone below 5 cm, split above


def _map(scales, opacities=None) -> GaussianMap:
    n = len(scales)
    points = torch.stack([torch.linspace(-0.5, 0.5, n), torch.zeros(n), torch.full((n,), 2.0)], dim=1)
    gmap = GaussianMap.from_points(points, torch.full((n, 3), 0.5), torch.tensor(scales, dtype=torch.float32),
                                   opacity=0.5)
    if opacities is not None:
        with torch.no_grad():
            gmap.params["opacity_logits"].copy_(torch.logit(torch.tensor(opacities)))
    return gmap


def _optimizer_with_state(gmap: GaussianMap) -> torch.optim.Adam:
    opt = gmap.make_optimizer(LearningRates(), 1e-15)
    loss = sum(p.square().sum() for p in gmap.params.values())
    loss.backward()
    opt.step()
    return opt


def _control(gmap: GaussianMap, grads, **overrides) -> DensityControl:
    cfg = RefineConfig(**overrides)
    adc = DensityControl(cfg, EXTENT, len(gmap))
    adc.accumulate(torch.tensor(grads, dtype=torch.float32), torch.ones(len(gmap), dtype=torch.bool))
    return adc


def test_small_gaussian_with_large_gradient_is_cloned():
    gmap = _map([0.01, 0.01, 0.01])
    opt = _optimizer_with_state(gmap)
    before = gmap.raw()
    adc = _control(gmap, [1e-3, 1e-5, 1e-3])
    stats = adc.densify_and_prune(gmap, opt, torch.Generator().manual_seed(0), prune_big=False)
    assert (stats.cloned, stats.split, stats.pruned) == (2, 0, 0)
    assert len(gmap) == 5
    for name, t in gmap.params.items():  # originals untouched, copies appended in order
        assert torch.equal(t.detach()[:3], before[name])
        assert torch.equal(t.detach()[3:], before[name][[0, 2]])
    state = opt.state[gmap.params["means"]]
    assert state["exp_avg"].shape == (5, 3) and torch.all(state["exp_avg"][3:] == 0)
    assert torch.all(adc.grad_accum == 0) and adc.grad_accum.shape == (5,)  # statistics restart


def test_large_gaussian_with_large_gradient_is_split():
    gmap = _map([0.2, 0.01])
    with torch.no_grad():
        gmap.params["log_scales"][0] = torch.log(torch.tensor([0.3, 0.1, 0.02]))
        gmap.params["quats"][0] = torch.tensor([math.cos(0.3), 0.0, math.sin(0.3), 0.0])
    opt = _optimizer_with_state(gmap)
    parent = {k: v[0] for k, v in gmap.raw().items()}
    adc = _control(gmap, [1e-3, 1e-5])
    stats = adc.densify_and_prune(gmap, opt, torch.Generator().manual_seed(0), prune_big=False)
    assert (stats.cloned, stats.split, stats.pruned) == (0, 1, 0)
    assert len(gmap) == 3  # the small one + two children, the parent removed
    children = {k: v.detach()[1:] for k, v in gmap.params.items()}
    assert torch.allclose(children["log_scales"], (parent["log_scales"] - math.log(1.6)).expand(2, 3))
    assert torch.equal(children["quats"], parent["quats"].expand(2, 4))
    assert torch.equal(children["f_dc"], parent["f_dc"].expand(2, 3))
    # children are drawn from the parent's Gaussian: within 4 sigma along each of its own axes
    from activesplat.splat.kernels import quat_to_rotmat

    rot = quat_to_rotmat(parent["quats"][None])[0]
    local = (children["means"] - parent["means"]) @ rot  # coordinates in the parent's frame
    assert torch.all(local.abs() < 4 * torch.exp(parent["log_scales"]))
    assert not torch.equal(children["means"][0], children["means"][1])


def test_prune_transparent_always_and_oversized_only_after_reset():
    gmap = _map([0.01, 0.01, 0.8], opacities=[0.001, 0.5, 0.5])  # 0.8 m > 0.1 x extent = 0.5 m
    adc = _control(gmap, [0.0, 0.0, 0.0])
    assert adc.densify_and_prune(gmap, None, torch.Generator(), prune_big=False).pruned == 1
    assert len(gmap) == 2
    adc = _control(gmap, [0.0, 0.0])
    assert adc.densify_and_prune(gmap, None, torch.Generator(), prune_big=True).pruned == 1
    assert len(gmap) == 1 and float(gmap.scales.detach().max()) == pytest.approx(0.01)


def test_opacity_reset_caps_opacity_and_clears_adam_moments():
    gmap = _map([0.01, 0.01], opacities=[0.9, 0.004])
    opt = _optimizer_with_state(gmap)
    before = gmap.opacities.detach().clone()
    assert before[0] > 0.5 and before[1] < 0.01
    reset_opacity(gmap, opt, 0.01)
    assert torch.allclose(gmap.opacities.detach(), torch.tensor([0.01, float(before[1])]), atol=1e-6)
    state = opt.state[gmap.params["opacity_logits"]]
    assert torch.all(state["exp_avg"] == 0) and torch.all(state["exp_avg_sq"] == 0)
    assert torch.any(opt.state[gmap.params["means"]]["exp_avg"] != 0)  # the others keep their moments


def test_gaussian_cap_keeps_the_largest_gradients():
    gmap = _map([0.01, 0.01, 0.01, 0.2])
    adc = _control(gmap, [1e-3, 5e-3, 2e-3, 1e-3], max_gaussians=6)  # room for 2 more
    stats = adc.densify_and_prune(gmap, None, torch.Generator().manual_seed(0), prune_big=False)
    # by gradient: #1 clone (cost 1), #2 clone (cost 1), then #0 and the split of #3 do not fit
    assert (stats.cloned, stats.split) == (2, 0) and len(gmap) == 6


def test_operations_alone():
    gmap = _map([0.01, 0.2])
    assert clone(gmap, None, torch.tensor([True, False])) == 1 and len(gmap) == 3
    assert split(gmap, None, torch.tensor([False, True, False]), 3, 2.4, torch.Generator()) == 1
    assert len(gmap) == 5
    assert prune(gmap, None, torch.tensor([True, False, False, False, False])) == 1 and len(gmap) == 4


def test_statistic_is_mean_over_views_where_visible():
    gmap = _map([0.01, 0.01])
    adc = DensityControl(RefineConfig(), EXTENT, 2)
    adc.accumulate(torch.tensor([3e-4, 1.0]), torch.tensor([True, False]))
    adc.accumulate(torch.tensor([1e-4, 1.0]), torch.tensor([True, False]))
    assert torch.allclose(adc.mean_grads(), torch.tensor([2e-4, 0.0]))
    assert len(gmap) == 2


def test_scene_extent_is_3dgs_camera_radius():
    centres = torch.tensor([[0.0, 0, 0], [2.0, 0, 0], [1.0, 0, 1.0]])
    mean = centres.mean(dim=0)
    assert scene_extent(centres, 1.1) == pytest.approx(1.1 * float((centres - mean).norm(dim=1).max()))


def _scene(n=20, seed=0):
    gen = torch.Generator().manual_seed(seed)
    means = torch.cat([torch.rand(n, 2, generator=gen) - 0.5, 2 + torch.rand(n, 1, generator=gen)], dim=1)
    return [means.requires_grad_(True), torch.randn(n, 4, generator=gen), torch.full((n, 3), 0.08),
            torch.full((n,), 0.7), torch.rand(n, 3, generator=gen)]


def test_rasterizer_gives_view_space_gradient_in_pixels():
    params = _scene()
    K = torch.tensor([[16.0, 0, 16], [0, 16, 16], [0, 0, 1]])
    out = rasterize(*params, torch.eye(4), K, 32, 32, backend="numba")
    out.means2d.retain_grad()
    out.rgb.sum().backward()
    grad = out.means2d.grad
    assert grad is not None and grad.shape == (20, 2)
    visible = out.radii > 0
    assert bool(visible.any()) and torch.all(grad[~visible] == 0) and torch.any(grad[visible] != 0)
    ndc = ndc_grad_norm(grad, 32, 48)
    assert torch.allclose(ndc, (grad * torch.tensor([16.0, 24.0])).norm(dim=1))

