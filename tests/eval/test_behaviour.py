"""Multi-room measures (eval/behaviour.py): action shares, rooms entered, per-room coverage, the sweep
ceiling shares, Tab. III path fractions, and the trajectory figure."""

import numpy as np
import pytest

from activesplat.eval.behaviour import (
    BehaviourConfig,
    at_path_fractions,
    completion_gain,
    episode_behaviour,
    relative_to_ceiling,
    room_completion,
    rooms_entered,
    rotation_causes,
    rotation_pct,
    steps_to_reach,
)


def test_rotation_share_counts_turns_and_tilts():
    actions = ["turn_left", "move_forward", "look_up", "look_down", "turn_right", "move_forward"]
    assert rotation_pct(actions) == pytest.approx(100 * 4 / 6)
    assert rotation_pct([]) == 0.0


def test_rotation_causes_count_turns_and_tilts_by_cause():
    actions = ["turn_left", "look_down", "move_forward", "turn_right", "turn_right", "turn_left"]
    causes = ["bootstrap", "bootstrap", "path", "arrival", "arrival", "path"]
    assert rotation_causes(actions, causes) == {"bootstrap": 2, "arrival": 2, "path": 1}


def test_completion_gain_attributes_each_frame_to_the_action_before_it():
    actions = ["turn_left", "move_forward", "look_down", "turn_right"]
    causes = ["bootstrap", "path", "arrival", "arrival"]
    gain = completion_gain(np.array([10, 5, 0, 3, 2]), actions, causes, n_gt_points=100)
    assert gain["by_cause"] == {"start": {"actions": 0, "completion_pct": 10.0},
                                "arrival": {"actions": 2, "completion_pct": 5.0},
                                "bootstrap": {"actions": 1, "completion_pct": 5.0},
                                "path": {"actions": 1, "completion_pct": 0.0}}
    assert gain["by_action"]["turn"] == {"actions": 2, "completion_pct": 7.0}
    assert gain["by_action"]["tilt"] == {"actions": 1, "completion_pct": 3.0}
    assert gain["by_action"]["move_forward"]["actions"] == 1
    with pytest.raises(ValueError, match="one frame more"):
        completion_gain(np.zeros(4), actions, causes, 100)


def test_rooms_entered_needs_the_inset_and_skips_corridors(house):
    # start in the living room's second rectangle, walk through the corridor, stop in the bedroom's doorway
    path = np.array([[1.0, 4.0], [3.0, 1.5], [4.8, 2.5], [5.7, 2.5]])
    assert rooms_entered(house, path, inset_m=0.5) == ["living"]
    assert rooms_entered(house, np.vstack([path, [[6.5, 2.5]]]), 0.5) == ["living", "bedroom"]
    assert rooms_entered(house, path, inset_m=0.0) == ["living", "bedroom"]
    # the open boundary between the living room's two rectangles (z = 3 for 0 <= x <= 2) is no wall
    assert rooms_entered(house, np.array([[1.0, 3.1]]), inset_m=0.5) == ["living"]
    assert rooms_entered(house, np.array([[2.6, 2.8]]), inset_m=0.5) == []  # 0.2 m from a real wall


def test_room_completion_labels_points_by_the_rectangles_of_a_room(house):
    gt = np.array([[1.0, 0.0, 1.0], [1.0, 1.0, 4.0], [7.0, 0.0, 1.0], [7.0, 2.0, 2.0], [20.0, 0.0, 0.0]])
    done = np.array([True, False, True, True, True])  # the last point is outside the house
    rooms = room_completion(house, gt, done)
    assert rooms["living"] == {"points": 2, "completion_ratio_pct": 50.0}
    assert rooms["bedroom"] == {"points": 2, "completion_ratio_pct": 100.0}
    assert rooms["corridor"] == {"points": 0, "completion_ratio_pct": None}


def _curve(values, paths):
    return [{"step": 50 * (i + 1), "completion_ratio_pct": v, "completion_cm": 100 - v, "path_length_m": p}
            for i, (v, p) in enumerate(zip(values, paths, strict=True))]


def test_path_fractions_take_the_last_point_within_the_allowed_path():
    curve = _curve([10, 40, 60, 70, 80, 85], [0.0, 2.0, 5.0, 6.0, 10.0, 10.0])
    rows = at_path_fractions(curve, (0.25, 0.5, 0.75, 1.0))
    assert [r["completion_ratio_pct"] for r in rows] == [40, 60, 70, 85]
    assert rows[-1]["step"] == 300 and rows[0]["path_length_m"] == 2.5


def test_steps_to_reach_and_shares_of_the_ceiling():
    curve = _curve([50, 80, 90, 95], [1, 2, 3, 4])
    assert steps_to_reach(curve, 85) == 150 and steps_to_reach(curve, 99) is None
    metrics = {"completion_ratio_pct": 95.0, "curve": curve,
               "rooms": {"completion": {"a": {"points": 1000, "completion_ratio_pct": 45.0},
                                        "b": {"points": 1000, "completion_ratio_pct": 99.0},
                                        "tiny": {"points": 100, "completion_ratio_pct": 10.0}}}}
    ceiling = {"completion_ratio_pct": 100.0,
               "rooms": {"a": {"points": 1000, "completion_ratio_pct": 90.0},
                         "b": {"points": 1000, "completion_ratio_pct": 99.0},
                         "tiny": {"points": 100, "completion_ratio_pct": 100.0}}}
    rel = relative_to_ceiling(metrics, ceiling, BehaviourConfig(min_room_points=200))
    assert rel["of_ceiling_pct"] == 95.0
    assert rel["steps_to_90_pct_ceiling"] == 150 and rel["steps_to_95_pct_ceiling"] == 200
    assert rel["room_of_ceiling_pct"] == {"a": 50.0, "b": 100.0}  # "tiny" has too few points to rank
    assert rel["worst_room"] == "a" and rel["worst_room_of_ceiling_pct"] == 50.0
    assert relative_to_ceiling({"steps": 5}, ceiling) == {}  # no ground truth: nothing to compare


def test_episode_behaviour_of_a_house(house):
    out = episode_behaviour(["turn_left", "move_forward"], np.array([[1.0, 1.0], [1.0, 1.25]]), house,
                            np.array([[1.0, 0.0, 1.0]]), np.array([True]))
    assert out["rooms_total"] == 2 and out["rooms_entered"] == 1 and out["rotation_pct"] == 50.0
    assert out["rooms"]["entered"] == ["living"]
    assert out["rooms"]["completion"]["living"]["completion_ratio_pct"] == 100.0


def test_trajectory_figure(tmp_path, house):
    from activesplat.sim.navmap import NavMap
    from activesplat.viz.trajectory import draw_trajectory

    grid = np.ones((180, 100), bool)
    nav = NavMap(grid, grid, np.ones(grid.shape), grid, np.zeros(2), 0.05, 0.0)
    xz = np.array([[1.0, 1.0], [1.0, 1.0], [1.0, 1.0], [2.0, 1.0], [6.0, 2.0]])
    out = draw_trajectory(tmp_path / "t.png", nav, xz, house, {"living": "50 %"}, title="t")
    assert out.is_file() and out.stat().st_size > 5000


def test_trajectory_figure_is_seen_from_above_like_the_topdown_map(house):
    from activesplat.sim.navmap import NavMap
    from activesplat.viz.trajectory import trajectory_figure

    grid = np.ones((180, 100), bool)
    nav = NavMap(grid, grid, np.ones(grid.shape), grid, np.zeros(2), 0.05, 0.0)
    ax = trajectory_figure(nav, np.array([[1.0, 1.0], [6.0, 2.0]]), house).axes[0]
    top, bottom = ax.get_ylim()[1], ax.get_ylim()[0]
    assert (top, bottom) == (0.0, 5.0)  # z grows downwards (topdown.png: world z down, as the grid rows)
    assert ax.get_xlim() == (0.0, 9.0)
