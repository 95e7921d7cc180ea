"""The gsplat (CUDA) adapter against the numba backend; skipped without CUDA or gsplat."""

import pytest
import torch
from raster_scenes import intrinsics, random_scene

from activesplat.splat import rasterize

gsplat = pytest.importorskip("gsplat", reason="gsplat is not installed (pip install activesplat[cuda])")
pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")

W, H = 64, 48


@pytest.mark.parametrize("seed", [0, 1])
def test_gsplat_matches_numba(seed):
    # opacities below 0.99 / 0.999 so the backends' different alpha clamps never apply
    params = random_scene(200, seed, scale=(0.02, 0.2), opacity=(0.05, 0.9))
    bg = torch.tensor([0.1, 0.2, 0.3])
    K = intrinsics(W, H)
    ref = rasterize(*params, torch.eye(4), K, W, H, backend="numba", background=bg)
    leaves = [p.cuda().requires_grad_(True) for p in params]
    out = rasterize(*leaves, torch.eye(4).cuda(), K.cuda(), W, H, backend="gsplat", background=bg.cuda())
    for name in ("rgb", "depth", "alpha"):
        torch.testing.assert_close(out[name].cpu(), ref[name], atol=2e-3, rtol=1e-3, msg=name)
    torch.testing.assert_close(out.median_depth.cpu(), ref.median_depth)
    (out.rgb.sum() + out.depth.sum()).backward()
    assert all(torch.isfinite(p.grad).all() for p in leaves)


def test_gsplat_mask_and_empty():
    params = random_scene(50, 3)
    mask = torch.arange(50) % 2 == 0
    cuda = [p.cuda() for p in params]
    out = rasterize(*cuda, torch.eye(4).cuda(), intrinsics(W, H).cuda(), W, H, backend="gsplat",
                    mask=mask.cuda())
    assert (out.radii[~mask.cuda()] == 0).all()
    empty = [torch.zeros(0, 3), torch.zeros(0, 4), torch.zeros(0, 3), torch.zeros(0), torch.zeros(0, 3)]
    out = rasterize(*[e.cuda() for e in empty], torch.eye(4).cuda(), intrinsics(W, H).cuda(), W, H,
                    backend="gsplat")
    assert out.alpha.abs().max() == 0
