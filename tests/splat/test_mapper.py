"""The online mapper end to end on a tiny analytic scene (torch reference rasterizer, 32x32)."""

import numpy as np
import pytest
import torch
from _synthetic import intrinsics, observe, pose

from activesplat.errors import InvalidInputError
from activesplat.splat import GaussianMap, Mapper, MapperConfig
from activesplat.splat.config import Schedule
from activesplat.splat.densify import densification_mask, stride_mask

S = 32
BACKEND = "torch"


def _mapper(iterations=0, map_every=1, keyframe_every=1, **kw) -> Mapper:
    cfg = MapperConfig(schedule=Schedule(map_every, keyframe_every, iterations), **kw)
    return Mapper(intrinsics(S), S, S, cfg, backend=BACKEND)


def _psnr(mapper: Mapper, cam_pose, rgb) -> float:
    out = mapper.render(cam_pose)
    mse = ((out.rgb.clamp(0, 1) - torch.from_numpy(rgb).float() / 255) ** 2).mean().item()
    return -10 * np.log10(mse)


def test_first_frame_initialises_one_gaussian_per_strided_pixel():
    mapper = _mapper(pixel_stride=2, detail_colour_range=None)  # the grid alone (no colour detail)
    rgb, depth = observe(pose(), S)
    stats = mapper.add_frame(rgb, depth, pose())
    assert stats.mapped and stats.keyframe and stats.added == (S // 2) ** 2 == len(mapper.gaussians)
    assert np.allclose(mapper.gaussians.means[:, 2].detach().numpy(), 2.0, atol=1e-5)  # on the wall
    out = mapper.render(pose())
    assert out.alpha.min() > 0.9 and out.alpha.mean() > 0.98
    assert (out.depth - torch.from_numpy(depth)).abs().mean() < 0.05
    assert not mapper.high_loss_mask.any()


def test_map_quality_improves_with_iterations():
    mapper = _mapper(iterations=0)
    cams = [pose(), pose(tx=0.15), pose(yaw_deg=-8)]
    frames = [observe(c, S) for c in cams]
    for c, (rgb, depth) in zip(cams, frames, strict=True):
        mapper.add_frame(rgb, depth, c)
    before = np.mean([_psnr(mapper, c, f[0]) for c, f in zip(cams, frames, strict=True)])
    mapper.config = MapperConfig(schedule=Schedule(1, 1000, 10))
    losses = []
    for _ in range(3):
        for c, (rgb, depth) in zip(cams, frames, strict=True):
            losses.append(mapper.add_frame(rgb, depth, c).loss)
    after = np.mean([_psnr(mapper, c, f[0]) for c, f in zip(cams, frames, strict=True)])
    assert after > before + 1.0, (before, after)
    assert np.mean(losses[-3:]) < np.mean(losses[:3])


def test_densification_adds_gaussians_only_where_the_mask_says():
    # the stride grid alone: the box's silhouette would get one Gaussian per pixel with edge_band_px, and
    # its colour edge with detail_colour_range
    mapper = _mapper(iterations=0, pixel_stride=2, mask_downscale=1, edge_band_px=0, detail_colour_range=None)
    rgb, depth = observe(pose(), S)
    mapper.add_frame(rgb, depth, pose())
    n0 = len(mapper.gaussians)
    box = (-0.3, 0.3, -0.3, 0.3, 1.0)  # a face 1 m in front of the wall
    rgb_b, depth_b = observe(pose(), S, box=box)
    with torch.no_grad():
        out = mapper.render(pose())
    expected = densification_mask(out.alpha, out.depth, torch.from_numpy(depth_b), mapper.config)
    on_box = torch.from_numpy(depth_b < 1.5)
    inner = torch.zeros_like(on_box)
    inner[2:-2, 2:-2] = True  # the outermost pixels lack neighbours and stay below O = 0.98
    assert not (expected & ~on_box & inner).any() and (expected & on_box).sum() > 0.9 * on_box.sum()
    stats = mapper.add_frame(rgb_b, depth_b, pose())
    assert stats.added == int(stride_mask(expected, 2).sum()) > 0
    new = mapper.gaussians.means[n0:].detach().numpy()
    on_face = np.isclose(new[:, 2], 1.0, atol=1e-5)
    assert on_face.sum() == int(stride_mask(expected & on_box, 2).sum())  # the box face ...
    assert np.all(np.abs(new[~on_face, :2]).max(axis=1) > 0.85 * 2.0)  # ... and the image border only
    # eq. 10 mask of that frame was computed before densification: it marks the box
    hl = torch.from_numpy(mapper.high_loss_mask)
    assert hl.sum() > 0 and bool((hl <= on_box).all())
    assert hl.sum() >= 0.8 * on_box.sum()


def test_schedule_dense_and_normal():
    mapper = _mapper(iterations=0, map_every=5, keyframe_every=5)
    rgb, depth = observe(pose(), S)
    flags, masks = [], []
    for _ in range(6):
        s = mapper.add_frame(rgb, depth, pose())
        flags.append((s.mapped, s.keyframe))
        masks.append(mapper.high_loss_mask is not None)
    assert flags == [(True, True)] + [(False, False)] * 4 + [(True, True)]
    assert masks == [True] + [False] * 4 + [True]  # no eq. 10 mask for a frame that was not mapped
    mapper.config = MapperConfig(dense_schedule=Schedule(2, 1, 0))
    dense = [mapper.add_frame(rgb, depth, pose(), dense=True) for _ in range(2)]
    dense = [(s.mapped, s.keyframe) for s in dense]
    assert dense == [(True, True), (False, True)]  # frames 6 and 7
    assert [k.step for k in mapper.keyframes] == [0, 5, 6, 7]


def test_bad_frames_are_rejected_or_skipped_without_touching_the_map():
    mapper = _mapper(iterations=1)
    rgb, depth = observe(pose(), S)
    mapper.add_frame(rgb, depth, pose())
    snapshot = {k: v.clone() for k, v in mapper.gaussians.raw().items()}
    n_kf = len(mapper.keyframes)
    with pytest.warns(UserWarning, match="no valid depth"):
        stats = mapper.add_frame(rgb, np.zeros_like(depth), pose())
    assert stats.skipped and not stats.mapped
    bad_calls = [
        ((rgb[:, :-1], depth, pose()), "rgb must have shape"),
        ((rgb, depth[None], pose()), "depth must have shape"),
        ((rgb, depth, np.eye(3)), "pose"),
        ((rgb, depth, np.full((4, 4), np.nan)), "pose"),
        ((rgb, depth, 2 * np.eye(4)), "rigid"),
        ((rgb, depth, np.diag([-1.0, 1.0, 1.0, 1.0]) @ pose()), "proper rotation"),  # a mirror
        ((np.full(rgb.shape, np.nan), depth, pose()), "rgb"),
        ((rgb.astype(np.float32), depth, pose()), "0-255 colours"),  # float colours not in [0, 1]
        ((rgb, (depth * 1000).astype(np.uint16), pose()), "millimetres"),  # integer depth
        ((rgb, depth * 1000, pose()), "millimetres"),  # float depth in millimetres
    ]
    for args, msg in bad_calls:
        with pytest.raises(InvalidInputError, match=f"mapper: frame 2: .*{msg}"):
            mapper.add_frame(*args)
    with pytest.raises(InvalidInputError, match="2 NaN / inf entries"):  # the message says what is wrong
        bad = pose()
        bad[0, 3] = bad[1, 3] = np.nan
        mapper.add_frame(rgb, depth, bad)
    with pytest.raises(InvalidInputError, match="render size must be positive"):
        mapper.render(pose(), width=0)
    assert mapper.frames == 1 and len(mapper.keyframes) == n_kf
    for k, v in mapper.gaussians.raw().items():
        assert torch.equal(v, snapshot[k])


def test_nan_depth_pixels_are_treated_as_invalid():
    mapper = _mapper(iterations=2, pixel_stride=1)
    rgb, depth = observe(pose(), S)
    depth[:, : S // 2] = np.nan
    depth[0, -1] = np.inf
    depth[1, -1] = -1.0
    with pytest.warns(UserWarning, match=rf"frame 0: {(S // 2) * S + 2} depth pixels are NaN, inf or neg"):
        stats = mapper.add_frame(rgb, depth, pose())
    assert stats.added == (S // 2) * S - 2 and mapper.broken_depth_frames == 1
    for t in mapper.gaussians.params.values():
        assert torch.isfinite(t).all()
    assert np.all(mapper.gaussians.means[:, 0].detach().numpy() > -0.1)  # only the right half
    assert mapper.keyframes[0].depth[0, 0] == 0.0


def test_save_and_load_round_trip(tmp_path):
    mapper = _mapper(iterations=1)
    for c in (pose(), pose(tx=0.1)):
        rgb, depth = observe(c, S)
        mapper.add_frame(rgb, depth, c)
    mapper.save(tmp_path / "m")
    back = Mapper.load(tmp_path / "m")
    assert isinstance(back.gaussians, GaussianMap)
    for k, v in mapper.gaussians.raw().items():
        assert torch.equal(back.gaussians.params[k].detach(), v)
    assert [k.step for k in back.keyframes] == [0, 1]
    assert np.array_equal(back.keyframes[1].rgb, mapper.keyframes[1].rgb)
    assert np.array_equal(back.keyframes[1].pose, mapper.keyframes[1].pose)
    assert back.config == mapper.config and back.frames == 2
    assert torch.allclose(back.render(pose()).rgb, mapper.render(pose()).rgb)
    with pytest.raises(InvalidInputError, match="mapper.json"):
        Mapper.load(tmp_path)


def test_half_resolution_mask_render_finds_the_same_new_surface():
    full, half = _mapper(mask_downscale=1), _mapper(mask_downscale=2)
    rgb, depth = observe(pose(), S)
    rgb_b, depth_b = observe(pose(), S, box=(-0.3, 0.3, -0.3, 0.3, 1.0))
    added = []
    for mapper in (full, half):
        mapper.add_frame(rgb, depth, pose())
        n0 = len(mapper.gaussians)
        mapper.add_frame(rgb_b, depth_b, pose())
        added.append(int(np.isclose(mapper.gaussians.means[n0:, 2].detach().numpy(), 1.0).sum()))
        assert mapper.high_loss_mask.shape == (S, S)
    assert added[0] > 0 and abs(added[1] - added[0]) <= 0.15 * added[0]
    n_full, n_half = int(full.high_loss_mask.sum()), int(half.high_loss_mask.sum())
    assert abs(n_half - n_full) <= 0.2 * n_full


@pytest.mark.parametrize("detail", [None, 0.1], ids=["grid", "colour-detail"])
def test_floaters_in_observed_free_space_are_pruned(detail):
    """A box that disappears (seen as free space) is pruned; the wall it hid is then mapped. With colour
    detail, the wall beside the box's old edge carries per-pixel Gaussians of half the grid's radius, so
    the column where they meet the new grid Gaussians renders at opacity ~0.94 before any Adam step: the
    depth is checked normalised by the opacity (a floater would sit 1 m in front either way)."""
    mapper = _mapper(iterations=0, pixel_stride=2, detail_colour_range=detail)
    rgb_b, depth_b = observe(pose(), S, box=(-0.3, 0.3, -0.3, 0.3, 1.0))
    mapper.add_frame(rgb_b, depth_b, pose())
    z = mapper.gaussians.means[:, 2].detach().numpy()
    n_box, n_wall = int(np.isclose(z, 1.0).sum()), int(np.isclose(z, 2.0).sum())
    assert n_box > 0 and n_box + n_wall == len(z)
    rgb, depth = observe(pose(), S)
    stats = mapper.add_frame(rgb, depth, pose())
    z = mapper.gaussians.means[:, 2].detach().numpy()
    assert stats.pruned == n_box and np.isclose(z, 2.0).all()
    mapper.add_frame(rgb, depth, pose())  # the uncovered wall is densified on the next mapped frame
    out = mapper.render(pose())
    assert out.alpha[4:-4, 4:-4].min() > 0.9
    surface = out.depth / out.alpha.clamp_min(1e-6)
    assert (surface - torch.from_numpy(depth))[4:-4, 4:-4].abs().max() < 0.01
    if detail is None:  # the grid alone also covers the wall fully: the blended depth itself is on it
        assert (out.depth - torch.from_numpy(depth))[4:-4, 4:-4].abs().max() < 0.1
    off = _mapper(iterations=0, pixel_stride=2, prune_floater_margin_m=None, detail_colour_range=detail)
    off.add_frame(rgb_b, depth_b, pose())
    assert off.add_frame(rgb, depth, pose()).pruned == 0


def test_depth_bias_on_a_slanted_wall_shrinks_with_the_means_rate():
    """Front-to-back blending of overlapping centres renders a slanted wall in front of the truth; the
    depth loss moves the centres back, fast enough only at the project's means rate (1e-3 m/step). Centre
    depths (planar depth, the default, has no such bias: next test)."""
    from activesplat.splat.config import LearningRates

    cam = pose(yaw_deg=35)
    rgb, depth = observe(cam, S)
    inner = (slice(4, -4), slice(4, -4))
    bias = {}
    for lr_means in (1e-4, 1e-3):
        mapper = _mapper(iterations=30, lr=LearningRates(means=lr_means), planar_depth=False)
        mapper.add_frame(rgb, depth, cam)
        bias[lr_means] = float((mapper.render(cam).depth - torch.from_numpy(depth))[inner].mean())
    initial = _mapper(iterations=0, planar_depth=False)
    initial.add_frame(rgb, depth, cam)
    before = float((initial.render(cam).depth - torch.from_numpy(depth))[inner].mean())
    assert before < -0.1  # in front of the wall
    assert abs(bias[1e-3]) < 0.85 * abs(before) and abs(bias[1e-3]) < abs(bias[1e-4])




def test_planar_depth_renders_a_slanted_wall_without_the_bias():
    """With ``planar_depth`` the mapper's flat Gaussians render the slanted wall's own depth from the
    first frame (no iteration), where centre depths put it 10 cm or more in front."""
    cam = pose(yaw_deg=35)
    rgb, depth = observe(cam, S)
    inner = (slice(4, -4), slice(4, -4))
    bias = {}
    for planar in (False, True):
        mapper = _mapper(iterations=0, planar_depth=planar)
        mapper.add_frame(rgb, depth, cam)
        bias[planar] = float((mapper.render(cam).depth - torch.from_numpy(depth))[inner].abs().mean())
    assert bias[False] > 0.1 and bias[True] < 0.2 * bias[False], bias


def _wall_pose(z: float) -> np.ndarray:
    p = pose()
    p[2, 3] = z  # the wall (z = 2) is 2 - z metres ahead
    return p


def test_the_voxel_budget_bounds_the_gaussians_of_a_wall_seen_close_and_again():
    """MapperConfig "Voxel budget": from 0.5 m the 2-px grid (f = 16 px) spaces new centres 6 cm apart on the
    wall; with one centre per 10 cm voxel the first frame adds one per voxel the view covers, and a second,
    closer view of the same wall adds none where the map already holds a centre."""
    near, nearer = _wall_pose(1.5), _wall_pose(1.7)  # wall 0.5 m, then 0.3 m ahead
    plain = _mapper(detail_colour_range=None)
    budget = _mapper(detail_colour_range=None, densify_voxel_m=0.1)
    for m in (plain, budget):
        m.add_frame(*observe(near, S), near)
    keys = np.floor(budget.gaussians.means.detach().numpy()[:, :2] / 0.1)
    assert len(np.unique(keys, axis=0)) == len(budget.gaussians) < 0.5 * len(plain.gaussians)
    alpha = budget.render(near).alpha[4:-4, 4:-4]
    assert alpha.min() > 0.98  # fewer, not missing: wider Gaussians still cover the wall (eq. 8's tau_o1)
    stats = budget.add_frame(*observe(nearer, S), nearer)
    assert stats.added == 0


def test_coarse_refresh_replaces_far_gaussians_with_fine_ones_only_in_full_view():
    size = 64  # f = 32
    far, near = _wall_pose(-0.5), _wall_pose(1.2)  # wall 2.5 m, then 0.8 m ahead
    maps = {}
    for factor in (None, 2.0):
        cfg = MapperConfig(schedule=Schedule(1, 1, 0), refresh_coarse_factor=factor)
        mapper = Mapper(intrinsics(size), size, size, cfg, backend=BACKEND)
        mapper.add_frame(*observe(far, size), far)
        before = mapper.gaussians.raw()
        stats = mapper.add_frame(*observe(near, size), near)
        maps[factor] = (mapper, before, stats)
    plain, _, plain_stats = maps[None]
    mapper, before, stats = maps[2.0]
    assert plain_stats.refreshed == 0 and plain_stats.added == 0  # eq. 8 alone adds nothing: wall opaque
    assert stats.refreshed > 0 and stats.added > 0
    # from 0.8 m a new Gaussian gets 0.75 * 2 * 0.8 / 32 = 0.0375 m: none coarser than 2 x that is left
    # where the near view sees them whole; the Gaussians beyond the near view are the far frame's, untouched
    scales = mapper.gaussians.scales.max(dim=1).values.detach()
    inside = (mapper.gaussians.means[:, :2].detach().abs() < 0.25).all(dim=1)
    assert (scales[inside] <= 0.075).all()
    outside = before["means"][(before["means"][:, :2].abs() > 1.0).any(dim=1)]
    assert len(outside) > 0
    gap = torch.cdist(outside, mapper.gaussians.means.detach()).min(dim=1).values
    assert (gap == 0).all()  # still there, unmoved
    rgb = torch.from_numpy(observe(near, size)[0]).float()[16:48, 16:48] / 255

    def centre_psnr(m: Mapper) -> float:
        return -10 * np.log10(((m.render(near).rgb[16:48, 16:48].clamp(0, 1) - rgb) ** 2).mean().item())

    assert centre_psnr(mapper) > centre_psnr(plain) + 3.0


def test_a_wall_seen_from_its_other_side_gets_its_own_gaussians_only_with_the_back_face_rule():
    """Back faces (MapperConfig): the flat Gaussians of a wall's front do not pass eq. 8's opacity test for
    a camera behind the wall, so its back face is mapped; with every Gaussian in the mask render it is not."""
    K = intrinsics(32)
    depth = np.full((32, 32), 2.0, np.float32)
    behind = np.eye(4)
    behind[:3, 3] = [0.0, 0.0, 4.0]
    behind[:3, :3] = np.diag([-1.0, 1.0, -1.0])  # turned round, looking back at the same plane z = 2
    counts = {}
    for rule in (True, False):
        mapper = Mapper(K, 32, 32, MapperConfig(densify_front_faces_only=rule))
        mapper.add_frame(np.full((32, 32, 3), 200, np.uint8), depth, np.eye(4), dense=True)
        front = len(mapper.gaussians)
        for _ in range(3):
            mapper.add_frame(np.full((32, 32, 3), 30, np.uint8), depth, behind, dense=True)
        counts[rule] = (front, len(mapper.gaussians))
    assert counts[True][0] == counts[False][0] > 0
    assert counts[False][1] == counts[False][0]  # the front's Gaussians already make the view opaque
    assert counts[True][1] > 1.5 * counts[True][0]  # the back is mapped: most of the plane anew


def test_front_alpha_reads_a_wall_seen_from_behind_as_unseen_but_still_hides_what_lies_beyond():
    """Mapper.render(front_alpha=True), the planner's visibility: the flat Gaussians of a wall mapped from
    one side add no visibility to a camera on the other side, yet the wall still occludes."""
    K = intrinsics(32)
    mapper = Mapper(K, 32, 32, MapperConfig(), backend=BACKEND)
    mapper.add_frame(np.full((32, 32, 3), 200, np.uint8), np.full((32, 32), 2.0, np.float32), np.eye(4),
                     dense=True)
    behind = np.eye(4)
    behind[:3, 3] = [0.0, 0.0, 4.0]
    behind[:3, :3] = np.diag([-1.0, 1.0, -1.0])  # turned round, looking back at the plane z = 2
    centre = (slice(8, 24), slice(8, 24))
    for cam in (np.eye(4), behind):
        plain, front = mapper.render(cam), mapper.render(cam, front_alpha=True)
        assert plain.alpha[centre].min() > 0.9
        assert torch.equal(plain.median_depth, front.median_depth)  # depths: every Gaussian
    assert mapper.render(np.eye(4), front_alpha=True).alpha[centre].min() > 0.9
    assert mapper.render(behind, front_alpha=True).alpha[centre].max() < 0.05
    # the rendered alpha of a frame's own view is unchanged by the option's existence
    assert torch.equal(mapper.render(np.eye(4)).rgb, mapper.render(np.eye(4), front_alpha=False).rgb)


def test_depth_edges_at_pixel_resolution_bleed_less_over_what_lies_behind():
    # a face 1 m in front of the wall (2 m), mapped from scratch in one frame, no optimisation: with the grid
    # alone the face's Gaussians reach past its silhouette; with edge_band_px its near-side edge pixels get
    # their own, smaller ones (256 -> 316 Gaussians), and the blended depth mixes face and wall less
    rgb, depth = observe(pose(), S, box=(-0.35, 0.35, -0.35, 0.35, 1.0))
    errors, counts = {}, {}
    for band in (0, 2):
        mapper = _mapper(iterations=0, pixel_stride=2, mask_downscale=1, edge_band_px=band,
                         init_normal_scale=1.0)
        mapper.add_frame(rgb, depth, pose())
        with torch.no_grad():
            out = mapper.render(pose())
        errors[band] = float(np.abs(out.depth.numpy() - depth).mean())
        counts[band] = len(mapper.gaussians)
    assert counts[2] > counts[0]
    assert errors[2] < 0.8 * errors[0], errors  # measured 0.061 vs 0.086 m


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_a_snapshot_renders_what_render_renders_and_refuses_a_changed_map(backend):
    """Mapper.snapshot (the replan's panoramas): every view bit-identical to Mapper.render, plain and front
    faces (a wall mapped from both sides, cameras on both sides, with and without the margin), also for
    views the snapshot's first call did not prepare; after add_frame the snapshot refuses to render."""
    K = intrinsics(S)
    mapper = Mapper(K, S, S, MapperConfig(schedule=Schedule(1, 1, 2)), backend=backend)
    behind = np.eye(4)
    behind[:3, 3] = [0.0, 0.0, 4.0]
    behind[:3, :3] = np.diag([-1.0, 1.0, -1.0])
    rgb, depth = observe(pose(), S, box=(-0.4, 0.3, -0.3, 0.5, 1.4))
    mapper.add_frame(rgb, depth, pose(), dense=True)
    mapper.add_frame(np.full((S, S, 3), 30, np.uint8), np.full((S, S), 2.0, np.float32), behind, dense=True)
    snap = mapper.snapshot()
    grazing = pose(-1.2, 0.0, 80.0)  # just behind the wall's front face, looking along it
    grazing[2, 3] = 2.1
    cams = [pose(), pose(0.3, 0.1, 20.0), behind, pose(-0.2, 0.0, -35.0), grazing]
    for cam in cams:
        for kw in ({}, {"front_alpha": True}, {"front_alpha": True, "behind_margin_deg": 10.0},
                   {"K": intrinsics(16), "width": 16, "height": 16, "front_alpha": True}):
            a, b = mapper.render(cam, **kw), snap(cam, **kw)
            for name in ("rgb", "alpha", "depth", "median_depth", "radii"):
                assert torch.equal(a[name], b[name]), (name, kw)
    assert snap(behind, front_alpha=True).alpha.max() < snap(behind).alpha.max()  # the rule acted
    margin = snap(grazing, front_alpha=True, behind_margin_deg=10.0).alpha
    assert not torch.equal(margin, snap(grazing, front_alpha=True).alpha)  # and so did the margin
    mapper.add_frame(rgb, depth, pose(0.1), dense=True)
    with pytest.raises(RuntimeError, match="map changed"):
        snap(pose())
    assert torch.equal(mapper.snapshot()(pose()).rgb, mapper.render(pose()).rgb)
