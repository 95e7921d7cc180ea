"""The coarser map of the scoring panoramas (splat/lod.py): moments kept per voxel, lone Gaussians kept as
they are, a covered surface still covered."""

import numpy as np
import pytest
import torch
from _synthetic import intrinsics, pose

from activesplat.errors import InvalidInputError
from activesplat.planning.config import PanoramaConfig
from activesplat.planning.explorer import snapshot_render
from activesplat.splat import GaussianMap, Mapper, MapperConfig
from activesplat.splat.gaussians import activate
from activesplat.splat.kernels import quat_to_rotmat
from activesplat.splat.lod import voxel_lod

S = 32


def _wall(spacing: float, radius: float, z: float = 2.0, half: float = 1.5) -> dict[str, torch.Tensor]:
    g = np.arange(-half, half + 1e-9, spacing)
    x, y = np.meshgrid(g, g)
    pts = torch.tensor(np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], 1), dtype=torch.float32)
    rgb = 0.5 + 0.3 * torch.sin(pts[:, :1] * 4.0).expand(-1, 3)
    return GaussianMap.raw_from_points(pts, rgb, torch.full((len(pts),), radius), 0.9)


def _cov(raw):
    _, q, s, _, _ = activate(raw)
    r = quat_to_rotmat(q).double()
    return r @ torch.diag_embed(s.double() ** 2) @ r.transpose(1, 2)


def test_a_voxel_becomes_one_gaussian_with_its_moments():
    gen = torch.Generator().manual_seed(0)
    n = 12
    pts = 0.10 + 0.08 * torch.rand(n, 3, generator=gen)  # all in the voxel [0, 0.2)^3
    raw = GaussianMap.raw_from_points(pts, torch.rand(n, 3, generator=gen),
                                      0.005 + 0.01 * torch.rand(n, generator=gen), 0.6)
    raw["quats"] = torch.randn(n, 4, generator=gen)
    lone = GaussianMap.raw_from_points(torch.tensor([[1.1, 0.1, 0.1]]), torch.tensor([[0.2, 0.4, 0.6]]),
                                       torch.tensor([0.02]), 0.7)
    both = {k: torch.cat([raw[k], lone[k]]) for k in raw}
    out = voxel_lod(both, 0.2, inflate=1.0)
    assert len(out["means"]) == 2
    far = int(torch.argmax(out["means"][:, 0]))
    for k in lone:  # the lone Gaussian is kept bit for bit
        assert torch.equal(out[k][far], lone[k][0])
    m, _, s, o, c = activate(raw)
    cov = _cov(raw)
    w = (o.double() * torch.sqrt((s[:, 0] * s[:, 1]) ** 2 + (s[:, 1] * s[:, 2]) ** 2
                                 + (s[:, 0] * s[:, 2]) ** 2).double())
    mean = (w[:, None] * m.double()).sum(0) / w.sum()
    d = m.double() - mean
    want = ((w[:, None, None] * (cov + d[:, :, None] * d[:, None, :])).sum(0) / w.sum())
    merged = {k: v[1 - far:2 - far] for k, v in out.items()}
    got_m, _, _, got_o, got_c = activate(merged)
    assert torch.allclose(got_m[0].double(), mean, atol=1e-6)
    assert torch.allclose(_cov(merged)[0], want, rtol=1e-4, atol=1e-9)
    assert abs(float(got_o[0]) - (1 - 0.4 ** n)) < 1e-3 or float(got_o[0]) > 0.998
    assert torch.allclose(got_c[0].double(), (w[:, None] * c.double()).sum(0) / w.sum(), atol=1e-5)


def test_a_covered_wall_stays_covered_with_fewer_gaussians():
    mapper = Mapper(intrinsics(S), S, S, MapperConfig(), backend="numba")
    mapper.gaussians = GaussianMap(_wall(0.01, 0.008, z=1.0, half=1.2))  # fills the 90 deg view
    full = mapper.snapshot()(pose())
    coarse_snapshot = mapper.snapshot(lod_voxel_m=0.05)
    coarse = coarse_snapshot(pose())
    assert len(coarse_snapshot._params["means"]) * 20 < len(mapper.gaussians)
    assert full.alpha.min() > 0.99
    assert coarse.alpha.min() > 0.95  # no gaps between the merged voxels
    assert (coarse.median_depth - full.median_depth).abs().max() < 0.05
    # 0.5 m away a voxel spans 1.6 pixels: gaps open, but no pixel becomes low-visibility (1 - alpha > 0.3,
    # `RotationCandidateConfig.invisibility_threshold`)
    mapper.gaussians = GaussianMap(_wall(0.005, 0.004, z=0.5, half=0.6))
    assert mapper.snapshot(lod_voxel_m=0.05)(pose()).alpha.min() > 0.8
    mapper.gaussians = GaussianMap(_wall(0.01, 0.008, z=1.0, half=1.2))
    assert torch.equal(snapshot_render(mapper)(pose()).alpha, full.alpha)
    assert torch.equal(snapshot_render(mapper, 0.05)(pose()).alpha, coarse.alpha)


def test_an_empty_map_and_bad_options():
    empty = voxel_lod(GaussianMap.empty().raw(), 0.05)
    assert all(len(t) == 0 for t in empty.values())
    for bad in ({"score_lod_voxel_m": 0.0}, {"score_lod_inflate": -1.0}):
        with pytest.raises(InvalidInputError, match=f"PanoramaConfig.{next(iter(bad))}"):
            PanoramaConfig(**bad)
    assert PanoramaConfig(score_lod_voxel_m=None).score_lod_voxel_m is None
