"""Where the agent's own depth frames have sampled the surfaces densely (ours; an addition to eq. 12).

The map knows a surface once it holds opaque Gaussians there, which a single glance from across a room or
down a corridor provides; the completion measure (docs/protocol.md §6) counts a surface point only where an
observed depth point lies within 5 cm of it, which a far, grazing view of a floor does not give (its samples
lie 10-20 cm apart). `ObservedSurface` keeps the voxels the agent's depth points have fallen into, sampled as
the completion measure samples them; `poorly_observed_share` is the share of a node's panorama that shows
mapped surface within reach of the node whose voxel no depth point has hit yet: what a visit there would add
that the invisibility of eq. 12 does not see.
"""

from __future__ import annotations

import math

import numpy as np

from activesplat.geometry import backproject, in_sorted, merge_sorted, voxel_keys, wrap_angle
from activesplat.planning.panorama import Panorama
from activesplat.planning.viewpoints import RotationTarget

WEIGHT_UNIT_SR = math.radians(2.0) ** 2
"""Solid angle of one weight unit of `unsampled_views`: a pixel of the half-resolution panorama (~2 deg
square), the unit of the rotation candidates' invisibility masses, so that both kinds of target rank on
one scale."""


class ObservedSurface:
    """The voxels (`voxel_m`) that hold at least one of the agent's observed depth points, each frame
    sampled every `stride` pixels (2: the completion measure's 128 x 128 of a 256 x 256 sensor)."""

    def __init__(self, voxel_m: float = 0.1, stride: int = 2):
        self.voxel_m, self.stride = float(voxel_m), int(stride)
        self.keys = np.zeros(0, np.int64)
        """Sorted voxel keys (`geometry.voxel_keys`)."""

    def add(self, depth: np.ndarray, pose: np.ndarray, K: np.ndarray) -> None:
        """Add one depth frame (z-depth, 0 or non-finite = no depth) seen from camera-to-world `pose`."""
        d = np.asarray(depth.detach().cpu().numpy() if hasattr(depth, "detach") else depth, np.float64)
        sub = np.zeros(d.shape, bool)
        sub[self.stride // 2::self.stride, self.stride // 2::self.stride] = True
        v, u = np.nonzero(sub & np.isfinite(d) & (d > 0))
        if not len(v):
            return
        keys = np.unique(voxel_keys(backproject(d, np.asarray(pose, np.float64), K, v, u), self.voxel_m))
        self.keys, _ = merge_sorted(self.keys, keys)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(M,) whether each world point (M, 3) lies in a voxel some depth point has fallen into."""
        return in_sorted(self.keys, voxel_keys(np.asarray(points, np.float64).reshape(-1, 3), self.voxel_m))


def poorly_observed_pixels(pano: Panorama, observed: ObservedSurface, radius_m: float
                           ) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of the panorama pixels that show mapped surface (a median depth) within `radius_m` of
    the panorama's centre in a voxel no observed depth point has fallen into."""
    rows, cols = np.nonzero(pano.median_depth > 0)
    if not len(rows):
        return rows, cols
    pts = pano.points(rows, cols)
    near = np.linalg.norm(pts - pano.origin[None, :], axis=1) <= radius_m
    poor = np.zeros(len(rows), bool)
    poor[near] = ~observed.contains(pts[near])
    return rows[poor], cols[poor]


def poorly_observed_share(pano: Panorama, observed: ObservedSurface, radius_m: float) -> float:
    """Share of the panorama's solid angle that `poorly_observed_pixels` cover."""
    rows, cols = poorly_observed_pixels(pano, observed, radius_m)
    w = pano.solid_angle
    return float(w[rows, cols].sum() / w.sum())


def unsampled_views(pano: Panorama, observed: ObservedSurface, radius_m: float, max_views: int,
                    min_weight: float, half_fov_deg: float = 40.0, turn_deg: float = 10.0,
                    look_deg: float = 15.0, max_pitch_deg: float = 45.0) -> list[RotationTarget]:
    """Camera directions that would sample the surface near the agent that its depth has not sampled yet
    (`poorly_observed_pixels` within `radius_m`), source "unsampled": greedily, the heading (whole turns)
    and pitch (whole tilts within +-`max_pitch_deg`) whose view, `half_fov_deg` either way of its centre
    in yaw and pitch, covers the most of that surface's solid angle not covered by a view chosen before, at
    most `max_views`, each while it covers at least `min_weight` (in `WEIGHT_UNIT_SR`). The map shows such
    surface as seen (no invisibility for eq. 12's panorama targets) once a glance from afar put Gaussians
    there, but the glance sampled it too sparsely for the completion measure."""
    rows, cols = poorly_observed_pixels(pano, observed, radius_m)
    if max_views <= 0 or not len(rows):
        return []
    yaw, pitch = pano.yaw[rows, cols], pano.pitch[rows, cols]
    weight = pano.solid_angle[rows, cols] / WEIGHT_UNIT_SR
    half = math.radians(half_fov_deg)
    headings = np.radians(np.arange(0.0, 360.0, turn_deg))
    limit = look_deg * math.floor(max_pitch_deg / look_deg)
    pitches = np.radians(np.arange(-limit, limit + 1e-9, look_deg))
    in_yaw = np.abs(wrap_angle(yaw[None, :] - headings[:, None])) <= half  # (headings, pixels)
    in_pitch = np.abs(pitch[None, :] - pitches[:, None]) <= half  # (pitches, pixels)
    yaw_f = in_yaw.T.astype(np.float64)
    left = weight.astype(np.float64)
    views: list[RotationTarget] = []
    for _ in range(max_views):
        covered = (in_pitch * left[None, :]) @ yaw_f  # (pitches, headings)
        p, h = np.unravel_index(int(np.argmax(covered)), covered.shape)
        if covered[p, h] < min_weight:
            break
        views.append(RotationTarget(float(wrap_angle(headings[h])), float(pitches[p]), float(covered[p, h]),
                                    "unsampled"))
        left[in_pitch[p] & in_yaw[h]] = 0.0
    return views


__all__ = ["WEIGHT_UNIT_SR", "ObservedSurface", "poorly_observed_pixels", "poorly_observed_share",
           "unsampled_views"]
