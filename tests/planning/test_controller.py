import math

import numpy as np
import pytest

from activesplat.geometry import camera_pose, heading, pose_yaw_pitch
from activesplat.planning.controller import (
    ControllerConfig,
    PathFollower,
    follow_action,
    level_actions,
    rotation_actions,
    turn_toward,
)

CFG = ControllerConfig()


def _apply(pose, action, cfg=CFG):
    """Minimal kinematics with the simulator's conventions (turn_left raises yaw, look_up raises pitch)."""
    yaw, pitch = pose_yaw_pitch(pose)
    pos = pose[:3, 3].copy()
    if action == "turn_left":
        yaw += math.radians(cfg.turn_deg)
    elif action == "turn_right":
        yaw -= math.radians(cfg.turn_deg)
    elif action == "look_up":
        pitch += math.radians(cfg.look_deg)
    elif action == "look_down":
        pitch -= math.radians(cfg.look_deg)
    elif action == "move_forward":
        pos += cfg.forward_m * heading(yaw)
    return camera_pose(pos, yaw, pitch)


def test_turn_toward_takes_the_short_way():
    assert turn_toward(0.0, math.radians(30), CFG) == ["turn_left"] * 3
    assert turn_toward(0.0, math.radians(-40), CFG) == ["turn_right"] * 4
    assert turn_toward(math.radians(170), math.radians(-170), CFG) == ["turn_left"] * 2


def test_rotation_then_level_returns_to_zero_pitch_and_clamps():
    pose = camera_pose([0, 1.25, 0], 0.0)
    actions = rotation_actions(pose, math.radians(90), math.radians(-80), CFG)
    assert actions.count("turn_left") == 9 and actions.count("look_down") == 3  # clamped at -45
    for a in actions:
        pose = _apply(pose, a)
    yaw, pitch = pose_yaw_pitch(pose)
    assert math.degrees(yaw) == pytest.approx(90, abs=1e-6)
    assert math.degrees(pitch) == pytest.approx(-45, abs=1e-6)
    for a in level_actions(pose, CFG):
        pose = _apply(pose, a)
    assert abs(pose_yaw_pitch(pose)[1]) < 1e-9


def test_follow_reaches_waypoints_in_order():
    pose = camera_pose([0, 1.25, 0], 0.0)
    follower = PathFollower(np.array([[1.0, 1.0], [1.0, -1.0]]))
    visited = []
    for _ in range(500):
        a = follower.next_action(pose)
        if a is None:
            break
        pose = _apply(pose, a)
        visited.append(pose[[0, 2], 3])
    assert follower.done
    assert np.hypot(*(pose[[0, 2], 3] - [1.0, -1.0])) <= CFG.arrive_radius
    # it passed near the first waypoint first
    d_first = [np.hypot(*(p - [1.0, 1.0])) for p in visited]
    assert min(d_first) <= CFG.arrive_radius


def test_follow_action_turns_when_heading_is_off():
    pose = camera_pose([0, 1.25, 0], 0.0)  # looking along +z
    assert follow_action(pose, np.array([0.0, 2.0]), CFG) == "move_forward"
    assert follow_action(pose, np.array([2.0, 0.0]), CFG) == "turn_left"  # +x is to the left
    assert follow_action(pose, np.array([-2.0, 0.0]), CFG) == "turn_right"
    assert follow_action(pose, np.array([0.05, 0.0]), CFG) is None
