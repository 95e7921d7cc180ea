"""The map's render and its gradients have the same bits with one CPU thread or two (a run must not change
with the machine's core count). torch.sigmoid did not: ATen cuts an elementwise op over more than 32768
elements into one share per thread and computes each share's last few elements with a scalar formula."""

from __future__ import annotations

import pytest
import torch
from raster_scenes import intrinsics, random_scene

from activesplat.splat import rasterize
from activesplat.splat.gaussians import SIGMOID_BLOCK, activate, sigmoid


def logits(n: int) -> torch.Tensor:
    """n opacity logits; for n = 39001 and 100003 torch.sigmoid gives other bits with two threads than with
    one on an AVX-512 host (measured 2026-12-06)."""
    return torch.randn(n, generator=torch.Generator().manual_seed(n)) * 4


@pytest.mark.parametrize("n", [2 * SIGMOID_BLOCK, 2 * SIGMOID_BLOCK + 1, 39001, 3 * SIGMOID_BLOCK + 17,
                               100003])
def test_sigmoid_has_the_bits_of_one_thread_with_two(threads, n):
    x = logits(n)
    threads(1)
    leaf = x.clone().requires_grad_(True)
    expected = torch.sigmoid(leaf)
    expected.square().sum().backward()
    threads(2)
    leaf2 = x.clone().requires_grad_(True)
    got = sigmoid(leaf2)
    got.square().sum().backward()
    assert torch.equal(got, expected)
    assert torch.equal(leaf2.grad, leaf.grad)
    with torch.no_grad():
        assert torch.equal(sigmoid(x), expected)


def test_sigmoid_keeps_shape_and_handles_small_and_strided_input(threads):
    threads(2)
    x = torch.randn(50000, 2, generator=torch.Generator().manual_seed(0))
    assert torch.equal(sigmoid(x[:, 0]), torch.sigmoid(x[:, 0]))  # strided: torch.sigmoid itself
    assert torch.equal(sigmoid(x[:10, 0].contiguous()), torch.sigmoid(x[:10, 0]))
    assert sigmoid(x.contiguous()).shape == (50000, 2)


def test_render_and_gradients_do_not_depend_on_the_thread_count(threads):
    """Forward and backward of 39,001 Gaussians (more than ATen's 32768 grain) through ``activate``."""
    means, quats, scales, _, colors = random_scene(39001, seed=3, scale=(0.01, 0.08), depth=(1.0, 6.0))
    means[19490:19510] = torch.tensor([0.0, 0.0, 0.8]) + 0.02 * means[19490:19510]  # the end of the first
    scales[19490:19510] = 0.05  # thread's share of 39001 elements (19501), in front of the rest
    raw = {"means": means, "quats": quats, "log_scales": scales.log(), "opacity_logits": logits(39001),
           "f_dc": (colors - 0.5) / 0.28209479177387814}
    K = intrinsics(96, 80)

    def render(n: int) -> list[torch.Tensor]:
        threads(n)
        leaves = {k: v.clone().requires_grad_(True) for k, v in raw.items()}
        out = rasterize(*activate(leaves), torch.eye(4), K, 96, 80, backend="numba", planar_depth=True)
        (out.rgb.square().sum() + out.depth.sum() + out.alpha.sum()).backward()
        return [out.rgb, out.depth, out.alpha] + [leaves[k].grad for k in sorted(leaves)]

    one, two = render(1), render(2)
    for a, b in zip(one, two, strict=True):
        assert torch.equal(a, b)
