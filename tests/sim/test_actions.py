"""Action geometry of the Habitat protocol (docs/protocol.md §1): 0.065 m steps, 10 deg turns, 15 deg looks
within the documented pitch limits, blocked moves leave the pose unchanged, every action is a step."""

import numpy as np
import pytest

from activesplat.geometry import camera_pose, intrinsics
from activesplat.sim import ACTIONS, SimConfig, Simulator

CFG = SimConfig()


def _yaw_pitch(pose):
    """Heading angle in the floor plane and elevation of the camera's forward (OpenCV +z) axis."""
    forward = pose[:3, 2]
    return np.arctan2(forward[0], forward[2]), np.arcsin(forward[1])


def _centre_pose(scene):
    """Level camera in the middle of the box room, looking along -z."""
    return camera_pose(np.array([2.0, CFG.sensor_height, 1.5]), np.pi, 0.0)


def test_intrinsics_and_pose_conventions(box):
    sim = Simulator(box, seed=0)
    obs = sim.reset()
    assert obs.rgb.shape == (256, 256, 3) and obs.rgb.dtype == np.uint8
    assert obs.depth.shape == (256, 256) and obs.depth.dtype == np.float32
    assert obs.step == 0
    np.testing.assert_allclose(sim.K, [[128, 0, 128], [0, 128, 128], [0, 0, 1]], atol=1e-9)
    rot = obs.pose[:3, :3]
    np.testing.assert_allclose(rot.T @ rot, np.eye(3), atol=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    assert obs.pose[1, 3] == pytest.approx(box.floor_height + CFG.sensor_height)
    assert obs.pose[:3, 1] @ [0.0, 1.0, 0.0] == pytest.approx(-1.0)  # level camera: image y points down
    np.testing.assert_allclose(intrinsics(512, 512, 90.0)[0, 0], 256.0)


def test_move_forward_is_0065_m_along_heading(box):
    sim = Simulator(box, start=_centre_pose(box))
    before = sim.reset().pose
    after = sim.step("move_forward").pose
    delta = after[:3, 3] - before[:3, 3]
    assert np.linalg.norm(delta) == pytest.approx(0.065, abs=1e-12)
    np.testing.assert_allclose(delta / 0.065, before[:3, 2], atol=1e-12)  # along the camera's forward
    np.testing.assert_allclose(after[:3, :3], before[:3, :3], atol=1e-12)


@pytest.mark.parametrize(("action", "sign"), [("turn_left", 1.0), ("turn_right", -1.0)])
def test_turns_are_10_deg_about_up(box, action, sign):
    sim = Simulator(box, start=_centre_pose(box))
    yaw0, _ = _yaw_pitch(sim.reset().pose)
    for k in range(1, 37):
        pose = sim.step(action).pose
        yaw, pitch = _yaw_pitch(pose)
        # atan2(f_x, f_z) grows by 10 deg per turn_left (checked on its own below).
        expected = yaw0 + sign * np.deg2rad(10.0 * k)
        assert np.cos(yaw - expected) == pytest.approx(1.0, abs=1e-12)
        assert pitch == pytest.approx(0.0, abs=1e-12)
        np.testing.assert_allclose(pose[:3, 3], sim.start_pose[:3, 3], atol=1e-12)
    first_left = Simulator(box, start=_centre_pose(box))
    first_left.reset()
    # turn_left is counter-clockwise seen from above (+y): from -z the camera turns towards -x.
    np.testing.assert_allclose(first_left.step("turn_left").pose[:3, 2],
                               [-np.sin(np.deg2rad(10)), 0.0, -np.cos(np.deg2rad(10))], atol=1e-12)


def test_look_up_down_15_deg_within_pitch_limits(box):
    sim = Simulator(box, start=_centre_pose(box))
    sim.reset()
    pitches = [np.rad2deg(_yaw_pitch(sim.step("look_down").pose)[1]) for _ in range(5)]
    np.testing.assert_allclose(pitches, [-15, -30, -45, -45, -45], atol=1e-9)
    pitches = [np.rad2deg(_yaw_pitch(sim.step("look_up").pose)[1]) for _ in range(8)]
    np.testing.assert_allclose(pitches, [-30, -15, 0, 15, 30, 45, 45, 45], atol=1e-9)
    assert sim.step_count == 13  # no-ops at the limit still cost a step
    assert CFG.pitch_min_deg == -45.0 and CFG.pitch_max_deg == 45.0


def test_forward_ignores_pitch_and_stop_changes_nothing(box):
    sim = Simulator(box, start=_centre_pose(box))
    start = sim.reset().pose
    sim.step("look_down")
    pose = sim.step("move_forward").pose
    assert pose[1, 3] == pytest.approx(start[1, 3])  # stays at sensor height
    assert np.linalg.norm(pose[:3, 3] - start[:3, 3]) == pytest.approx(0.065)
    before = sim.pose
    obs = sim.step("stop")
    np.testing.assert_array_equal(obs.pose, before)
    assert obs.step == 3 and not obs.collided


def test_blocked_move_keeps_pose_and_counts(box):
    """Walk into the wall at z = 0: the last allowed position keeps the radius, then no sliding."""
    sim = Simulator(box, start=camera_pose(np.array([1.3, 1.25, 1.5]), np.deg2rad(200.0), 0.0))
    sim.reset()
    obs = [sim.step("move_forward") for _ in range(40)]
    blocked = [o for o in obs if o.collided]
    assert blocked, "the agent walked through the wall"
    first = next(k for k, o in enumerate(obs) if o.collided)
    assert all(o.collided for o in obs[first:])
    for o in blocked:
        np.testing.assert_array_equal(o.pose, obs[first - 1].pose)
    assert obs[-1].step == 40
    assert 0.1 <= obs[first - 1].pose[2, 3] <= 0.1 + 0.065 + 2 * 0.025 * np.sqrt(2) + 0.025


def test_actions_table():
    assert ACTIONS == ("move_forward", "turn_left", "turn_right", "look_up", "look_down", "stop")


def test_act_moves_like_step_without_rendering(box, monkeypatch):
    actions = ["move_forward", "turn_left", "look_down", "move_forward"] + ["move_forward"] * 60
    stepped = Simulator(box, start=_centre_pose(box))
    stepped.reset()
    poses = [stepped.step(a).pose for a in actions]
    acted = Simulator(box, start=_centre_pose(box))
    monkeypatch.setattr(acted, "observe", lambda *a, **k: pytest.fail("act() must not render"))
    collided = [acted.act(a) for a in actions]
    np.testing.assert_allclose(acted.pose, poses[-1])
    assert acted.step_count == len(actions)
    assert any(collided)  # 60 steps forward in a 4 m room reach a wall
