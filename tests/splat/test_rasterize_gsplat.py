"""The gsplat (CUDA) adapter against the numba backend: images, median depth and the gradient of every
parameter on the same inputs. Skipped without CUDA or gsplat (the CPU suite never runs it; run it on a
GPU machine, see README "GPU")."""

import pytest
import torch
from raster_scenes import intrinsics, random_scene

from activesplat.splat import rasterize

gsplat = pytest.importorskip("gsplat", reason="gsplat is not installed (pip install activesplat[cuda])")
pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")

W, H = 96, 72
NAMES = ("means", "quats", "scales", "opacities", "colors")


def render_with_grads(params, backend, device, bg, planar_depth=False):
    leaves = [p.detach().clone().to(device).requires_grad_(True) for p in params]
    out = rasterize(*leaves, torch.eye(4, device=device), intrinsics(W, H).to(device), W, H, backend=backend,
                    background=bg.to(device), planar_depth=planar_depth)
    out.means2d.retain_grad()
    # a loss that weighs every output channel differently, so each gradient term is exercised
    g = torch.Generator().manual_seed(7)
    w_rgb = torch.rand(H, W, 3, generator=g).to(device)
    w_d, w_a = torch.rand(H, W, generator=g).to(device), torch.rand(H, W, generator=g).to(device)
    ((out.rgb * w_rgb).sum() + (out.depth * w_d).sum() + (out.alpha * w_a).sum()).backward()
    grads = {n: p.grad.cpu() for n, p in zip(NAMES, leaves, strict=True)}
    grads["means2d"] = out.means2d.grad.cpu()
    return out, grads


def rel_err(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a - b).norm() / b.norm().clamp_min(1e-12))


@pytest.mark.parametrize("planar_depth", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gsplat_matches_numba(seed, planar_depth):
    """With ``planar_depth`` the gsplat adapter blends three depth features and its Triton median kernel
    reads the slopes (splat/raster/planar.py); both written without a GPU at hand, this is their check."""
    # opacities below 0.99 so the backends' different alpha clamps (0.99 / 0.999) never apply
    params = random_scene(300, seed, scale=(0.02, 0.2), opacity=(0.05, 0.9))
    bg = torch.tensor([0.1, 0.2, 0.3])
    ref, ref_grads = render_with_grads(params, "numba", "cpu", bg, planar_depth)
    out, grads = render_with_grads(params, "gsplat", "cuda", bg, planar_depth)
    report = {name: float((out[name].detach().cpu() - ref[name]).abs().max())
              for name in ("rgb", "depth", "alpha")}
    same = torch.isclose(out.median_depth.cpu(), ref.median_depth, atol=1e-4, rtol=0)
    report["median_equal"] = float(same.float().mean())
    for name, g in grads.items():
        report[f"d_{name}"] = rel_err(g, ref_grads[name])
    print(f"\nseed {seed}, planar {planar_depth}: " + ", ".join(f"{k} {v:.2e}" for k, v in report.items()))
    for name in ("rgb", "depth", "alpha"):
        torch.testing.assert_close(out[name].detach().cpu(), ref[name], atol=5e-3, rtol=1e-3, msg=name)
    assert report["median_equal"] > 0.99
    for name in grads:
        assert report[f"d_{name}"] < 1e-2, f"gradient of {name}: relative error {report[f'd_{name}']:.2e}"


def test_gsplat_cpu_inputs_come_back_on_the_cpu():
    params = random_scene(50, 4)
    out = rasterize(*params, torch.eye(4), intrinsics(W, H), W, H, backend="gsplat")
    ref = rasterize(*params, torch.eye(4), intrinsics(W, H), W, H, backend="numba")
    assert out.rgb.device.type == "cpu"
    torch.testing.assert_close(out.alpha, ref.alpha, atol=2e-3, rtol=1e-3)


def test_gsplat_mask_and_empty():
    params = random_scene(50, 3)
    mask = torch.arange(50) % 2 == 0
    cuda = [p.cuda() for p in params]
    out = rasterize(*cuda, torch.eye(4).cuda(), intrinsics(W, H).cuda(), W, H, backend="gsplat",
                    mask=mask.cuda())
    sub = rasterize(*[p[mask] for p in params], torch.eye(4), intrinsics(W, H), W, H, backend="numba")
    assert (out.radii[~mask.cuda()] == 0).all()
    torch.testing.assert_close(out.rgb.cpu(), sub.rgb, atol=2e-3, rtol=1e-3)
    empty = [torch.zeros(0, 3), torch.zeros(0, 4), torch.zeros(0, 3), torch.zeros(0), torch.zeros(0, 3)]
    out = rasterize(*[e.cuda() for e in empty], torch.eye(4).cuda(), intrinsics(W, H).cuda(), W, H,
                    backend="gsplat")
    assert out.alpha.abs().max() == 0


def test_prepare_backend_loads_the_cuda_extension():
    from activesplat.splat.raster import prepare_backend

    assert 0.0 <= prepare_backend("gsplat", planar_depth=True) < 600.0
