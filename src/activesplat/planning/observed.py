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

import numpy as np

from activesplat.geometry import backproject, in_sorted, merge_sorted, voxel_keys
from activesplat.planning.panorama import Panorama


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


def poorly_observed_share(pano: Panorama, observed: ObservedSurface, radius_m: float) -> float:
    """Share of the panorama's solid angle that shows mapped surface (a median depth) within `radius_m` of
    the panorama's centre in a voxel no observed depth point has fallen into."""
    rows, cols = np.nonzero(pano.median_depth > 0)
    if not len(rows):
        return 0.0
    pts = pano.points(rows, cols)
    near = np.linalg.norm(pts - pano.origin[None, :], axis=1) <= radius_m
    poor = np.zeros(len(rows), bool)
    poor[near] = ~observed.contains(pts[near])
    w = pano.solid_angle
    return float(w[rows[poor], cols[poor]].sum() / w.sum())


__all__ = ["ObservedSurface", "poorly_observed_share"]
