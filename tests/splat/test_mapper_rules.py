"""Mapper building blocks that need no rendering: eq. 8 / eq. 10 masks, new Gaussians, pruning, Adam
bookkeeping under densify/prune."""

import numpy as np
import pytest
import torch

from activesplat.errors import InvalidInputError
from activesplat.splat.config import LearningRates, MapperConfig, Schedule
from activesplat.splat.densify import (
    cap_mask,
    coarse_mask,
    colour_detail,
    densification_mask,
    depth_edge_band,
    gaussians_from_pixels,
    high_loss_mask,
    one_per_voxel,
    prune_mask,
    surface_frame,
)
from activesplat.splat.gaussians import SH_C0, GaussianMap, back_facing
from activesplat.splat.kernels import quat_normal, quat_to_rotmat, rotmat_to_quat


def _planar_render(h=4, w=4):
    alpha = torch.ones(h, w)
    depth = torch.full((h, w), 2.0)
    obs = torch.full((h, w), 2.0)
    return alpha, depth, obs


def test_densification_mask_eq8():
    cfg = MapperConfig(densify_k=50.0)
    alpha, depth, obs = _planar_render()
    obs = obs + 0.001 * torch.arange(16.0).reshape(4, 4)  # median |error| = 0.0075 -> threshold 0.375
    alpha[0, 0] = 0.97  # not yet covered -> densify
    alpha[0, 1] = 0.99  # covered -> keep
    obs[1, 1] = 1.5  # in front by 0.5 > 0.375 -> densify
    obs[1, 2] = 1.8  # in front by only 0.2 -> keep
    obs[2, 2] = 2.6  # behind by 0.6 -> keep (eq. 8 only looks at D_obs < D_render)
    obs[3, 3] = 0.0  # invalid depth never densifies
    alpha[3, 3] = 0.0
    mask = densification_mask(alpha, depth, obs, cfg)
    expected = torch.zeros(4, 4, dtype=torch.bool)
    expected[0, 0] = expected[1, 1] = True
    assert torch.equal(mask, expected)
    assert not densification_mask(alpha, depth, obs, MapperConfig(densify_max_depth_m=1.0))[1, 1]


def test_voxel_groups_sort_by_voxel_then_tiebreak_then_index_and_mark_each_first():
    from activesplat.geometry import voxel_groups

    keys = np.array([5, 3, 5, 3, 7])
    order, first = voxel_groups(keys)
    assert order.tolist() == [1, 3, 0, 2, 4] and first.tolist() == [True, False, True, False, True]
    order, first = voxel_groups(keys, np.array([1, 0, 0, 0, 0]))  # row 0 sorts after row 2 in voxel 5
    assert order.tolist() == [1, 3, 2, 0, 4] and first.tolist() == [True, False, True, False, True]
    order, first = voxel_groups(keys[:0])
    assert order.shape == (0,) and first.shape == (0,)


def test_voxel_budget_keeps_one_new_centre_per_empty_voxel_grid_picks_first():
    from activesplat.geometry import voxel_keys

    points = np.array([[0.001, 0.0, 0.0],  # voxel A, a fine pick
                       [0.012, 0.0, 0.0],  # voxel A, a grid pick: kept before the fine one
                       [0.018, 0.0, 0.0],  # voxel A, a later grid pick: dropped
                       [0.050, 0.0, 0.0],  # voxel B, alone: kept
                       [0.301, 0.0, 0.0],  # voxel C, which the map already holds: dropped
                       [-0.001, 0.0, 0.0]])  # the voxel just below A: kept
    fine = np.array([True, False, False, False, False, False])
    occupied = np.unique(voxel_keys(np.array([[0.31, 0.001, 0.0]]), 0.02))
    assert one_per_voxel(points, fine, occupied, 0.02).tolist() == [False, True, False, True, False, True]
    assert one_per_voxel(points[:0], fine[:0], occupied, 0.02).shape == (0,)
    assert one_per_voxel(points, fine, occupied[:0], 0.02).sum() == 4


def test_voxel_budget_in_new_gaussians_spares_exempt_pixels_and_widens_what_it_keeps():
    from activesplat.geometry import voxel_keys

    cfg = MapperConfig(densify_voxel_m=0.1, detail_colour_range=None)
    K = np.array([[32.0, 0, 32], [0, 32.0, 32], [0, 0, 1]])
    wall = torch.full((64, 64), 2.0)  # the 2-px grid spaces centres 12.5 cm apart on it
    rgb = torch.full((64, 64, 3), 0.5)
    mask = torch.ones(64, 64, dtype=torch.bool)
    free = gaussians_from_pixels(mask, rgb, wall, np.eye(4), K, cfg, occupied=np.zeros(0, np.int64))
    assert len(free["means"]) == 32 * 32  # one pick per voxel already: the budget drops nothing
    assert torch.allclose(free["log_scales"].exp().max(dim=1).values, torch.tensor(0.1))  # >= 1 x voxel
    occupied = np.unique(voxel_keys(free["means"][:512].numpy(), 0.1))  # the top half is in the map
    budget = gaussians_from_pixels(mask, rgb, wall, np.eye(4), K, cfg, occupied=occupied)
    assert len(budget["means"]) == 512 and (budget["means"][:, 1] > 0).all()
    exempt = torch.zeros(64, 64, dtype=torch.bool)
    exempt[:4] = True  # two rows of grid picks in the occupied half: kept, at the grid's own radius
    spared = gaussians_from_pixels(mask, rgb, wall, np.eye(4), K, cfg, occupied=occupied, exempt=exempt)
    assert len(spared["means"]) == 512 + 64
    radii = spared["log_scales"].exp().max(dim=1).values
    assert torch.allclose(radii[spared["means"][:, 1] < -0.8], torch.tensor(0.75 * 2 * 2.0 / 32))
    with pytest.raises(InvalidInputError, match="densify_voxel_m"):
        MapperConfig(densify_voxel_m=0.0)


def test_high_loss_mask_eq10():
    cfg = MapperConfig()
    alpha, median, obs = _planar_render()
    obs[0, 0] = 1.5  # in front by 0.5, opaque -> high loss
    obs[0, 1] = 1.8  # in front by 0.2 < 0.3 -> no
    obs[0, 2], alpha[0, 2] = 1.0, 0.7  # in front but O <= 0.8 -> no
    obs[0, 3] = 2.5  # behind -> no
    obs[1, 0] = 0.0  # invalid -> no
    mask = high_loss_mask(alpha, median, obs, cfg)
    assert mask.sum() == 1 and mask[0, 0]


def test_gaussians_from_pixels_backprojects_with_projective_radius():
    cfg = MapperConfig(pixel_stride=1, init_radius_scale=1.0, init_normal_scale=1.0)  # the paper: isotropic
    K = np.array([[8.0, 0, 4], [0, 8.0, 4], [0, 0, 1]])
    pose = np.eye(4)
    pose[:3, 3] = [1.0, 2.0, 3.0]
    depth = torch.full((8, 8), 4.0)
    rgb = torch.rand(8, 8, 3, generator=torch.Generator().manual_seed(0))
    mask = torch.zeros(8, 8, dtype=torch.bool)
    mask[2, 5] = True
    raw = gaussians_from_pixels(mask, rgb, depth, pose, K, cfg)
    x = (5 + 0.5 - 4) / 8 * 4.0
    y = (2 + 0.5 - 4) / 8 * 4.0
    assert torch.allclose(raw["means"], torch.tensor([[1.0 + x, 2.0 + y, 3.0 + 4.0]]))
    assert torch.allclose(raw["log_scales"], torch.full((1, 3), np.log(4.0 / 8.0)))
    assert torch.allclose(torch.sigmoid(raw["opacity_logits"]), torch.tensor([cfg.init_opacity]))
    assert torch.equal(raw["quats"], torch.tensor([[1.0, 0, 0, 0]]))
    assert torch.allclose(0.5 + SH_C0 * raw["f_dc"], rgb[2, 5])


def _near_and_far_view():
    """An 8x8 camera (focal 8 px) whose left half sees a surface 1 m away and its right half one 6 m away."""
    depth = torch.full((8, 8), 6.0)
    depth[:, :4] = 1.0
    return np.array([[8.0, 0, 4], [0, 8.0, 4], [0, 0, 1]]), depth


def test_the_birth_radius_cap_bounds_far_gaussians_and_leaves_near_ones():
    """init_max_radius_m caps the projective radius: a pixel 6 m away gets the cap, one 1 m away its own
    radius (stride x depth / focal x scale)."""
    K, depth = _near_and_far_view()
    mask = torch.ones(8, 8, dtype=torch.bool)
    for cap in (None, 0.3):
        cfg = MapperConfig(pixel_stride=2, init_normal_scale=1.0, edge_band_px=0, detail_colour_range=None,
                           init_max_radius_m=cap)
        raw = gaussians_from_pixels(mask, torch.zeros(8, 8, 3), depth, np.eye(4), K, cfg)
        radius = torch.exp(raw["log_scales"]).max(dim=1).values
        near = raw["means"][:, 2] < 2.0
        assert torch.allclose(radius[near], torch.tensor(cfg.init_radius_scale * 2 * 1.0 / 8.0))
        far = cfg.init_radius_scale * 2 * 6.0 / 8.0 if cap is None else cap
        assert torch.allclose(radius[~near], torch.tensor(far))
    with pytest.raises(InvalidInputError, match="init_max_radius_m"):
        MapperConfig(init_max_radius_m=0.0)


def test_the_capped_fill_gives_every_far_pixel_its_own_gaussian():
    """With init_capped_fill, where the capped radius is under half the grid's spacing (here the pixels 6 m
    away: spacing 2 x 6 / 8 = 1.5 m, cap 0.3 m) every pixel gets a Gaussian; nearer ones keep the grid."""
    K, depth = _near_and_far_view()
    counts = []
    for fill in (False, True):
        cfg = MapperConfig(pixel_stride=2, edge_band_px=0, detail_colour_range=None, init_max_radius_m=0.3,
                           init_capped_fill=fill)
        raw = gaussians_from_pixels(torch.ones(8, 8, dtype=torch.bool), torch.zeros(8, 8, 3), depth,
                                    np.eye(4), K, cfg)
        far = raw["means"][:, 2] > 2.0
        counts.append((int((~far).sum()), int(far.sum())))
        assert torch.exp(raw["log_scales"]).max() <= 0.3 + 1e-6
    assert counts == [(8, 8), (8, 32)]


def test_pixel_stride_subsamples_the_mask():
    cfg = MapperConfig(pixel_stride=2, init_normal_scale=1.0)
    K = np.array([[8.0, 0, 4], [0, 8.0, 4], [0, 0, 1]])
    raw = gaussians_from_pixels(torch.ones(8, 8, dtype=torch.bool), torch.zeros(8, 8, 3), torch.ones(8, 8),
                                np.eye(4), K, cfg)
    assert raw["means"].shape == (16, 3)
    assert torch.allclose(raw["log_scales"], torch.full((16, 3), np.log(cfg.init_radius_scale * 2 / 8.0)))


def _floor_depth(size=64, focal=32.0, height=1.0):
    """z-depth of a camera at ``height`` above a floor (camera y points down to it), looking level."""
    v = np.arange(size)[:, None].repeat(size, axis=1)
    dy = (v + 0.5 - size / 2) / focal
    return np.where(dy > 0, height / np.maximum(dy, 1e-9), 0.0).astype(np.float32)


def test_surface_frame_finds_the_plane_facing_the_camera_and_the_slant_under_the_ray():
    K = np.array([[32.0, 0, 32], [0, 32.0, 32], [0, 0, 1]])
    v, u = np.array([40, 50, 60, 20, 33]), np.array([32, 10, 50, 32, 0])
    normal, axis, ok = surface_frame(_floor_depth(), v, u, K, 2, 0.02)
    assert ok.tolist() == [True, True, True, False, False]  # no depth (ceiling side), neighbour off the image
    assert np.allclose(normal[:3], [0.0, -1.0, 0.0], atol=1e-5)  # the floor's normal, up to the camera
    rays = np.stack([(u + 0.5 - 32) / 32, (v + 0.5 - 32) / 32, np.ones(5)], axis=1)
    assert np.allclose(axis[:3, 1], 0.0, atol=1e-5)  # the axis lies in the floor...
    assert np.allclose(np.cross(axis[:3], rays[:3])[:, 1], 0.0, atol=1e-5)  # ...under the viewing ray
    assert not normal[3:].any() and not axis[3:].any()
    depth = np.full((64, 64), 3.0, np.float32)
    depth[:, 33:] = 1.5  # a box edge: neighbours off the plane
    normal, _, ok = surface_frame(depth, np.array([20, 20]), np.array([32, 20]), K, 2, 0.02)
    assert ok.tolist() == [False, True]  # the edge, and a wall facing the camera seen off-axis
    assert np.allclose(normal[1], [0.0, 0.0, -1.0], atol=1e-5)


def test_depth_edge_band_marks_the_near_side_of_a_jump_not_a_steep_plane():
    depth = torch.full((6, 9), 2.0)
    depth[:, 4:] = 4.0  # a jump between columns 3 (near) and 4 (far)
    depth[5, 0] = 0.0  # an invalid pixel: counts as infinitely far
    band = depth_edge_band(depth, 1, 0.05)
    expected = torch.zeros(6, 9, dtype=torch.bool)
    expected[:, 3] = True
    expected[4, 0] = expected[5, 1] = True
    assert torch.equal(band, expected)
    wide = depth_edge_band(depth, 2, 0.05)
    assert wide[:, 2:4].all() and not wide[:, 4:].any() and not wide[5, 0]  # far side and invalid: never
    # a floor seen from 1.2 m: depth grows by more than 5 % per row far away, but smoothly (no jump)
    rows = torch.arange(40, 64, dtype=torch.float32)[:, None] + 0.5
    floor = (1.2 * 128.0 / (rows - 32.0)).expand(24, 64).contiguous()
    assert (floor[1:5, 0] / floor[2:6, 0] > 1.05).all()
    assert not depth_edge_band(floor, 2, 0.05)[1:-1].any()


def test_pixels_near_a_depth_jump_get_one_gaussian_each_of_a_one_pixel_radius():
    K = np.array([[32.0, 0, 32], [0, 32.0, 32], [0, 0, 1]])
    depth = torch.full((64, 64), 3.0)
    depth[:, 33:] = 1.5  # a jump between columns 32 (far) and 33 (near)
    mask = torch.ones(64, 64, dtype=torch.bool)
    grid = MapperConfig(edge_band_px=0)
    off = gaussians_from_pixels(mask, torch.zeros(64, 64, 3), depth, np.eye(4), K, grid)
    cfg = MapperConfig(edge_band_px=2)
    on = gaussians_from_pixels(mask, torch.zeros(64, 64, 3), depth, np.eye(4), K, cfg)
    assert len(off["means"]) == 32 * 32
    # the near side's columns 33 and 34 at every row (2 x 64) replace the grid's column 33 (32)
    assert len(on["means"]) == 32 * 32 - 32 + 2 * 64
    x = on["means"][:, 0] / on["means"][:, 2] * 32 + 32  # back to the pixel column (centre at u + 0.5)
    radius = torch.exp(on["log_scales"]).max(dim=1).values
    band = (x > 33) & (x < 35)
    z = on["means"][:, 2]
    assert torch.allclose(z[band], torch.full_like(z[band], 1.5))
    assert torch.allclose(radius[band], cfg.init_radius_scale * 1 * z[band] / 32.0, rtol=1e-5)
    assert torch.allclose(radius[~band], cfg.init_radius_scale * 2 * z[~band] / 32.0, rtol=1e-5)


def test_colour_detail_marks_whole_blocks_whose_colours_span_more_than_the_range():
    rgb = torch.full((5, 7, 3), 0.5)
    rgb[1, 2, 1] = 0.8  # the block of rows 0-1, columns 2-3: green spans 0.3
    rgb[4, 5, 0] = 0.6  # the clipped bottom block (row 4, columns 4-5): red spans 0.1 only
    detail = colour_detail(rgb, 2, 0.2)
    expected = torch.zeros(5, 7, dtype=torch.bool)
    expected[0:2, 2:4] = True
    assert torch.equal(detail, expected)
    assert colour_detail(rgb, 2, 0.05)[4, 4:6].all() and not colour_detail(rgb, 2, 0.3).any()


def test_a_block_with_colour_detail_gets_one_gaussian_per_pixel_of_a_one_pixel_radius():
    K = np.array([[32.0, 0, 32], [0, 32.0, 32], [0, 0, 1]])
    depth = torch.full((64, 64), 2.0)
    rgb = torch.full((64, 64, 3), 0.4)
    rgb[10:12, 20:22] = torch.tensor([[[0.9, 0.4, 0.4], [0.1, 0.4, 0.4]]] * 2)  # one 2 x 2 block, two colours
    mask = torch.ones(64, 64, dtype=torch.bool)
    cfg = MapperConfig(detail_colour_range=0.2)
    off = gaussians_from_pixels(mask, rgb, depth, np.eye(4), K, MapperConfig(detail_colour_range=None))
    on = gaussians_from_pixels(mask, rgb, depth, np.eye(4), K, cfg)
    assert len(off["means"]) == 32 * 32 and len(on["means"]) == 32 * 32 + 3  # the block's grid pixel kept
    radius = torch.exp(on["log_scales"]).max(dim=1).values
    assert int((radius < cfg.init_radius_scale * 1.5 * 2.0 / 32.0).sum()) == 4
    # colours are kept per pixel: the block's two reds both appear
    reds = on["f_dc"][:, 0] * SH_C0 + 0.5
    assert (reds > 0.8).sum() == 2 and (reds < 0.2).sum() == 2


def test_flat_gaussians_lie_in_the_floor_and_are_thin_along_its_normal():
    cfg = MapperConfig(init_normal_scale=0.1)
    K = np.array([[32.0, 0, 32], [0, 32.0, 32], [0, 0, 1]])
    depth = torch.from_numpy(_floor_depth())
    mask = torch.zeros(64, 64, dtype=torch.bool)
    mask[47, 33] = mask[41, 21] = True
    pose = np.eye(4)
    pose[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]  # camera turned: the axes must come out in the world
    raw = gaussians_from_pixels(mask, torch.zeros(64, 64, 3), depth, pose, K, cfg)
    scales = torch.exp(raw["log_scales"])
    rot = quat_to_rotmat(raw["quats"])
    z = depth[[41, 47], [21, 33]]  # torch.nonzero order: row-major
    radius = cfg.init_radius_scale * 2 * z / 32.0
    assert torch.allclose(scales[:, :2], radius[:, None].expand(2, 2), rtol=1e-5)  # the radius in the plane
    assert torch.allclose(scales[:, 2], 0.1 * radius, rtol=1e-5)
    normal = rot[:, :, 2]  # world floor normal (0, +-1, 0): the camera looks down on it from above
    assert torch.allclose(normal.abs(), torch.tensor([[0.0, 1.0, 0.0]]).expand(2, 3), atol=1e-4)
    assert torch.allclose(torch.linalg.det(rot), torch.ones(2), atol=1e-5)
    # the normal points to the camera that made them: seen from there they face it, from below the floor not
    assert not back_facing(raw["quats"], raw["log_scales"], raw["means"], pose[:3, 3]).any()
    assert back_facing(raw["quats"], raw["log_scales"], raw["means"], [0.0, 5.0, 0.0]).all()
    # an edge (neighbours off the plane) stays isotropic
    edge = torch.full((64, 64), 3.0)
    edge[:, 34:] = 1.5
    one = torch.zeros(64, 64, dtype=torch.bool)
    one[21, 33] = True
    raw = gaussians_from_pixels(one, torch.zeros(64, 64, 3), edge, np.eye(4), K, cfg)
    assert torch.allclose(raw["log_scales"][0], raw["log_scales"][0, :1].expand(3))
    with pytest.raises(InvalidInputError):
        MapperConfig(init_normal_scale=0.0)


def test_rotmat_to_quat_inverts_quat_to_rotmat_including_half_turns():
    g = torch.Generator().manual_seed(0)
    q = torch.randn(200, 4, generator=g, dtype=torch.float64)
    q /= q.norm(dim=1, keepdim=True)
    half_turns = torch.diag_embed(torch.tensor([[1.0, -1, -1], [-1, 1, -1], [-1, -1, 1], [1, 1, 1]],
                                               dtype=torch.float64))
    rots = torch.cat([quat_to_rotmat(q), half_turns])
    back = rotmat_to_quat(rots)
    assert torch.all(back[:, 0] >= 0)
    assert torch.allclose(back.norm(dim=1), torch.ones(204, dtype=torch.float64))
    assert torch.allclose(quat_to_rotmat(back), rots, atol=1e-12)


def test_back_facing_marks_flat_gaussians_seen_from_behind_only():
    half_turn_about_x = [0.0, 1.0, 0.0, 0.0]  # normal (third axis) -z
    quats = torch.tensor([[1.0, 0, 0, 0], half_turn_about_x, [1.0, 0, 0, 0]])
    log_scales = torch.log(torch.tensor([[0.05, 0.05, 0.005], [0.05, 0.05, 0.005], [0.05, 0.05, 0.05]]))
    means = torch.zeros(3, 3)
    assert back_facing(quats, log_scales, means, [0.0, 0.0, 1.0]).tolist() == [False, True, False]
    assert back_facing(quats, log_scales, means, [0.3, 0.0, -2.0]).tolist() == [True, False, False]
    assert back_facing(quats[:0], log_scales[:0], means[:0], [0.0, 0.0, 1.0]).numel() == 0


def _map(n=6, seed=0) -> GaussianMap:
    g = torch.Generator().manual_seed(seed)
    return GaussianMap({"means": torch.randn(n, 3, generator=g), "quats": torch.randn(n, 4, generator=g),
                        "log_scales": torch.full((n, 3), -3.0), "opacity_logits": torch.zeros(n),
                        "f_dc": torch.zeros(n, 3)})


def test_prune_removes_transparent_and_oversized_then_caps():
    gmap = _map(6)
    with torch.no_grad():
        gmap.params["opacity_logits"][:] = torch.tensor([2.0, -6.0, 1.0, 0.5, 3.0, -1.0])  # [1]: 0.0025
        gmap.params["log_scales"][2, 1] = np.log(0.8)  # oversized (> 0.5 m)
    keep = prune_mask(gmap.params, MapperConfig())
    assert keep.tolist() == [True, False, False, True, True, True]
    capped = cap_mask(gmap.params["opacity_logits"].detach(), keep, 2)  # the two most opaque survivors
    assert capped.tolist() == [True, False, False, False, True, False]
    removed = gmap.keep(capped)
    assert removed == 4 and len(gmap) == 2


def test_adam_state_follows_densify_and_prune():
    gmap = _map(5)
    opt = gmap.make_optimizer(LearningRates(), 1e-15)
    loss = sum((t**2).sum() for t in (gmap.means, gmap.scales, gmap.opacities, gmap.colors, gmap.quats))
    loss.backward()
    opt.step()
    before = {n: opt.state[gmap.params[n]]["exp_avg"].clone() for n in gmap.params}
    added = gmap.append({k: v[:3] for k, v in _map(3, seed=1).raw().items()}, opt)
    assert added == 3 and len(gmap) == 8
    for n, t in gmap.params.items():
        state = opt.state[t]
        assert state["exp_avg"].shape == t.shape and state["exp_avg_sq"].shape == t.shape
        assert torch.equal(state["exp_avg"][:5], before[n])
        assert not state["exp_avg"][5:].any() and not state["exp_avg_sq"][5:].any()
        assert any(g["params"][0] is t for g in opt.param_groups)
    keep = torch.tensor([True, False, True, True, False, True, True, False])
    gmap.keep(keep, opt)
    for n, t in gmap.params.items():
        assert torch.equal(opt.state[t]["exp_avg"][:3], before[n][[0, 2, 3]])
        assert opt.state[t]["exp_avg"].shape == t.shape
    assert len(opt.state) == 5  # no stale entries for replaced tensors
    opt.zero_grad()
    gmap.means.sum().backward()
    opt.step()  # still steps after the swaps


def test_map_and_config_reject_bad_values():
    with pytest.raises(InvalidInputError, match="quats"):
        GaussianMap({**_map(3).raw(), "quats": torch.zeros(2, 4)})
    with pytest.raises(InvalidInputError, match="NaN"):
        GaussianMap({**_map(3).raw(), "f_dc": torch.full((3, 3), float("nan"))})
    with pytest.raises(InvalidInputError, match="keep mask"):
        _map(3).keep(torch.ones(2, dtype=torch.bool))
    with pytest.raises(InvalidInputError, match="densify_k"):
        MapperConfig(densify_k=-1.0)
    with pytest.raises(InvalidInputError, match="schedule"):
        MapperConfig(schedule=Schedule(0, 5, 2))


def test_downsample_observation_block_means_and_invalid_blocks():
    from activesplat.splat.frames import downsample_observation

    rgb = torch.arange(4 * 4 * 3, dtype=torch.float32).reshape(4, 4, 3)
    depth = torch.tensor([[1.0, 2, 3, 4], [1, 2, 0, 4], [5, 5, 6, 6], [5, 5, 6, 6]])
    small_rgb, small_depth = downsample_observation(rgb, depth, 2)
    assert torch.equal(small_rgb[0, 1], rgb[:2, 2:].reshape(-1, 3).mean(dim=0))
    assert torch.equal(small_depth, torch.tensor([[1.5, 0.0], [5.0, 6.0]]))  # a block with a hole -> invalid
    assert downsample_observation(rgb, depth, 1)[1] is depth


def test_free_space_mask_flags_only_gaussians_in_observed_free_space():
    from activesplat.splat.densify import free_space_mask

    K = np.array([[8.0, 0, 8], [0, 8.0, 8], [0, 0, 1]])  # 16 x 16 image, pixel (v, u) centre (u+.5, v+.5)
    depth = torch.full((16, 16), 2.0)
    depth[:, :6] = 1.0  # a box face on the left, its edge between columns 5 and 6
    depth[12:, 12:] = 0.0  # a hole: unknown space

    def at(v, u, z):  # world point on the ray through pixel (v, u) centre at z-depth z (camera = world)
        return [(u + 0.5 - 8) / 8 * z, (v + 0.5 - 8) / 8 * z, z]

    means = torch.tensor([
        at(4, 10, 2.0),  # on the wall -> keep
        at(4, 10, 1.0),  # 1 m in front of the wall -> floater
        at(4, 10, 3.0),  # behind the wall (occluded) -> keep
        at(4, 10, 1.95),  # within the 0.1 m margin -> keep
        at(4, 6, 1.0),  # box rim seen one pixel off, on a wall pixel next to the box -> keep (3x3 min)
        at(4, 8, 1.0),  # two pixels off the box -> floater
        at(13, 13, 0.5),  # in front of unknown depth -> keep
        [0.0, 0.0, -1.0],  # behind the camera -> keep
        at(4, 40, 1.0),  # outside the image -> keep
    ])
    got = free_space_mask(means, np.eye(4), K, depth, margin_m=0.1, window_px=1)
    assert got.tolist() == [False, True, False, False, False, True, False, False, False]
    moved = np.eye(4)
    moved[:3, 3] = [0.0, 0.0, -1.0]  # camera 1 m back: the wall is at z = 3 in the camera
    assert free_space_mask(means + torch.tensor([0.0, 0.0, -1.0]), moved, K, depth, 0.1, 1).tolist() == \
        got.tolist()


def _rough_depth(h: int, w: int, seed: int) -> torch.Tensor:
    """A floor-like ramp with boxes in front of it, noise, and invalid pixels: jumps, smooth slopes, holes."""
    rng = np.random.default_rng(seed)
    rows = np.arange(h, dtype=np.float64)[:, None] + 0.5
    depth = np.broadcast_to(40.0 / (rows + 8.0), (h, w)).copy()
    for _ in range(4):
        i, j = rng.integers(0, h), rng.integers(0, w)
        depth[i:i + rng.integers(2, 9), j:j + rng.integers(2, 9)] *= rng.uniform(0.3, 0.98)
    depth *= 1.0 + 0.01 * rng.standard_normal((h, w))
    depth[rng.random((h, w)) < 0.03] = 0.0
    return torch.from_numpy(depth.astype(np.float32))


@pytest.mark.parametrize("h,w", [(37, 45), (2, 7), (16, 16)])
def test_cpu_density_masks_are_the_torch_masks_bit_for_bit(h, w):
    """The CPU (numba) depth-edge band, colour detail and floater test give exactly the torch versions'
    masks: every band width and stride, image sizes that leave partial blocks, windows at the border."""
    from activesplat.splat.densify import (
        _colour_detail_torch,
        _depth_edge_band_torch,
        _floaters_torch,
        _project,
        free_space_mask,
    )

    depth = _rough_depth(h, w, h * w)
    for band in (1, 2, 3):
        for jump in (0.05, 0.01):
            assert torch.equal(depth_edge_band(depth, band, jump), _depth_edge_band_torch(depth, band, jump))
    rng = np.random.default_rng(w)
    rgb = torch.from_numpy(rng.integers(0, 256, (h, w, 3)).astype(np.uint8)).to(torch.float32) / 255.0
    rgb[: h // 2] = rgb[: h // 2].mean()  # flat colour in the top half
    for stride in (1, 2, 3, 4):
        for colour_range in (0.1, 0.5):
            want = _colour_detail_torch(rgb, stride, colour_range)
            assert torch.equal(colour_detail(rgb, stride, colour_range), want)
    K = np.array([[w / 2.0, 0, w / 2.0], [0, h / 2.0, h / 2.0], [0, 0, 1]])
    n = 3000
    g = torch.Generator().manual_seed(h)
    z = 0.2 + 6.0 * torch.rand(n, generator=g)
    means = torch.cat([(torch.rand(n, 2, generator=g) - 0.5) * 2.4 * z[:, None], z[:, None]], 1)
    means[:50, 2] *= -1.0  # behind the camera
    projected = _project(means, np.eye(4), K, h, w)
    for window in (0, 1, 2):
        for margin in (0.1, 0.0):
            got = free_space_mask(means, np.eye(4), K, depth, margin, window)
            assert torch.equal(got, _floaters_torch(*projected, depth, margin, window))
            assert got.dtype == torch.bool and not got.all()
            assert got.any() or min(h, w) <= 2 * window


def test_coarse_mask_picks_only_what_the_view_sees_whole_and_much_finer():
    size, f = 64, 32.0
    K = np.array([[f, 0, size / 2], [0, f, size / 2], [0, 0, 1]])
    cam = np.eye(4)  # looking down +z at a wall 2 m away
    depth = torch.full((size, size), 2.0)
    depth[44:50, 18:24] = 1.5  # a box in front of the wall, left of centre, lower half
    cfg = MapperConfig(refresh_coarse_factor=2.0)  # new radius at 2 m: 0.75 * 2 * 2 / 32 = 0.094 m
    centres = [(0.0, 0.0, 2.0),  # coarse (0.2 > 2 x 0.094), footprint +-6.4 px inside, unoccluded -> yes
               (1.0, -1.0, 2.0),  # fine (0.05) -> no
               (-1.0, 0.9, 2.0),  # coarse, the box covers part of its footprint -> no
               (1.7, 0.0, 2.0),  # coarse, footprint leaves the image -> no
               (0.0, 0.0, 3.0),  # coarse, behind the observed wall (hidden) -> no
               (0.0, 0.0, 1.0)]  # coarse, 1 m in front of the wall (free space, not the surface) -> no
    scales = [0.2, 0.05, 0.2, 0.2, 0.3, 0.1]
    means = torch.tensor(centres)
    log_scales = torch.log(torch.tensor(scales)).unsqueeze(1).repeat(1, 3)
    expected = [True, False, False, False, False, False]
    assert coarse_mask(means, log_scales, cam, K, depth, cfg).tolist() == expected
    assert not coarse_mask(means, log_scales, cam, K, depth, MapperConfig()).any()  # off by default
    big_floor = MapperConfig(refresh_coarse_factor=2.0, refresh_min_radius_m=0.15)  # 0.2 < 2 x 0.15
    assert not coarse_mask(means, log_scales, cam, K, depth, big_floor).any()
    invalid = depth.clone()
    invalid[30, 30] = 0.0  # an unknown pixel inside the first one's footprint
    assert not coarse_mask(means, log_scales, cam, K, invalid, cfg)[0]
    with pytest.raises(InvalidInputError, match="refresh_coarse_factor"):
        MapperConfig(refresh_coarse_factor=1.0)


def test_quat_normal_is_the_rotation_matrix_third_column_bit_for_bit():
    quats = torch.randn(1000, 4, generator=torch.Generator().manual_seed(3))
    quats[0] = torch.tensor([0.0, 0.0, 0.0, 2.0])  # unnormalised: a half turn about z keeps the normal +z
    normal = quat_normal(quats)
    assert torch.equal(normal, quat_to_rotmat(quats)[:, :, 2])
    assert torch.allclose(normal[0], torch.tensor([0.0, 0.0, 1.0]))
