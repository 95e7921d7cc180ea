"""What lets the online map scale to many rooms: frustum culling that changes no pixel, a row-sparse Adam
that leaves unseen Gaussians untouched, and a mapper that does not forget what it no longer sees."""

import numpy as np
import torch
from _synthetic import intrinsics, observe, pose

from activesplat.splat import GaussianMap, Mapper, MapperConfig
from activesplat.splat._mapper_numba import far_depth
from activesplat.splat.config import LearningRates, Schedule
from activesplat.splat.gaussians import (
    PARAM_NAMES,
    _far_depth,
    _frustum_rows_torch,
    activate,
    frustum_rows,
)
from activesplat.splat.optim import RowAdam
from activesplat.splat.rasterize import rasterize

S = 32


def _cloud(n: int, seed: int = 0) -> GaussianMap:
    """Gaussians all around a camera at the origin: behind it, beside it, far, near, small and large."""
    g = torch.Generator().manual_seed(seed)
    means = (torch.rand(n, 3, generator=g) - 0.5) * torch.tensor([8.0, 8.0, 8.0])
    return GaussianMap({"means": means, "quats": torch.randn(n, 4, generator=g),
                        "log_scales": torch.log(0.02 + 0.5 * torch.rand(n, 3, generator=g) ** 3),
                        "opacity_logits": torch.randn(n, generator=g) + 1.0,
                        "f_dc": torch.randn(n, 3, generator=g)})


def test_frustum_rows_render_exactly_the_whole_map():
    gmap = _cloud(600)
    K = intrinsics(S)
    for cam in (pose(), pose(yaw_deg=70.0), pose(tx=1.0, ty=-0.5, yaw_deg=-120.0)):
        rows = frustum_rows(gmap.params["means"], gmap.params["log_scales"], cam, K, S, S)
        assert torch.equal(rows, _frustum_rows_torch(gmap.params["means"], gmap.params["log_scales"], cam,
                                                     K, S, S, None, 0.1, 8))  # numba kernel = torch
        assert 0 < len(rows) < len(gmap)  # culls something, keeps something
        viewmat = torch.from_numpy(np.linalg.inv(cam).astype(np.float32))
        Kt = torch.from_numpy(K.astype(np.float32))
        whole = rasterize(*activate(gmap.params), viewmat, Kt, S, S, backend="torch")
        part = rasterize(*activate(gmap.rows(rows)), viewmat, Kt, S, S, backend="torch")
        drawn = torch.nonzero(whole.radii > 0, as_tuple=True)[0]
        assert set(drawn.tolist()) <= set(rows.tolist())  # a superset of what the rasterizer draws
        for name in ("rgb", "depth", "alpha", "median_depth"):
            torch.testing.assert_close(part[name], whole[name], rtol=0, atol=1e-6)


def test_occlusion_culling_drops_only_what_the_observed_surface_hides():
    """A wall of small Gaussians at 2 m and a second layer at 3.5 m behind it: with the observed depth of
    the wall, the hidden layer is culled and the render is unchanged; where the depth is invalid (unknown)
    or the wall has a window (observed depth 3.5 m), the layer behind stays."""
    cam = pose()
    K = intrinsics(S)
    xs = torch.linspace(-2.5, 2.5, 60)
    grid = torch.stack(torch.meshgrid(xs, xs, indexing="xy"), dim=-1).reshape(-1, 2)
    n = len(grid)
    means = torch.cat([torch.cat([grid, torch.full((n, 1), z)], 1) for z in (2.0, 3.5)])
    gmap = GaussianMap({"means": means, "quats": torch.tensor([[1.0, 0, 0, 0]]).repeat(2 * n, 1),
                        "log_scales": torch.full((2 * n, 3), float(np.log(0.04))),
                        "opacity_logits": torch.full((2 * n,), 6.0), "f_dc": torch.randn(2 * n, 3)})
    depth = torch.full((S, S), 2.0)
    p = gmap.params
    frustum = frustum_rows(p["means"], p["log_scales"], cam, K, S, S)
    culled = frustum_rows(p["means"], p["log_scales"], cam, K, S, S, depth, 0.1, 8)
    behind = culled >= n
    assert behind.sum() < 0.2 * (frustum >= n).sum()  # most of the hidden layer is gone
    viewmat = torch.eye(4)
    Kt = torch.from_numpy(K.astype(np.float32))
    full = rasterize(*activate(gmap.rows(frustum)), viewmat, Kt, S, S, backend="torch")
    part = rasterize(*activate(gmap.rows(culled)), viewmat, Kt, S, S, backend="torch")
    torch.testing.assert_close(part.rgb, full.rgb, rtol=0, atol=1e-3)
    depth[:, : S // 2] = 0.0  # unknown on the left: nothing is hidden there
    depth[:8, S // 2:] = 3.5  # a window in the wall at the top right
    kept = frustum_rows(p["means"], p["log_scales"], cam, K, S, S, depth, 0.1, 8)
    assert torch.equal(kept, _frustum_rows_torch(p["means"], p["log_scales"], cam, K, S, S, depth, 0.1, 8))
    kept_behind = means[kept[kept >= n]]
    assert (kept_behind[:, 0] < 0).sum() > 0.9 * (means[frustum[frustum >= n]][:, 0] < 0).sum()
    assert ((kept_behind[:, 0] > 0.5) & (kept_behind[:, 1] < -1.5)).any()  # seen through the window


def test_far_depth_kernel_and_cpu_culling_match_the_torch_version():
    """``_mapper_numba.far_depth`` is ``gaussians._far_depth`` bit for bit (windows clipped at the border,
    invalid pixels = inf), and the CPU occlusion culling (numba) keeps exactly the rows of the torch one."""
    rng = np.random.default_rng(3)
    depth = torch.from_numpy((1.0 + 3.0 * rng.random((S, S + 7))).astype(np.float32))
    depth[torch.from_numpy(rng.random((S, S + 7)) < 0.02)] = 0.0
    for r in (0, 1, 3, 8, 2 * S):
        assert torch.equal(torch.from_numpy(far_depth(depth.numpy(), r)), _far_depth(depth, r))
    gmap = _cloud(3000, seed=4)
    p = gmap.params
    K = intrinsics(S)
    depth = torch.from_numpy((0.5 + 2.0 * rng.random((S, S))).astype(np.float32))
    depth[:, :5] = 0.0
    for cam in (pose(), pose(0.3, -0.2, 40.0)):
        want = frustum_rows(p["means"], p["log_scales"], cam, K, S, S, depth, 0.1, 8)
        got = _frustum_rows_torch(p["means"], p["log_scales"], cam, K, S, S, depth, 0.1, 8)
        assert len(want) > 100 and torch.equal(got, want)
        # testing only the rows of the frustum (no depth) and the last 500, as the mapper does after
        # densifying, keeps the same rows as the whole map; on CPU (numba) and in torch alike
        frustum = frustum_rows(p["means"][:2500], p["log_scales"][:2500], cam, K, S, S)
        candidates = torch.cat([frustum, torch.arange(2500, 3000)])
        some = frustum_rows(p["means"], p["log_scales"], cam, K, S, S, depth, 0.1, 8, candidates)
        assert torch.equal(some, want)
        subset = _frustum_rows_torch(p["means"][candidates], p["log_scales"][candidates], cam, K, S, S, depth,
                                     0.1, 8)  # what other devices do with candidates
        assert torch.equal(candidates[subset], want)
        assert len(frustum_rows(p["means"], p["log_scales"], cam, K, S, S, depth, 0.1, 8,
                                candidates[:40])) < 40  # and nothing outside the candidates


def test_cpu_culling_of_centres_in_the_image_matches_the_torch_version():
    """The CPU kernel skips the screen radius of a centre in the image unless the observed depth would hide
    it: Gaussians in front of the camera, centres in the image and around it, footprints from well under to
    well over the depth window, in front of and behind the observed surface, keep exactly the torch rows,
    with and without the depth."""
    g = torch.Generator().manual_seed(7)
    n = 4000
    z = 0.5 + 4.0 * torch.rand(n, generator=g)
    xy = (torch.rand(n, 2, generator=g) - 0.5) * 2.6 * z[:, None]  # about 1.3 x the 90 deg field of view
    means = torch.cat([xy, z[:, None]], 1)
    log_scales = torch.log(0.003 + 0.6 * torch.rand(n, 3, generator=g) ** 2)  # radii from 1 px to ~100 px
    K = intrinsics(S)
    depth = torch.from_numpy((0.4 + 3.0 * np.random.default_rng(8).random((S, S))).astype(np.float32))
    depth[:4] = 0.0
    for observed in (None, depth):
        want = _frustum_rows_torch(means, log_scales, pose(), K, S, S, observed, 0.1, 8)
        got = frustum_rows(means, log_scales, pose(), K, S, S, observed, 0.1, 8)
        assert torch.equal(got, want)
        some = frustum_rows(means, log_scales, pose(), K, S, S, observed, 0.1, 8, torch.arange(0, n, 3))
        assert torch.equal(some, want[want % 3 == 0])
    hidden = len(frustum_rows(means, log_scales, pose(), K, S, S)) - len(want)
    assert 200 < hidden < n // 2  # the depth hides some of them, and not all


def test_row_adam_is_adam_on_trained_rows_and_leaves_the_others_alone():
    gmap, ref = _cloud(50, seed=1), _cloud(50, seed=1)
    lr = LearningRates()
    ours, torch_adam = RowAdam(gmap, lr, 1e-15), ref.make_optimizer(lr, 1e-15)
    g = torch.Generator().manual_seed(2)
    every = torch.arange(50)
    for _ in range(4):  # every row trained: exactly torch's Adam
        grads = {n: torch.randn(ref.params[n].shape, generator=g) for n in PARAM_NAMES}
        for n in PARAM_NAMES:
            ref.params[n].grad = grads[n].clone()
        torch_adam.step()
        ours.step(every, grads)
    for n in PARAM_NAMES:
        torch.testing.assert_close(gmap.params[n], ref.params[n], rtol=1e-5, atol=1e-6)
    before = {n: t.detach().clone() for n, t in gmap.params.items()}
    trained = torch.tensor([3, 17, 40])
    ours.step(trained, {n: torch.randn((3, *before[n].shape[1:]), generator=g) for n in PARAM_NAMES})
    untouched = torch.ones(50, dtype=torch.bool)
    untouched[trained] = False
    for n in PARAM_NAMES:
        assert torch.equal(gmap.params[n][untouched], before[n][untouched])  # bit for bit
        assert not torch.equal(gmap.params[n][trained], before[n][trained])
    assert ours.steps.tolist().count(5) == 3 and ours.steps.tolist().count(4) == 47


def test_row_adam_state_follows_append_and_keep():
    """Appends (into spare capacity and with reallocation) and prunes keep each row's moments and step
    count with its row: the same as concatenating and masking the state tensors."""
    gmap = _cloud(10, seed=5)
    adam = RowAdam(gmap, LearningRates(), 1e-15)
    g = torch.Generator().manual_seed(6)

    def state() -> dict[str, torch.Tensor]:  # the moments of one parameter and the step counts
        return {"m": adam.exp_avg["means"].clone(), "v": adam.exp_avg_sq["means"].clone(),
                "steps": adam.steps.clone()}

    ref = state()
    for m, drop in ((5, 0), (1, 3), (40, 0), (0, 7), (2, 1), (100, 20)):
        if m:  # into spare capacity after a prune, or with a reallocation
            gmap.append(_cloud(m, seed=m).params)
        adam.append(m)
        ref = {k: torch.cat([t, t.new_zeros((m, *t.shape[1:]))]) for k, t in ref.items()}
        n = len(gmap)
        rows = torch.randperm(n, generator=g)[: n // 2]
        grads = {name: torch.randn((len(rows), *t.shape[1:]), generator=g) for name, t in gmap.params.items()}
        adam.step(rows, grads)
        after = state()
        assert torch.equal(after["steps"][rows], ref["steps"][rows] + 1)
        others = torch.ones(n, dtype=torch.bool)
        others[rows] = False
        for k in ref:
            assert torch.equal(after[k][others], ref[k][others])
        ref = after
        keep = torch.ones(n, dtype=torch.bool)
        keep[torch.randperm(n, generator=g)[:drop]] = False
        gmap.keep(keep)
        adam.keep(keep)
        ref = {k: t[keep] for k, t in ref.items()}
        assert len(adam) == len(gmap) and all(torch.equal(state()[k], ref[k]) for k in ref)
        assert all(t.is_contiguous() for t in (*adam.exp_avg.values(), *adam.exp_avg_sq.values()))


def test_row_adam_step_nonzero_is_step_on_the_rows_with_a_gradient():
    """The fused CPU step: the rows whose gradient is zero in every parameter are left alone (step count
    too); the others get exactly :meth:`RowAdam.step` (bit for bit)."""
    gmaps = [_cloud(300, seed=7) for _ in range(2)]
    adams = [RowAdam(gm, LearningRates(), 1e-15) for gm in gmaps]
    g = torch.Generator().manual_seed(8)
    start = torch.randint(0, 50000, (300,), generator=g, dtype=torch.int32)  # rows with a long history
    for adam in adams:
        adam.steps[:] = start
        adam._calls = 50000  # the bound on the step counts that step_nonzero's bias tables rely on
    for _ in range(5):
        rows = torch.randperm(300, generator=g)[:120]
        grads = {n: torch.randn((120, *t.shape[1:]), generator=g) for n, t in gmaps[0].params.items()}
        zero = torch.rand(120, generator=g) < 0.3
        for n in grads:
            grads[n][zero] = 0.0
        grads["f_dc"][:3] = 1e-30  # non-zero in one parameter only: stepped
        touched = adams[0].step_nonzero(rows, grads)
        assert torch.equal(touched, ~zero | (torch.arange(120) < 3))
        adams[1].step(rows[touched], {n: t[touched] for n, t in grads.items()})
        assert torch.equal(adams[0].steps, adams[1].steps)
        for n in PARAM_NAMES:
            assert torch.equal(gmaps[0].params[n], gmaps[1].params[n])
            assert torch.equal(adams[0].exp_avg[n], adams[1].exp_avg[n])
            assert torch.equal(adams[0].exp_avg_sq[n], adams[1].exp_avg_sq[n])


def _left_then_right(sparse_adam: bool) -> tuple[torch.Tensor, torch.Tensor]:
    """Map the left part of the wall, then only its right part; the raw parameters of the left
    Gaussians (x < -0.5 m) after the first right frame and after ten more."""
    cfg = MapperConfig(schedule=Schedule(1, 1, 2), sparse_adam=sparse_adam, pixel_stride=2)
    mapper = Mapper(intrinsics(S), S, S, cfg, backend="torch")
    left, right = pose(tx=-3.0), pose(tx=3.0)
    for _ in range(3):
        mapper.add_frame(*observe(left, S), left)
    mapper.add_frame(*observe(right, S), right)  # the last keyframe (left) may still be trained here

    def left_rows() -> torch.Tensor:
        p = mapper.gaussians.params
        rows = torch.nonzero(p["means"][:, 0] < -0.5, as_tuple=True)[0]
        flat = torch.cat([p[n].detach()[rows].reshape(len(rows), -1) for n in PARAM_NAMES], dim=1)
        return flat[torch.argsort(flat[:, 0])]

    snapshot = left_rows()
    for _ in range(10):
        mapper.add_frame(*observe(right, S), right)
    return snapshot, left_rows()


def test_what_is_out_of_view_is_not_forgotten_or_moved():
    before, after = _left_then_right(sparse_adam=True)
    assert len(before) > 50 and torch.equal(before, after)
    # the release's dense Adam keeps moving them on stale momentum (why sparse_adam exists)
    before, after = _left_then_right(sparse_adam=False)
    assert before.shape == after.shape and not torch.equal(before, after)


def test_the_map_appends_into_spare_rows_and_earlier_views_stay_as_they_were():
    """Appends (into spare capacity and with reallocation) and prunes give the parameters that concatenating
    and masking give; each parameter stays a contiguous leaf; and a view of the map taken before (as a
    replan's snapshot holds) is not changed by them."""
    gmap = _cloud(10, seed=7)
    ref = {name: t.detach().clone() for name, t in gmap.params.items()}
    g = torch.Generator().manual_seed(8)
    for m, drop in ((5, 0), (1, 3), (40, 0), (0, 7), (2, 1), (100, 20)):
        before = {name: t.detach() for name, t in gmap.params.items()}  # views, as MapSnapshot keeps them
        frozen = {name: t.clone() for name, t in before.items()}
        if m:
            extra = _cloud(m, seed=m).params
            gmap.append(extra)
            ref = {name: torch.cat([t, extra[name].detach()]) for name, t in ref.items()}
        keep = torch.ones(len(gmap), dtype=torch.bool)
        keep[torch.randperm(len(gmap), generator=g)[:drop]] = False
        gmap.keep(keep)
        ref = {name: t[keep] for name, t in ref.items()}
        for name, t in gmap.params.items():
            assert torch.equal(t.detach(), ref[name])
            assert t.is_leaf and t.requires_grad and t.is_contiguous()
            assert torch.equal(before[name], frozen[name])
