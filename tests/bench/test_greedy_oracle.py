"""benchmarks/greedy_oracle.py: a route that knows the house, counted exactly like an episode."""

import numpy as np
from _bench import load_benchmark

from activesplat.eval.coverage import CoverageAccumulator, CoverageConfig
from activesplat.eval.sweep import SweepConfig, exhaustive_sweep
from activesplat.geometry import intrinsics
from activesplat.sim import SimConfig, Simulator, load_scene

SWEEP = SweepConfig(spacing_m=1.0, yaw_step_deg=90.0, pitches_deg=(-45.0, 0.0, 45.0))
COV = CoverageConfig(n_gt_points=4000)


def test_the_oracle_completes_what_the_protocol_counts_within_its_budget():
    oracle = load_benchmark("greedy_oracle")
    scene, sim = load_scene("small-0"), SimConfig()
    gt = np.asarray(scene.sample_surface(COV.n_gt_points, seed=COV.seed), np.float64)
    poses, indptr, indices = oracle.view_sets(scene, sim, SWEEP, COV, gt, cache=None)
    # the per-view sets, together, are exactly what the sweep completes
    union = np.zeros(len(gt), bool)
    union[indices] = True
    sweep = exhaustive_sweep(scene, sim, SWEEP, COV, with_completed=True)
    assert np.array_equal(union, sweep["completed"])
    assert len(indptr) == len(poses) + 1

    route = oracle.OracleRoute(scene, 0, sim, COV, gt, poses, indptr, indices, views_per_spot=12, min_gain=5)
    out = route.run(150, at=[60], first_budget=60)
    assert out["steps"] == len(route.actions) <= 150 and out["stops"] >= 1
    assert 0.0 < out["at"][60] <= out["end"]
    # replayed as an episode (start frame, then one frame per action), the actions see the same
    replay = Simulator(scene, seed=0, config=sim)
    replay.reset()
    K = intrinsics(COV.resolution, COV.resolution, sim.hfov_deg)
    cov = CoverageAccumulator(gt, COV)
    cov.add_frame(replay.depth(replay.pose, COV.resolution, COV.resolution), replay.pose, K)
    for action in route.actions:
        replay.act(action)
        cov.add_frame(replay.depth(replay.pose, COV.resolution, COV.resolution), replay.pose, K)
    assert abs(cov.metrics(uncapped=False)["completion_ratio_pct"] - out["end"]) < 1e-9
