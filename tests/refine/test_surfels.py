"""The 2dgs refinement: surfels from 3D Gaussians, depth normals, the regularisers, and a short run."""

import math
import shutil

import numpy as np
import pytest
import torch
from _refine_scene import make_episode

from activesplat.refine import RefineConfig, Refiner, refine
from activesplat.refine.surfels import (
    depth_normals,
    frame_from_normal,
    normal_error,
    rotmat_to_quat,
    surfel_raw_from_gaussians,
)
from activesplat.splat import GaussianMap, load_ply
from activesplat.splat.kernels import quat_to_rotmat


def _random_quats(n, seed=0):
    q = torch.randn(n, 4, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
    return q / q.norm(dim=1, keepdim=True)


def test_rotmat_to_quat_inverts_quat_to_rotmat():
    q = torch.cat([_random_quats(200), torch.tensor([[0.0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1],
                                                     [1e-4, 0.7071, 0.7071, 0]], dtype=torch.float64)])
    rot = quat_to_rotmat(q)
    back = rotmat_to_quat(rot)
    assert torch.allclose(quat_to_rotmat(back), rot, atol=1e-9)
    assert torch.allclose(back.norm(dim=1), torch.ones(len(q), dtype=torch.float64))


def test_surfel_spans_the_two_largest_axes_and_its_normal_is_the_smallest():
    n = 50
    gen = torch.Generator().manual_seed(1)
    raw = {
        "means": torch.randn(n, 3, generator=gen), "quats": _random_quats(n, 2).float(),
        "log_scales": torch.randn(n, 3, generator=gen), "opacity_logits": torch.zeros(n),
        "f_dc": torch.zeros(n, 3),
    }
    surf = surfel_raw_from_gaussians(raw, log_thickness=math.log(1e-6), flat_ratio=1.01)  # own axes only
    r0, r1 = quat_to_rotmat(raw["quats"].double()), quat_to_rotmat(surf["quats"].double())
    assert torch.allclose(torch.linalg.det(r1), torch.ones(n, dtype=torch.float64), atol=1e-6)
    order = torch.argsort(raw["log_scales"], dim=1, descending=True)
    assert torch.equal(surf["log_scales"][:, :2], torch.gather(raw["log_scales"], 1, order[:, :2]))
    assert torch.allclose(surf["log_scales"][:, 2], torch.full((n,), math.log(1e-6)))
    for k in range(3):  # each new axis is the old axis of that rank, up to sign
        old = torch.gather(r0, 2, order[:, k].view(n, 1, 1).expand(n, 3, 1))[..., 0]
        cos = (old * r1[:, :, k]).sum(dim=1).abs()
        assert torch.allclose(cos, torch.ones(n, dtype=torch.float64), atol=1e-5)
    for name in ("means", "opacity_logits", "f_dc"):
        assert torch.equal(surf[name], raw[name])


def test_round_gaussians_take_the_normal_of_their_neighbourhood():
    """Isotropic Gaussians spread on a tilted plane become surfels lying in that plane; a clearly flat
    Gaussian keeps its own smallest axis."""
    gen = torch.Generator().manual_seed(3)
    normal = torch.nn.functional.normalize(torch.tensor([0.2, 1.0, -0.4], dtype=torch.float64), dim=0)
    t1 = frame_from_normal(normal[None])[0][:, 0]
    t2 = torch.linalg.cross(normal, t1, dim=0)
    uv = torch.rand(300, 2, generator=gen, dtype=torch.float64) * 2 - 1
    means = (uv[:, :1] * t1 + uv[:, 1:] * t2 + 0.001 * torch.randn(300, 1, generator=gen) * normal).float()
    gmap = GaussianMap.from_points(means, torch.full((300, 3), 0.5), torch.full((300,), 0.03))
    raw = gmap.raw()
    raw["log_scales"][0] = torch.log(torch.tensor([0.05, 0.04, 0.005]))  # flat along its local z
    surf = surfel_raw_from_gaussians(raw, -10.0, flat_ratio=0.8, neighbours=16)
    normals = quat_to_rotmat(surf["quats"].double())[:, :, 2]
    cos = (normals[1:] @ normal).abs()
    assert float(cos.min()) > 0.99
    assert float(normals[0].abs() @ torch.tensor([0.0, 0, 1], dtype=torch.float64)) > 0.999


def test_frame_from_normal_is_a_rotation_with_that_normal():
    n = torch.nn.functional.normalize(torch.randn(40, 3, generator=torch.Generator().manual_seed(4),
                                                  dtype=torch.float64), dim=1)
    rot = frame_from_normal(n)
    assert torch.allclose(rot[:, :, 2], n)
    assert torch.allclose(rot.transpose(1, 2) @ rot, torch.eye(3, dtype=torch.float64).expand(40, 3, 3),
                          atol=1e-12)
    assert torch.allclose(torch.linalg.det(rot), torch.ones(40, dtype=torch.float64))


def test_depth_normals_of_a_tilted_plane_face_the_camera():
    size, f = 24, 12.0
    K = torch.tensor([[f, 0, size / 2], [0, f, size / 2], [0, 0, 1]], dtype=torch.float64)
    normal = torch.tensor([0.3, -0.2, -1.0], dtype=torch.float64)
    normal = normal / normal.norm()  # plane n . p = d, facing the camera (n_z < 0)
    d = -2.0
    v, u = torch.meshgrid(torch.arange(size) + 0.5, torch.arange(size) + 0.5, indexing="ij")
    rays = torch.stack([(u - K[0, 2]) / f, (v - K[1, 2]) / f, torch.ones_like(u)], dim=-1).double()
    depth = d / (rays @ normal)  # z-depth of the plane along each ray
    n = depth_normals(depth, K)
    assert torch.allclose(n[1:-1, 1:-1], normal.expand(size - 2, size - 2, 3), atol=1e-6)
    assert torch.all(n[0] == 0) and torch.all(n[:, -1] == 0)
    # a rendered normal equal to the depth normal (full opacity) has zero error on the interior
    alpha = torch.ones(size, size, dtype=torch.float64)
    err = normal_error(depth, alpha, n, K)
    border = 1.0 - (size - 2) ** 2 / size**2  # the border pixels contribute 1 each
    assert float(err) == pytest.approx(border, abs=1e-6)


@pytest.fixture(scope="module")
def episode(tmp_path_factory):
    return make_episode(tmp_path_factory.mktemp("surfels") / "ep")


def test_2dgs_refinement_improves_the_keyframes_and_writes_flat_gaussians(episode, tmp_path):
    ep = shutil.copytree(episode, tmp_path / "ep")
    refiner = Refiner(ep, "2dgs", 20, backend="numba", progress=False)
    assert (refiner.method.dist_from, refiner.method.normal_from) == (2, 5)  # 3000 / 7000 of 30k, scaled
    before = refiner.keyframe_metrics()
    refiner.train()
    after = refiner.keyframe_metrics()
    assert after["psnr"] > before["psnr"] + 2.0, (before, after)
    assert after["depth_l1_m"] < before["depth_l1_m"]
    ply = refiner.write_outputs()
    saved = load_ply(ply)
    assert len(saved) == len(refiner.gmap)
    assert torch.allclose(saved.params["log_scales"][:, 2], torch.full((len(saved),), math.log(1e-6)))
    assert torch.equal(saved.params["log_scales"][:, :2], refiner.gmap.params["log_scales"].detach()[:, :2])


def test_2dgs_regularisers_switch_on_at_their_start(episode, tmp_path):
    ep = shutil.copytree(episode, tmp_path / "ep")
    refiner = Refiner(ep, "2dgs", 100, config=RefineConfig(lambda_dist=1.0), backend="numba", progress=False)
    out = refiner.method.render(refiner.gmap, refiner.viewmats[0], refiner.K, refiner.width, refiner.height)
    assert refiner.method.regularisers(out, 10, refiner.K) == (0.0, {})
    total, terms = refiner.method.regularisers(out, 11, refiner.K)
    assert set(terms) == {"distortion"} and float(total.detach()) == pytest.approx(terms["distortion"])
    total, terms = refiner.method.regularisers(out, 24, refiner.K)
    assert set(terms) == {"distortion", "normal"}
    assert float(total.detach()) == pytest.approx(terms["distortion"] + 0.05 * terms["normal"], rel=1e-5)
    assert 0.0 < terms["normal"] < 2.0


def test_2dgs_resume_matches_uninterrupted(episode, tmp_path):
    cfg = RefineConfig(densify_from_iter=3, densify_interval=4, opacity_reset_interval=1000,
                       densify_until_frac=1.0, checkpoint_every=5)
    a = shutil.copytree(episode, tmp_path / "a")
    b = shutil.copytree(episode, tmp_path / "b")
    refine(a, "2dgs", 10, config=cfg, backend="numba", progress=False, evaluate=False)
    refine(b, "2dgs", 10, config=cfg, backend="numba", progress=False, evaluate=False, stop_at=5)
    refine(b, "2dgs", 10, config=cfg, backend="numba", progress=False, evaluate=False)
    ga, gb = load_ply(a / "refined_2dgs" / "gaussians.ply"), load_ply(b / "refined_2dgs" / "gaussians.ply")
    for name in ga.params:
        assert torch.equal(ga.params[name], gb.params[name]), name


def test_surfel_initialisation_keeps_the_map_size():
    gmap = GaussianMap.from_points(torch.zeros(3, 3), torch.full((3, 3), 0.5), torch.tensor([0.1, 0.2, 0.3]))
    raw = surfel_raw_from_gaussians(gmap.raw(), -10.0)
    assert all(len(v) == 3 for v in raw.values())
    assert np.allclose(raw["log_scales"][:, 2].numpy(), -10.0)
