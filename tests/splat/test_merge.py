"""Merging Gaussians that render alike (MapperConfig "Merging", splat/merge.py)."""

import numpy as np
import pytest
import torch
from _synthetic import intrinsics, observe, pose

from activesplat.errors import InvalidInputError
from activesplat.splat import Mapper, MapperConfig
from activesplat.splat.config import Schedule
from activesplat.splat.gaussians import f_dc_to_rgb, is_flat, rgb_to_f_dc
from activesplat.splat.kernels import quat_to_rotmat, rotmat_to_quat
from activesplat.splat.merge import merge_alike

RULE = dict(voxel_m=0.05, normal_deg=20.0, colour_tol=0.05, min_opacity=0.5, scale_ratio=2.0)


def _surfels(centres, normals=None, radii=0.02, rgb=(0.5, 0.5, 0.5), opacity=0.9, thickness=0.1):
    """Flat Gaussians in planes with the given normals (default +z), in-plane radius ``radii``."""
    n = len(centres)
    normals = np.tile([0.0, 0.0, 1.0], (n, 1)) if normals is None else np.asarray(normals, float)
    rot = []
    for nz in normals:
        nz = nz / np.linalg.norm(nz)
        helper = np.array([1.0, 0.0, 0.0]) if abs(nz[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x = np.cross(helper, nz)
        x /= np.linalg.norm(x)
        rot.append(np.stack([x, np.cross(nz, x), nz], axis=1))
    radii = np.broadcast_to(np.asarray(radii, float), (n,))
    scales = np.stack([radii, radii, thickness * radii], axis=1)
    rgb = np.broadcast_to(np.asarray(rgb, float), (n, 3))
    opacity = np.broadcast_to(np.asarray(opacity, float), (n,))
    return {"means": torch.tensor(np.asarray(centres, float), dtype=torch.float32),
            "quats": rotmat_to_quat(torch.tensor(np.stack(rot), dtype=torch.float32)),
            "log_scales": torch.tensor(np.log(scales), dtype=torch.float32),
            "opacity_logits": torch.logit(torch.tensor(opacity, dtype=torch.float32)),
            "f_dc": rgb_to_f_dc(torch.tensor(rgb, dtype=torch.float32))}


def test_two_copies_of_one_surfel_merge_into_that_surfel():
    raw = _surfels([[0.01, 0.01, 0.01]] * 2)
    merge = merge_alike(raw, **RULE)
    assert merge.leaders.tolist() == [0] and merge.absorbed.tolist() == [1]
    for name in ("means", "log_scales", "f_dc", "opacity_logits"):
        assert torch.allclose(merge.params[name], raw[name][:1], atol=1e-5), name
    normal = quat_to_rotmat(merge.params["quats"])[:, :, 2]
    assert torch.allclose(normal, torch.tensor([[0.0, 0.0, 1.0]]), atol=1e-5)


def test_an_offset_pair_merges_into_one_wider_surfel_in_the_same_plane():
    """Two equal surfels 2 cm apart along x: the merged one sits between them, is wider along x by the
    spread of the centres (sigma^2 + 0.01^2), as wide along y, as thin, and keeps the normal."""
    raw = _surfels([[0.005, 0.02, 0.01], [0.025, 0.02, 0.01]], radii=0.01, opacity=[0.9, 0.9])
    merge = merge_alike(raw, **RULE)
    assert len(merge.absorbed) == 1
    assert torch.allclose(merge.params["means"], torch.tensor([[0.015, 0.02, 0.01]]), atol=1e-6)
    axes = quat_to_rotmat(merge.params["quats"])[0]
    scales = merge.params["log_scales"].exp()[0]
    assert torch.allclose(axes[:, 2].abs(), torch.tensor([0.0, 0.0, 1.0]), atol=1e-5) and axes[2, 2] > 0
    assert abs(axes[0, 0]) > 0.999  # the wide axis along the offset
    assert scales[0].item() == pytest.approx(np.hypot(0.01, 0.01), rel=1e-4)
    assert scales[1].item() == pytest.approx(0.01, rel=1e-4)
    assert scales[2].item() == pytest.approx(0.001, rel=1e-4)
    assert bool(is_flat(merge.params["log_scales"])[0])


def test_the_merge_weights_by_opacity_and_area_and_keeps_the_largest_opacity():
    raw = _surfels([[0.01, 0.01, 0.01], [0.02, 0.01, 0.01]], radii=[0.01, 0.02], opacity=[0.6, 0.95],
                   rgb=[[0.50, 0.5, 0.5], [0.54, 0.5, 0.5]])
    merge = merge_alike(raw, **RULE)
    w = np.array([0.6 * 0.01 ** 2, 0.95 * 0.02 ** 2])
    assert merge.params["means"][0, 0].item() == pytest.approx((w @ [0.01, 0.02]) / w.sum(), rel=1e-5)
    assert torch.sigmoid(merge.params["opacity_logits"][0]).item() == pytest.approx(0.95, rel=1e-5)
    expected_red = (w @ [0.50, 0.54]) / w.sum()
    red = f_dc_to_rgb(merge.params["f_dc"])[0, 0].item()
    assert red == pytest.approx(expected_red, rel=1e-4)


@pytest.mark.parametrize("change", ["colour", "facing", "tilted", "voxel", "transparent", "round", "size"])
def test_gaussians_that_do_not_render_alike_are_left_alone(change):
    centres = [[0.01, 0.01, 0.01], [0.02, 0.01, 0.01]]
    kw = {}
    if change == "colour":
        kw["rgb"] = [[0.5, 0.5, 0.5], [0.5, 0.5, 0.6]]
    elif change == "facing":  # the two faces of a thin object
        kw["normals"] = [[0, 0, 1], [0, 0, -1]]
    elif change == "tilted":
        kw["normals"] = [[0, 0, 1], [0, np.sin(np.radians(30)), np.cos(np.radians(30))]]
    elif change == "voxel":
        centres[1] = [0.06, 0.01, 0.01]
    elif change == "transparent":
        kw["opacity"] = [0.9, 0.3]
    elif change == "round":
        kw["thickness"] = 1.0
    elif change == "size":
        kw["radii"] = [0.01, 0.025]
    merge = merge_alike(_surfels(centres, **kw), **RULE)
    assert merge.absorbed.numel() == 0 and merge.leaders.numel() == 0


def test_a_group_of_three_merges_into_its_first_row():
    raw = _surfels([[0.02, 0.02, 0.01], [0.01, 0.01, 0.01], [0.03, 0.01, 0.01], [0.2, 0.2, 0.01]])
    merge = merge_alike(raw, **RULE)
    assert merge.leaders.tolist() == [0] and sorted(merge.absorbed.tolist()) == [1, 2]


S = 32


def test_the_mapper_merges_copies_of_its_gaussians_in_view_and_keeps_the_originals():
    """A map whose every Gaussian was added twice: with the rule on, the next frame of the same view merges
    each copy of a flat Gaussian into its original, which keeps its parameters (the copies are identical),
    the Adam state follows, and merges are counted apart from pruning; with the rule off nothing merges."""
    cam = pose()
    rgb, depth = observe(cam, S)
    for voxel in (None, 0.01):
        cfg = MapperConfig(schedule=Schedule(1, 1, 0), merge_voxel_m=voxel, detail_colour_range=None)
        mapper = Mapper(intrinsics(S), S, S, cfg, backend="torch")
        mapper.add_frame(rgb, depth, cam)
        original = mapper.gaussians.raw()
        n, flat = len(mapper.gaussians), int(is_flat(original["log_scales"]).sum())
        mapper._append(mapper.gaussians.raw())  # every Gaussian twice
        stats = mapper.add_frame(rgb, depth, cam)
        assert len(mapper.optimizer) == len(mapper.gaussians)
        if voxel is None:
            assert stats.merged == 0 and len(mapper.gaussians) == 2 * n + stats.added
            continue
        assert 0.5 * n < flat == stats.merged and stats.pruned == 0
        assert len(mapper.gaussians) == 2 * n - flat + stats.added
        kept = mapper.gaussians.raw()
        for name in ("means", "opacity_logits", "f_dc"):
            assert torch.allclose(kept[name][:n], original[name], atol=1e-5), name
        # the same covariances and normals (the axes may turn about the normal of a round surfel)
        old_rot, new_rot = quat_to_rotmat(original["quats"]), quat_to_rotmat(kept["quats"][:n])
        old_cov = old_rot @ torch.diag_embed(original["log_scales"].exp() ** 2) @ old_rot.transpose(1, 2)
        new_cov = new_rot @ torch.diag_embed(kept["log_scales"][:n].exp() ** 2) @ new_rot.transpose(1, 2)
        assert torch.allclose(new_cov, old_cov, atol=1e-7)
        assert torch.allclose(new_rot[:, :, 2], old_rot[:, :, 2], atol=1e-4)


def test_merge_config_is_checked():
    with pytest.raises(InvalidInputError, match="merge_voxel_m"):
        MapperConfig(merge_voxel_m=0.0)
    with pytest.raises(InvalidInputError, match="merge_scale_ratio"):
        MapperConfig(merge_scale_ratio=0.5)
