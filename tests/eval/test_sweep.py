"""The exhaustive-sweep reference on a box room, where everything is visible from the floor."""

import numpy as np
import pytest

from activesplat.errors import InvalidInputError
from activesplat.eval.coverage import CoverageConfig
from activesplat.eval.sweep import SweepConfig, exhaustive_sweep, sweep_poses
from activesplat.sim import box_room, load_scene

CFG = SweepConfig(spacing_m=1.0, yaw_step_deg=90.0, pitches_deg=(-45.0, 0.0, 45.0))
COV = CoverageConfig(n_gt_points=20_000)


def test_sweep_poses_stand_on_a_grid_of_the_navigable_space_and_look_all_around():
    scene = box_room(4.0, 3.0)
    poses = sweep_poses(scene, cfg=CFG)
    assert len(poses) % 12 == 0 and len(poses) >= 12 * 4
    nav = scene.navmap
    assert nav.is_navigable(poses[:, 0, 3], poses[:, 2, 3]).all()
    # every spot: 4 yaws x 3 pitches; the optical axes' pitch (forward y) spans -45..45 deg
    pitch = np.degrees(np.arcsin(poses[:12, 1, 2]))
    assert sorted(set(np.round(-pitch).astype(int))) == [-45, 0, 45]


def test_the_sweep_of_an_empty_room_sees_nearly_everything():
    m = exhaustive_sweep(box_room(4.0, 3.0), cfg=CFG, coverage_config=COV)
    assert m["completion_ratio_pct"] > 97.0 and m["completion_cm"] < 2.0
    assert m["n_views"] == 12 * m["n_positions"]
    sparse = exhaustive_sweep(box_room(4.0, 3.0), cfg=SweepConfig(spacing_m=1.0, yaw_step_deg=180.0,
                                                                pitches_deg=(0.0,)), coverage_config=COV)
    assert sparse["completion_ratio_pct"] < m["completion_ratio_pct"] - 5.0


def test_bad_sweep_config_is_a_clear_error():
    with pytest.raises(InvalidInputError, match="positive spacing"):
        sweep_poses(box_room(), cfg=SweepConfig(spacing_m=0.0))


def test_the_mapping_ceiling_tour_is_an_episode_of_neighbouring_look_arounds(tmp_path):
    """benchmarks/mapper_ceiling.py: the sweep's poses as a replayable episode, rows walked back and forth."""
    import importlib.util
    from pathlib import Path

    from activesplat.episode import read_episode

    path = Path(__file__).parents[2] / "benchmarks" / "mapper_ceiling.py"
    spec = importlib.util.spec_from_file_location("mapper_ceiling", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    cfg = SweepConfig(spacing_m=1.0, yaw_step_deg=90.0, pitches_deg=(0.0, 30.0))
    n = module.write_tour("small-0", tmp_path / "tour", cfg)
    episode = read_episode(tmp_path / "tour")
    assert n == len(episode.poses) and n % 8 == 0 and n >= 8 * 10
    assert set(episode.actions) == {"turn_left"}  # every frame mapped with the look-around schedule
    assert episode.meta["scene"] == "small-0" and episode.meta["config"]["tour"]["spacing_m"] == 1.0
    positions = episode.poses[::8, [0, 2], 3]
    assert len(np.unique(np.round(positions, 3), axis=0)) == len(positions)  # each grid spot once
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    assert np.median(steps) == pytest.approx(1.0, abs=0.05)
    # back and forth along the rows: half the long moves of the sweep's own row-major order
    grid = sweep_poses(load_scene("small-0"), cfg=cfg)[::8, [0, 2], 3]
    assert (steps > 1.5).sum() <= (np.linalg.norm(np.diff(grid, axis=0), axis=1) > 1.5).sum() // 2


def test_the_sweep_shows_the_progress_bar_of_every_long_command(monkeypatch):
    """`timing.progress_bar`: one step per view, closed at the end; none without `progress`."""
    from activesplat import timing
    from activesplat.eval import sweep

    bars = []

    def recorded(*args, **kwargs):
        bars.append((args, kwargs, timing.progress_bar(*args, **kwargs)))
        return bars[-1][2]

    monkeypatch.setattr(sweep, "progress_bar", recorded)
    cfg = SweepConfig(spacing_m=2.0, yaw_step_deg=180.0, pitches_deg=(0.0,))
    scene = box_room(4.0, 3.0)
    m = exhaustive_sweep(scene, cfg=cfg, coverage_config=CoverageConfig(n_gt_points=1000), progress=True)
    (args, _, bar), = bars
    assert args == (m["n_views"], f"sweep {scene.name}", "view", True)
    assert bar.n == m["n_views"] and bar.disable  # closed
    exhaustive_sweep(box_room(4.0, 3.0), cfg=cfg, coverage_config=CoverageConfig(n_gt_points=1000))
    assert bars[-1][2] is None
