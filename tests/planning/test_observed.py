"""The sampled-surface memory and the poorly-observed share of a panorama (planning/observed.py)."""

import math

import numpy as np

from activesplat.geometry import camera_pose
from activesplat.planning.config import ScoreConfig
from activesplat.planning.observed import ObservedSurface, poorly_observed_share
from activesplat.planning.panorama import render_panorama

ORIGIN = np.array([0.0, 1.25, 0.0])
K_128 = np.array([[64.0, 0, 64], [0, 64, 64], [0, 0, 1]])  # 128 x 128, 90 deg field of view


def sphere_depth(radius: float) -> np.ndarray:
    """z-depth of a sphere of `radius` around the camera, seen by the 128 x 128 camera."""
    u, v = np.meshgrid(np.arange(128) + 0.5, np.arange(128) + 0.5)
    ray = np.stack([(u - 64) / 64, (v - 64) / 64, np.ones_like(u)], -1)
    return (radius / np.linalg.norm(ray, axis=-1)).astype(np.float32)


def sphere_renderer(radius: float):
    """The map: an opaque sphere of `radius` around ORIGIN."""

    def render(pose, K, width, height):
        u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
        ray = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
        med = radius / np.linalg.norm(ray, axis=-1)
        return type("Out", (), {"alpha": np.ones((height, width)), "median_depth": med})()

    return render


def test_depth_points_mark_their_voxels_and_nothing_else():
    seen = ObservedSurface(voxel_m=0.1)
    assert not seen.contains(np.array([[0.0, 1.25, 2.0]])).any()  # nothing observed yet
    seen.add(sphere_depth(2.0), camera_pose(ORIGIN, 0.0, 0.0), K_128)  # one look ahead at a sphere
    ahead, behind = np.array([[0.03, 1.27, 1.97]]), np.array([[0.03, 1.27, -1.97]])  # on the sphere
    assert seen.contains(ahead).all() and not seen.contains(behind).any()
    # frames without depth, and invalid depth, add nothing
    before = seen.keys.copy()
    seen.add(np.zeros((128, 128)), camera_pose(ORIGIN, math.pi, 0.0), K_128)
    seen.add(np.full((128, 128), np.nan), camera_pose(ORIGIN, math.pi, 0.0), K_128)
    assert np.array_equal(seen.keys, before)


def test_a_look_around_leaves_only_what_it_did_not_sample_poorly_observed():
    render = sphere_renderer(2.0)
    pano = render_panorama(render, ORIGIN)
    seen = ObservedSurface(voxel_m=0.1)
    radius = ScoreConfig().quality_radius_m
    before = poorly_observed_share(pano, seen, radius)
    assert before > 0.99  # mapped all around, sampled nowhere
    for k in range(4):  # four level looks: the band within 45 deg of the horizon
        seen.add(sphere_depth(2.0), camera_pose(ORIGIN, k * math.pi / 2, 0.0), K_128)
    after = poorly_observed_share(pano, seen, radius)
    assert 0.05 < after < 0.5 * before  # the caps above and below the band remain
    # surface beyond the radius does not count: a visit to the node would not sample it densely
    assert poorly_observed_share(pano, ObservedSurface(), radius_m=1.5) == 0.0


def test_views_toward_unsampled_surface_cover_it_greedily_and_stop_when_it_is_covered():
    from activesplat.geometry import wrap_angle
    from activesplat.planning.observed import unsampled_views

    pano = render_panorama(sphere_renderer(2.0), ORIGIN)
    seen = ObservedSurface(voxel_m=0.1)
    for k in range(3):  # level looks at 0, 90 and 180 deg: only the quarter around -90 deg is unsampled
        for pitch in (-math.pi / 4, 0.0, math.pi / 4):
            seen.add(sphere_depth(2.0), camera_pose(ORIGIN, k * math.pi / 2, pitch), K_128)
    views = unsampled_views(pano, seen, radius_m=2.5, max_views=3, min_weight=25.0)
    assert views and all(v.source == "unsampled" for v in views)
    first = views[0]
    assert abs(math.degrees(float(wrap_angle(first.yaw + math.pi / 2)))) <= 10.0  # looks into the gap
    assert abs(math.degrees(first.pitch)) <= 15.0 and first.weight > 100.0
    assert all(v.weight < first.weight for v in views[1:])  # greedy: each covers less than the one before
    # the others cover what the first one's 40 deg half-field leaves of the same quarter, above and below
    assert all(abs(math.degrees(float(wrap_angle(v.yaw + math.pi / 2)))) <= 50.0 for v in views)
    assert {round(math.degrees(v.pitch)) for v in views[1:]} <= {-45, -30, -15, 15, 30, 45}
    everywhere = ObservedSurface(voxel_m=0.1)
    for k in range(4):
        for pitch in (-math.pi / 3, 0.0, math.pi / 3):
            everywhere.add(sphere_depth(2.0), camera_pose(ORIGIN, k * math.pi / 2, pitch), K_128)
    assert unsampled_views(pano, everywhere, 2.5, 3, 25.0) == []
    assert unsampled_views(pano, seen, 2.5, 0, 25.0) == []
