import numpy as np
import pytest

from activesplat.eval.coverage import CoverageAccumulator, CoverageConfig
from activesplat.geometry import backproject, camera_pose, intrinsics


def _plane_depth(K, w, h, dist):
    """z-depth of a fronto-parallel plane at `dist`."""
    return np.full((h, w), dist, np.float32)


def test_backproject_plane_lies_on_plane():
    K = intrinsics(32, 32, 90.0)
    pose = camera_pose([1.0, 1.25, 0.0], 0.0)  # looks along +z
    pts = backproject(_plane_depth(K, 32, 32, 2.0), pose, K)
    assert pts.shape == (32 * 32, 3)
    assert np.allclose(pts[:, 2], 2.0)
    # 90 deg fov: the plane patch spans +-2 m around the camera's x and y
    assert pts[:, 0].min() == pytest.approx(1.0 - 2.0 + 2.0 / 32, abs=1e-6)
    assert pts[:, 1].max() == pytest.approx(1.25 + 2.0 - 2.0 / 32, abs=1e-6)


def test_coverage_of_a_plane_seen_partly():
    rng = np.random.default_rng(0)
    # GT: points on the plane z = 2, x in [-4, 4], y in [0, 2.5]; the camera sees only x in ~[-2, 2]
    gt = np.stack([rng.uniform(-4, 4, 5000), rng.uniform(0, 2.5, 5000), np.full(5000, 2.0)], 1)
    K = intrinsics(128, 128, 90.0)
    acc = CoverageAccumulator(gt, CoverageConfig(batch_frames=1))
    m0 = acc.metrics()
    assert m0["completion_ratio_pct"] == 0 and m0["completion_cm"] == pytest.approx(100.0)
    assert m0["completion_cm_uncapped"] is None
    acc.add_frame(_plane_depth(K, 128, 128, 2.0), camera_pose([0.0, 1.25, 0.0], 0.0), K)
    m = acc.metrics()
    seen = (np.abs(gt[:, 0]) < 1.95) & (gt[:, 1] < 1.25 + 1.95)
    expected_ratio = 100.0 * ((np.abs(gt[:, 0]) < 2.0 + 0.05) & (gt[:, 1] < 3.25 + 0.05)).mean()
    assert m["completion_ratio_pct"] >= 100.0 * seen.mean()
    assert m["completion_ratio_pct"] <= expected_ratio + 1e-9
    # unseen points at |x| up to 4 m contribute their true distance when uncapped, the 1 m cap otherwise
    assert m["completion_cm_uncapped"] > m["completion_cm"] * 0.5
    assert m["completion_cm"] < 100.0


def test_running_minimum_is_order_and_batch_independent():
    rng = np.random.default_rng(1)
    gt = rng.uniform(-3, 3, (2000, 3))
    K = intrinsics(64, 64, 90.0)
    frames = [(rng.uniform(1, 4, (64, 64)).astype(np.float32), camera_pose(rng.uniform(-1, 1, 3), y, 0.1))
              for y in np.linspace(0, 6, 7)]
    results = []
    for batch, order in [(1, frames), (3, frames[::-1]), (100, frames)]:
        acc = CoverageAccumulator(gt, CoverageConfig(batch_frames=batch))
        for d, p in order:
            acc.add_frame(d, p, K)
        results.append(acc.metrics())
    for r in results[1:]:
        assert r["completion_cm"] == pytest.approx(results[0]["completion_cm"], rel=1e-12)
        assert r["completion_ratio_pct"] == results[0]["completion_ratio_pct"]


def test_running_minimum_is_the_exact_nearest_distance_below_the_cap():
    """The batches search each GT point only as far as could lower its running minimum (up to the threshold
    once it is completed, else up to the cap): the minimum is still the nearest observed point's distance
    wherever that is under the cap, and inf elsewhere."""
    from scipy.spatial import cKDTree

    from activesplat.geometry import backproject

    rng = np.random.default_rng(3)
    gt = rng.uniform(-3, 3, (3000, 3))
    K = intrinsics(40, 40, 90.0)
    frames = [(rng.uniform(1, 4, (40, 40)).astype(np.float32), camera_pose(rng.uniform(-1, 1, 3), y, 0.1))
              for y in np.linspace(0, 6, 10)]
    cfg = CoverageConfig(batch_frames=2, threshold_m=0.2, cap_m=0.6)
    acc = CoverageAccumulator(gt, cfg)
    for d, p in frames:
        acc.add_frame(d, p, K)
    acc.flush()
    true, _ = cKDTree(np.concatenate([backproject(d, p, K) for d, p in frames])).query(gt)
    assert 0.2 < np.mean(true < cfg.threshold_m) < 0.8 and np.any(true > cfg.cap_m)  # all three cases occur
    np.testing.assert_array_equal(acc.min_dist, np.where(true < cfg.cap_m, true, np.inf))
    # and the first frame that came within the threshold of each GT point, frame by frame
    first = np.full(len(gt), -1)
    for f, (d, p) in enumerate(frames):
        near, _ = cKDTree(backproject(d, p, K)).query(gt)
        first[(first < 0) & (near < cfg.threshold_m)] = f
    assert len(np.unique(first)) == len(frames) + 1  # every frame completed some points first
    np.testing.assert_array_equal(acc.first_frame, first)


def test_first_frame_of_each_point_is_batch_independent_and_sums_to_the_ratio():
    rng = np.random.default_rng(2)
    gt = rng.uniform(-3, 3, (3000, 3))
    K = intrinsics(48, 48, 90.0)
    frames = [(rng.uniform(1, 4, (48, 48)).astype(np.float32), camera_pose(rng.uniform(-1, 1, 3), y, 0.1))
              for y in np.linspace(0, 6, 9)]
    gains = []
    for batch in (1, 4, 100):
        acc = CoverageAccumulator(gt, CoverageConfig(batch_frames=batch, threshold_m=0.2))
        ratios = []
        for d, p in frames:
            acc.add_frame(d, p, K)
            ratios.append(acc.metrics(uncapped=False)["completion_ratio_pct"])
        gain = acc.gain_by_frame()
        assert gain.shape == (len(frames),) and gain.sum() == acc.completed().sum()
        # the cumulative gain is the completion curve at every frame
        assert np.allclose(100.0 * np.cumsum(gain) / len(gt), ratios)
        gains.append(gain)
    assert gains[0].min() > 0  # every frame completed something, so the test says something
    for g in gains[1:]:
        assert np.array_equal(g, gains[0])


def test_invalid_depth_is_ignored():
    gt = np.zeros((10, 3))
    acc = CoverageAccumulator(gt)
    K = intrinsics(16, 16, 90.0)
    acc.add_frame(np.zeros((16, 16), np.float32), np.eye(4), K)
    assert acc.metrics()["completion_cm"] == pytest.approx(100.0)


def test_unique_first_is_numpy_unique_with_first_indices():
    from activesplat.geometry import unique_first

    rng = np.random.default_rng(4)
    for keys in (np.zeros(0, np.int64), np.array([7]), np.array([3, 1, 3, 2, 1, 1]),
                 rng.integers(0, 60, 5000), rng.integers(-2**62, 2**62, 3000)):
        expected = np.unique(keys, return_index=True)
        got = unique_first(keys)
        np.testing.assert_array_equal(got[0], expected[0])
        np.testing.assert_array_equal(got[1], expected[1])


def test_voxel_keys_is_the_numpy_formula():
    """The compiled voxel keys are floor(x / size) + 2^20 per axis in float64, packed by 21 bits, as the
    numpy expression gives them, for float32 and float64 points, on voxel boundaries and strided input."""
    from activesplat.geometry import voxel_keys

    def formula(pts, size):
        v = np.floor(np.asarray(pts, np.float64) / size).astype(np.int64) + (1 << 20)
        return (v[:, 0] << 42) | (v[:, 1] << 21) | v[:, 2]

    rng = np.random.default_rng(5)
    for dtype in (np.float64, np.float32):
        pts = ((rng.random((4000, 3)) - 0.5) * 60).astype(dtype)
        pts[:500] = (np.round(pts[:500] / 0.02) * 0.02).astype(dtype)  # on (or next to) voxel boundaries
        for size in (0.02, 0.05, 0.013, 1.0):
            np.testing.assert_array_equal(voxel_keys(pts, size), formula(pts, size))
        np.testing.assert_array_equal(voxel_keys(pts[::3], 0.05), formula(pts[::3], 0.05))
    ints = np.array([[1, -2, 3]])  # integer input is taken as float64
    np.testing.assert_array_equal(voxel_keys(ints, 0.5), formula(ints, 0.5))
    assert voxel_keys(np.zeros((0, 3)), 0.1).shape == (0,)
    with pytest.raises(ValueError, match="M, 3"):
        voxel_keys(np.zeros(3), 0.1)


def test_metrics_of_a_toy_mesh_by_hand():
    """Completion of a toy mesh computed by brute force: 200k-style GT sample (area-uniform, seeded) on a
    2 x 2 m wall at z = 2 and a 0.5 m^2 triangle 3 m behind it; two 16 x 16 frames (the first sees depth on
    its left half only). cm = mean of min(distance, 1 m), ratio = share below 5 cm, uncapped = plain mean."""
    import trimesh
    from scipy.spatial.distance import cdist

    from activesplat.sim.scene import Scene

    v = np.array([[-1, -1, 2], [1, -1, 2], [1, 1, 2], [-1, 1, 2], [-1, -1, 5], [0, -1, 5], [-1, 0, 5]], float)
    scene = Scene("toy", trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3], [4, 5, 6]], process=False), 0.0, 10)
    gt = scene.sample_surface(8000, seed=3)
    assert np.array_equal(gt, scene.sample_surface(8000, seed=3))
    assert np.mean(gt[:, 2] > 3) == pytest.approx(0.5 / 4.5, abs=0.012)  # area-uniform over the faces
    K = intrinsics(16, 16, 90.0)
    left = np.zeros((16, 16), np.float32)
    left[:, :8] = 2.0
    shifted = np.eye(4)
    shifted[0, 3] = 0.5
    frames = [(left, np.eye(4)), (np.full((16, 16), 2.0, np.float32), shifted)]
    points = []
    for depth, pose in frames:  # pixel centres at integer + 0.5, principal point at the image centre
        r, c = np.nonzero(depth > 0)
        z = depth[r, c].astype(float)
        points.append(np.stack([(c + 0.5 - 8) / K[0, 0] * z + pose[0, 3], (r + 0.5 - 8) / K[1, 1] * z, z], 1))
    dist = cdist(gt, np.concatenate(points)).min(axis=1)
    acc = CoverageAccumulator(gt, CoverageConfig(far_voxel_m=1e-3))
    for depth, pose in frames:
        acc.add_frame(depth, pose, K)
    m = acc.metrics()
    assert 0 < m["completion_ratio_pct"] < 100 and dist.max() > 1.0  # capped and uncapped differ
    assert m["completion_ratio_pct"] == pytest.approx(100 * np.mean(dist < 0.05), abs=1e-9)
    assert m["completion_cm"] == pytest.approx(100 * np.minimum(dist, 1.0).mean(), rel=1e-9)
    assert m["completion_cm_uncapped"] == pytest.approx(100 * dist.mean(), rel=1e-6)
    assert m["within_cap_pct"] == pytest.approx(100 * np.mean(dist < 1.0))
    # thinning beyond the cap (0.3 m voxels here, the frames' points being ~12 cm apart): each such
    # distance at most a voxel diagonal too long, the others exact
    coarse = CoverageAccumulator(gt, CoverageConfig(far_voxel_m=0.3))
    for depth, pose in frames:
        coarse.add_frame(depth, pose, K)
    coarse.flush()
    uncapped, far = coarse._uncapped(), dist >= 1.0
    np.testing.assert_allclose(uncapped[~far], dist[~far], rtol=1e-12)
    excess = uncapped[far] - dist[far]
    assert excess.min() >= -1e-12 and 0 < excess.max() <= np.sqrt(3) * 0.3
