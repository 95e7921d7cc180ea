"""The GPU median-depth kernel against the numba backend's median depth, run on the CPU through Triton's
interpreter over tile lists built by gsplat's PyTorch reference functions. For machines without CUDA that
have triton and gsplat installed; skipped elsewhere (with CUDA, test_rasterize_gsplat compares the
compiled kernel)."""

import math
import os

import pytest
import torch
from raster_scenes import intrinsics, random_scene

from activesplat.splat import rasterize

if torch.cuda.is_available():  # there the compiled kernel is compared, in test_rasterize_gsplat
    pytest.skip("with CUDA the compiled kernel is tested in test_rasterize_gsplat", allow_module_level=True)
# Triton reads this when it is first imported: set before, and only on machines without CUDA, so that no
# compiled kernel of the same test session becomes an interpreted one
os.environ.setdefault("TRITON_INTERPRET", "1")
pytest.importorskip("triton", reason="triton is not installed")
pytest.importorskip("gsplat", reason="gsplat is not installed (pip install activesplat[cuda])")

from gsplat.cuda._torch_impl import (  # noqa: E402
    _fully_fused_projection,
    _isect_offset_encode,
    _isect_tiles,
    _quat_scale_to_covar_preci,
)

from activesplat.splat.raster.constants import RASTER  # noqa: E402
from activesplat.splat.raster.gsplat_backend import scalar_radii  # noqa: E402
from activesplat.splat.raster.median_triton import median_depth_from_meta  # noqa: E402
from activesplat.splat.raster.planar import depth_slopes  # noqa: E402

W, H = 40, 36  # not multiples of the 16-px tile: partial tiles on both axes


def gsplat_meta(means, quats, scales, opacities, viewmat, K, width, height) -> dict:
    """What ``gsplat.rasterization`` puts in its meta for one camera (packed=False), on the CPU."""
    covars, _ = _quat_scale_to_covar_preci(quats, scales, compute_preci=False)
    radii, means2d, depths, conics, _ = _fully_fused_projection(
        means, covars, viewmat[None], K[None], width, height, eps2d=RASTER.low_pass, near_plane=RASTER.near)
    tile = RASTER.tile_size
    tw, th = math.ceil(width / tile), math.ceil(height / tile)
    _, isect_ids, flatten_ids = _isect_tiles(means2d, radii, depths, tile, tw, th)
    return {"means2d": means2d, "conics": conics, "opacities": opacities[None], "depths": depths,
            "radii": radii, "isect_offsets": _isect_offset_encode(isect_ids, 1, tw, th),
            "flatten_ids": flatten_ids, "tile_width": tw, "tile_height": th, "tile_size": tile}


@pytest.mark.parametrize("planar", [False, True])
@pytest.mark.parametrize(("seed", "n", "opacity"), [(0, 200, (0.3, 0.98)), (1, 400, (0.3, 0.98)),
                                                    (2, 3000, (0.02, 0.3))])  # lists of many chunks
def test_median_kernel_matches_numba(seed, n, opacity, planar):
    params = random_scene(n, seed, scale=(0.03, 0.3), opacity=opacity)
    K = intrinsics(W, H)
    ref = rasterize(*params, torch.eye(4), K, W, H, backend="numba", planar_depth=planar).median_depth
    meta = gsplat_meta(*params[:4], torch.eye(4), K, W, H)
    if planar:  # what the gsplat adapter adds to the meta (gsplat_backend._render)
        meta["slopes"] = depth_slopes(*params[:3], torch.eye(4), K, scalar_radii(meta["radii"][0]))[None]
    got = median_depth_from_meta(meta, W, H)
    assert got.shape == (H, W)
    assert (ref > 0).float().mean() > 0.3  # the scene covers the image: the check means something
    same = torch.isclose(got, ref, atol=1e-5, rtol=0)
    assert same.float().mean() > 0.99, f"{int((~same).sum())} of {H * W} pixels differ"


def test_median_kernel_empty_lists_give_zero():
    far = [p[:0] for p in random_scene(5, 2)[:4]]
    got = median_depth_from_meta(gsplat_meta(*far, torch.eye(4), intrinsics(W, H), W, H), W, H)
    assert got.shape == (H, W) and got.abs().max() == 0
