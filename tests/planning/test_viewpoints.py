"""Viewpoint selection on synthetic worlds with known answers (no Gaussians needed: a fake renderer
answers opacity and median depth from each pixel's ray)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from activesplat.geometry import camera_pose, heading, wrap_angle
from activesplat.planning.config import HighLossConfig, PanoramaConfig, ScoreConfig
from activesplat.planning.panorama import render_panorama
from activesplat.planning.viewpoints import (
    HighLossTracker,
    hull_volume,
    invisible_share,
    node_scores,
    rotation_candidates,
)

ORIGIN = np.array([0.0, 1.25, 0.0])
K_128 = np.array([[64.0, 0, 64], [0, 64, 64], [0, 0, 1]])  # a 128 x 128 camera with a 90 deg field of view
DEPTH_2M = np.full((128, 128), 2.0, np.float32)


def fake_renderer(hole_yaw_deg, hole_pitch_deg, radius=3.0):
    """A sphere of `radius` around ORIGIN, opaque except for a window of directions (a hole)."""
    (y0, y1), (p0, p1) = hole_yaw_deg, hole_pitch_deg

    def render(pose, K, width, height):
        u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
        cam = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
        d = cam @ pose[:3, :3].T
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        yaw = np.degrees(np.arctan2(d[..., 0], d[..., 2]))
        pitch = np.degrees(np.arcsin(d[..., 1]))
        in_yaw = np.abs(wrap_angle(np.radians(yaw - (y0 + y1) / 2))) <= np.radians((y1 - y0) / 2)
        hole = in_yaw & (pitch >= p0) & (pitch <= p1)
        cos_axis = d @ pose[:3, 2]
        alpha = np.where(hole, 0.0, 1.0)
        med = np.where(hole, 0.0, radius * cos_axis)
        return SimpleNamespace(alpha=alpha, median_depth=med)

    return render


def test_front_faces_asks_the_world_for_front_facing_opacity_when_it_can_give_it():
    plain = fake_renderer((0, 0), (0, 0))  # opaque everywhere

    def faces(pose, K, width, height, front_alpha=False, behind_margin_deg=0.0):  # all seen from behind
        out = plain(pose, K, width, height)
        return SimpleNamespace(alpha=out.alpha * (0.0 if front_alpha else 1.0), median_depth=out.median_depth)

    assert invisible_share(render_panorama(faces, ORIGIN)) == 0.0
    assert invisible_share(render_panorama(faces, ORIGIN, front_faces=True)) == pytest.approx(1.0)
    assert invisible_share(render_panorama(plain, ORIGIN, front_faces=True)) == 0.0  # plain opacity


def test_panorama_rays_point_where_the_pose_looks():
    pano = render_panorama(fake_renderer((0, 0), (0, 0)), ORIGIN)
    assert pano.shape == (150, 360)
    centre = pano.rays[75, 60] / np.linalg.norm(pano.rays[75, 60])
    assert np.allclose(centre, heading(0.0), atol=0.03)
    # yaw decreases left to right and is continuous across the camera boundaries
    row = np.degrees(np.unwrap(pano.yaw[75]))
    assert np.all(np.diff(row) < 0)
    assert row[0] - row[-1] == pytest.approx(360, abs=2)
    # back-projected points of an opaque sphere lie on the sphere
    rows, cols = np.array([10, 75, 140]), np.array([5, 200, 359])
    pts = pano.points(rows, cols)
    assert np.allclose(np.linalg.norm(pts - ORIGIN, axis=1), 3.0, atol=1e-3)


@pytest.mark.parametrize("yaw_centre", [90.0, 60.0, -150.0])  # 60 deg sits on the panorama's seam
def test_rotation_candidate_points_at_the_hole(yaw_centre):
    render = fake_renderer((yaw_centre - 20, yaw_centre + 20), (-10, 20))
    targets = rotation_candidates(render_panorama(render, ORIGIN))
    assert len(targets) == 1
    t = targets[0]
    assert math.degrees(abs(wrap_angle(t.yaw - math.radians(yaw_centre)))) < 4
    assert math.degrees(t.pitch) == pytest.approx(5, abs=6)


def test_no_candidate_when_everything_is_seen():
    pano = render_panorama(fake_renderer((0, 0), (0, 0)), ORIGIN)
    assert rotation_candidates(pano) == []
    assert invisible_share(pano) == 0
    assert hull_volume(pano) == 0


def test_hull_volume_grows_with_the_hole():
    small = render_panorama(fake_renderer((70, 110), (-30, 30)), ORIGIN)
    big = render_panorama(fake_renderer((20, 160), (-50, 50)), ORIGIN)
    assert 0 < hull_volume(small) < hull_volume(big)
    # the share is a solid-angle share: a 140 x 100 deg window of the sphere is ~ 0.30 of it
    assert 0 < invisible_share(small) < invisible_share(big)
    window_sr = math.radians(140) * (math.sin(math.radians(50)) * 2)
    total_sr = 2 * math.pi * (math.sin(math.radians(75)) * 2)  # the panorama spans +-75 deg of pitch
    assert invisible_share(big) == pytest.approx(window_sr / total_sr, rel=0.05)


def test_high_loss_tracker_adds_then_drops_sample():
    pose = camera_pose(ORIGIN, 0.0)
    mask = np.zeros((128, 128), bool)
    mask[20:50, 90:120] = True  # upper right of the image
    tracker = HighLossTracker()
    tracker.update(mask, DEPTH_2M, pose, K_128, step=3)
    assert len(tracker.samples) == 1
    p = tracker.samples[0].point
    # upper right in the image: up (world +y) and to the right (world -x when looking along +z)
    assert p[1] > ORIGIN[1] and p[0] < 0 and p[2] == pytest.approx(2.0, abs=0.05)
    target = tracker.targets(ORIGIN)[0]
    assert target.yaw < 0 and target.pitch > 0
    tracker.observe(camera_pose(ORIGIN, target.yaw, target.pitch))
    assert tracker.samples == []


def test_only_the_heaviest_high_loss_samples_become_targets():
    tracker = HighLossTracker(HighLossConfig(max_samples=8))
    for step, (c0, size) in enumerate(((10, 20), (50, 36), (90, 28))):  # three clusters of three sizes
        mask = np.zeros((128, 128), bool)
        mask[40:40 + size, c0:c0 + size] = True
        tracker.update(mask, DEPTH_2M, camera_pose(ORIGIN, 0.5), K_128, step=step)
    weights = sorted((s.weight for s in tracker.samples), reverse=True)
    assert len(weights) == 3 and len(set(weights)) == 3
    capped = tracker.targets(ORIGIN)
    assert [t.weight for t in capped] == weights[:2]  # default: the two heaviest
    tracker.cfg = HighLossConfig(max_targets=0)
    assert [t.weight for t in tracker.targets(ORIGIN)] == weights
    assert tracker.targets(ORIGIN, max_distance=1.0) == []


def test_tiny_mask_adds_nothing():
    tracker = HighLossTracker()
    mask = np.zeros((64, 64), bool)
    mask[0, :5] = True
    tracker.update(mask, np.ones((64, 64)), np.eye(4), np.eye(3), step=0)
    assert tracker.samples == []


def test_node_scores_paper_and_release():
    s = node_scores([1.0, 0.5, 0.0], [0.0, 2.0, 1.0], [1, 0, 1], [1, 1, 0], [0, 0, 1])
    assert s.tolist() == pytest.approx([20 + 0 + 10 + 10, 10 + 10 + 0 + 10, 0 + 5 + 10 + 0 - 60])
    r = node_scores([1.0, 0.5], [0.0, 2.0], [1, 0], [1, 1], [0, 0], ScoreConfig(preset="release"))
    assert r.tolist() == pytest.approx([20 + 10 + 20 + 0, 0 + 10 + 10 + 10])
    with pytest.raises(ValueError, match="preset"):
        node_scores([1.0], [1.0], [1], [1], [0], ScoreConfig(preset="bogus"))


def test_panorama_config_shape():
    cfg = PanoramaConfig(width_per_camera=60, height=75)
    pano = render_panorama(fake_renderer((0, 0), (0, 0)), ORIGIN, cfg)
    assert pano.shape == (75, 180)
