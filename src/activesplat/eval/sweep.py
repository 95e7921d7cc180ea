"""Exhaustive-sweep reference: how much of a scene the sensor can see at all from its navigable space.

Not a policy: no step budget, no map, no collisions. The camera is put on a regular grid over the
agent's reachable navigable space (the component random starts are drawn from) and at every grid point
looks all around, at every pitch the agent can reach; each view is counted with exactly the coverage
protocol of the episodes (docs/protocol.md §6: 128 x 128 ground-truth depth, the same 200k seeded
mesh samples, 1 m cap, 5 cm threshold). The result is the ceiling an explorer can approach within a
budget: the completion ratio is below 100 % because some mesh surface (inside furniture, under beds,
behind shelves) is visible from nowhere the agent can stand.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from activesplat.errors import InvalidInputError
from activesplat.timing import progress_bar


@dataclass
class SweepConfig:
    """Density of the exhaustive sweep (ours: a ceiling needs a dense sampling, not a particular one)."""

    spacing_m: float = 0.5
    """Grid spacing of the standing positions over the navigable space."""
    yaw_step_deg: float = 30.0
    """Yaw increment of the all-around look (the 90 deg field of view overlaps 3x at 30 deg)."""
    pitches_deg: tuple[float, ...] = (-45.0, 0.0, 45.0)
    """Pitches at every yaw: the agent's full tilt range (+-45 deg, docs/protocol.md §1)."""


def sweep_poses(scene, sim_config=None, cfg: SweepConfig | None = None) -> np.ndarray:
    """Camera-to-world poses (M,4,4) of the sweep: grid positions of the largest navigable component x
    yaws x pitches, camera at the sensor height."""
    from activesplat.geometry import camera_pose
    from activesplat.sim import SimConfig

    cfg = cfg or SweepConfig()
    sim_config = sim_config or SimConfig()
    if cfg.spacing_m <= 0 or cfg.yaw_step_deg <= 0 or not cfg.pitches_deg:
        raise InvalidInputError(f"sweep needs a positive spacing and yaw step and some pitches, got {cfg}")
    nav = scene.navmap_for(sim_config)
    k = max(1, int(round(cfg.spacing_m / nav.resolution)))
    cells = np.argwhere(nav.largest)
    # a grid aligned to the component's bounding box, then the cell nearest each grid point's centre
    keep = cells[((cells[:, 0] - cells[:, 0].min()) % k == k // 2) & ((cells[:, 1] - cells[:, 1].min()) % k
                                                                       == k // 2)]
    if len(keep) == 0:
        keep = cells[:1]
    xz = nav.cell_centre(keep[:, 0], keep[:, 1])
    yaws = np.deg2rad(np.arange(0.0, 360.0, cfg.yaw_step_deg))
    poses = []
    for x, z in xz:
        position = np.array([x, nav.floor_height + sim_config.sensor_height, z])
        for yaw in yaws:
            for pitch in cfg.pitches_deg:
                poses.append(camera_pose(position, float(yaw), math.radians(pitch)))
    return np.stack(poses)


def exhaustive_sweep(scene, sim_config=None, cfg: SweepConfig | None = None, coverage_config=None,
                     progress: bool = False, with_completed: bool = False) -> dict:
    """Coverage metrics (the episode keys ``completion_ratio_pct``, ``completion_cm``,
    ``completion_cm_uncapped``) of the exhaustive sweep of ``scene`` (a built-in name or a `Scene`),
    plus ``n_positions`` and ``n_views``; for a built-in house ``rooms``: per room name its ground-truth
    point count and completion ratio (eval/behaviour.py). `with_completed`: add ``completed``, the
    per-ground-truth-point mask the sweep observed (the ceiling point by point, in sample order)."""
    from activesplat.eval.coverage import CoverageAccumulator, CoverageConfig
    from activesplat.geometry import intrinsics
    from activesplat.sim import Scene, SimConfig, load_scene

    cfg = cfg or SweepConfig()
    sim_config = sim_config or SimConfig()
    cov_cfg = coverage_config or CoverageConfig()
    scene = scene if isinstance(scene, Scene) else load_scene(scene)
    poses = sweep_poses(scene, sim_config, cfg)
    sensor = scene.sensor_for(sim_config)
    K = intrinsics(cov_cfg.resolution, cov_cfg.resolution, sim_config.hfov_deg)
    coverage = CoverageAccumulator(scene.sample_surface(cov_cfg.n_gt_points, seed=cov_cfg.seed), cov_cfg)
    bar = progress_bar(len(poses), f"sweep {scene.name}", "view", progress)
    for pose in poses:
        coverage.add_frame(sensor.depth(pose, K, cov_cfg.resolution, cov_cfg.resolution), pose, K)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    out = coverage.metrics()
    if getattr(scene, "house", None) is not None:
        from activesplat.eval.behaviour import room_completion

        out["rooms"] = room_completion(scene.house, coverage.gt, coverage.completed())
    views_per_spot = len(np.arange(0.0, 360.0, cfg.yaw_step_deg)) * len(cfg.pitches_deg)
    out.update({"scene": scene.name, "n_views": int(len(poses)),
                "n_positions": int(len(poses) // views_per_spot),
                "sweep": asdict(cfg)})
    if with_completed:
        out["completed"] = coverage.completed()
    return out


def sweep_ceiling(scene, cache: str | Path | None = None, sim_config=None, cfg: SweepConfig | None = None,
                  coverage_config=None, progress: bool = False) -> dict:
    """exhaustive_sweep of `scene` (a built-in name or mesh path), read from the JSON file `cache` when it
    holds the sweep of the same scene and settings, else computed and written there (a medium house takes
    minutes: ~15,000 views)."""
    from activesplat.episode import write_json_atomic
    from activesplat.eval.coverage import CoverageConfig
    from activesplat.sim import SimConfig, load_scene

    cfg, sim_config = cfg or SweepConfig(), sim_config or SimConfig()
    cov = coverage_config or CoverageConfig()
    name = scene if isinstance(scene, str) else scene.name
    key = json.loads(json.dumps({"scene": str(name), "sweep": asdict(cfg), "coverage": asdict(cov),
                                 "sim": asdict(sim_config)}))
    cache = Path(cache) if cache is not None else None
    if cache is not None and cache.is_file():
        try:
            found = json.loads(cache.read_text())
        except ValueError:
            found = {}
        if found.get("key") == key:
            return found
    out = exhaustive_sweep(load_scene(scene) if isinstance(scene, str) else scene, sim_config, cfg, cov,
                           progress=progress)
    out["key"] = key
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        write_json_atomic(cache, out)
    return out


__all__ = ["SweepConfig", "exhaustive_sweep", "sweep_ceiling", "sweep_poses"]
