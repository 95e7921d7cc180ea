"""Keyframe overlap selection (SplaTAM-style) on synthetic cameras."""

import numpy as np

from activesplat.geometry import backproject
from activesplat.splat.keyframes import (
    Keyframe,
    mapping_window,
    overlap_fraction,
    select_overlapping,
)

W = H = 64
K = np.array([[32.0, 0, 32], [0, 32.0, 32], [0, 0, 1]])


def _pose(yaw_deg: float, t=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Camera-to-world: rotation about the world y axis (OpenCV camera, y down)."""
    a = np.radians(yaw_deg)
    pose = np.eye(4)
    pose[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    pose[:3, 3] = t
    return pose


def _kf(yaw, step, t=(0.0, 0.0, 0.0)):
    return Keyframe(np.zeros((H, W, 3), np.uint8), np.full((H, W), 2.0, np.float32), _pose(yaw, t), step)


def test_backproject_then_project_returns_the_pixels():
    depth = np.full((H, W), 3.0, np.float32)
    pose = _pose(30, (1.0, 0.5, -2.0))
    v, u = np.array([0, 10, 63]), np.array([5, 32, 63])
    pts = backproject(depth, pose, K, v, u)
    cam = (pts - pose[:3, 3]) @ pose[:3, :3]
    assert np.allclose(cam[:, 2], 3.0)
    assert np.allclose(K[0, 0] * cam[:, 0] / cam[:, 2] + K[0, 2], u + 0.5)
    assert np.allclose(K[1, 1] * cam[:, 1] / cam[:, 2] + K[1, 2], v + 0.5)


def test_overlap_fraction_counts_border_and_behind():
    pose = _pose(0)
    pts = np.array([[0, 0, 2.0], [0, 0, -2.0], [0.99 * 2, 0, 2.0]])  # centre, behind, near the right edge
    assert overlap_fraction(pts, pose, K, W, H, border=0) == 2 / 3
    assert overlap_fraction(pts, pose, K, W, H, border=5) == 1 / 3
    assert overlap_fraction(np.zeros((0, 3)), pose, K, W, H, border=0) == 0.0


def test_select_overlapping_orders_by_overlap_and_drops_zero():
    keyframes = [_kf(180, 0), _kf(40, 1), _kf(0, 2), _kf(20, 3)]
    depth = np.full((H, W), 2.0, np.float32)
    rng = np.random.default_rng(0)
    picked = select_overlapping(depth, _pose(0), K, keyframes, k=10, n_pixels=400, border=4, rng=rng)
    assert picked == [2, 3, 1]  # same view, then 20 deg, then 40 deg; the one looking back is dropped
    assert select_overlapping(depth, _pose(0), K, keyframes, 2, 400, 4, rng) == [2, 3]


def test_window_adds_the_last_keyframe_once():
    keyframes = [_kf(0, 0), _kf(20, 1), _kf(180, 2)]
    depth = np.full((H, W), 2.0, np.float32)
    rng = np.random.default_rng(0)
    assert mapping_window(depth, _pose(0), K, keyframes, 1, 400, 4, rng) == [0, 2]
    assert mapping_window(depth, _pose(180), K, keyframes, 5, 400, 4, rng) == [2]
    assert mapping_window(depth, _pose(0), K, [], 5, 400, 4, rng) == []
