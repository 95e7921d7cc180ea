"""Replay an action log in the simulator and measure what the sensor observed (docs/protocol.md §6)."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from activesplat.errors import EpisodeError
from activesplat.eval.coverage import CoverageAccumulator, CoverageConfig


def replay_coverage(scene, start_pose: np.ndarray, actions: Iterable[str], cfg: CoverageConfig | None = None,
                    expected_poses: np.ndarray | None = None, sim_config=None,
                    with_completed: bool = False, with_gain: bool = False) -> dict:
    """Completion metrics and path length of an episode, from its start pose and actions alone.

    After the reset and after every action, the ground-truth depth at `cfg.resolution` (same field of
    view) is back-projected; `expected_poses` (N+1, 4, 4), when given, must match the replayed poses
    (a mismatch means the log does not belong to this scene / start / simulator version).
    `with_completed`: add ``completed``, the per-ground-truth-point mask the completion ratio counts.
    `with_gain`: add ``gain_by_frame``, the ground-truth points each frame observed first
    (`CoverageAccumulator.gain_by_frame`).
    """
    from activesplat.geometry import intrinsics
    from activesplat.sim import SimConfig, Simulator

    cfg = cfg or CoverageConfig()
    sim_config = sim_config or SimConfig()
    sim = Simulator(scene, start=start_pose, config=sim_config)
    K = intrinsics(cfg.resolution, cfg.resolution, sim_config.hfov_deg)
    acc = CoverageAccumulator(scene.sample_surface(cfg.n_gt_points, seed=cfg.seed), cfg)
    poses = [sim.pose]  # a new simulator stands at its start: the reset pose, no frame rendered
    forward = 0
    for action in actions:
        sim.act(action)
        forward += action == "move_forward"
        poses.append(sim.pose)
    for pose in poses:
        acc.add_frame(sim.render(pose, cfg.resolution, cfg.resolution)[1], pose, K)
    if expected_poses is not None:
        expected = np.asarray(expected_poses)
        n = min(len(expected), len(poses))
        same = np.all(np.isclose(expected[:n], np.stack(poses[:n]), atol=1e-4), axis=(1, 2))
        if not same.all():
            bad = int(np.argmin(same))
            raise EpisodeError(f"replayed pose at step {bad} differs from poses.txt: the actions do not "
                               f"replay to the recorded trajectory")
    metrics = acc.metrics()
    metrics["path_length_m"] = forward * sim_config.forward_step
    metrics["steps"] = len(poses) - 1
    if with_completed:
        metrics["completed"] = acc.completed()
    if with_gain:
        metrics["gain_by_frame"] = acc.gain_by_frame()
    return metrics
