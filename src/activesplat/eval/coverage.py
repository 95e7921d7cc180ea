"""Completion ratio and completion (paper sec. IV-B; REFERENCE.md section 6).

These measure the *observed sensor data*, not the map: after the reset and after every action, the
ground-truth depth (at 128 x 128) is back-projected into world points; 200,000 points sampled (seeded) on
the full ground-truth mesh keep the running minimum distance to any frame's points, initialised to 1 m.
completion = mean of that minimum (cm); completion ratio = share below 5 cm. The uncapped variant keeps
the true minimum (infinite until something is observed within range, reported over the points that were
observed at all as well as over all points when every point has a finite distance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass
class CoverageConfig:
    """Evaluation protocol constants (REFERENCE.md section 6)."""

    resolution: int = 128
    """Replay depth is rendered at 128 x 128 (half the 256 x 256 sensor), same field of view."""
    n_gt_points: int = 200_000
    """Points sampled area-uniformly on the ground-truth mesh."""
    seed: int = 0
    """Seed of the ground-truth point sample (fixed so that runs compare)."""
    cap_m: float = 1.0
    """The running minimum distance starts at 1 m, which caps completion."""
    threshold_m: float = 0.05
    """A ground-truth point counts as completed when observed within 5 cm."""
    batch_frames: int = 50
    """Frames whose points are pooled into one KD-tree per update (a speed knob; the result is exact)."""


def backproject(depth: np.ndarray, pose: np.ndarray, K: np.ndarray) -> np.ndarray:
    """World points (M, 3) of the valid (> 0) pixels of a z-depth image seen from a camera-to-world pose."""
    depth = np.asarray(depth, np.float64)
    v, u = np.nonzero(depth > 0)
    z = depth[v, u]
    cam = np.stack([(u + 0.5 - K[0, 2]) / K[0, 0] * z, (v + 0.5 - K[1, 2]) / K[1, 1] * z, z], axis=1)
    return cam @ pose[:3, :3].T + pose[:3, 3]


class CoverageAccumulator:
    """Running minimum distance from each ground-truth point to everything observed so far.

    Frames are buffered and folded in by batches (one KD-tree over the batch's points, one query of the GT
    points), which gives exactly the per-frame running minimum at a fraction of the cost.
    """

    def __init__(self, gt_points: np.ndarray, cfg: CoverageConfig | None = None):
        self.cfg = cfg or CoverageConfig()
        self.gt = np.asarray(gt_points, np.float64)
        self._tree_gt = None
        self.min_dist = np.full(len(self.gt), np.inf)
        self._pending: list[np.ndarray] = []
        self.frames = 0

    def add_frame(self, depth: np.ndarray, pose: np.ndarray, K: np.ndarray) -> None:
        pts = backproject(depth, pose, K)
        if len(pts):
            self._pending.append(pts)
        self.frames += 1
        if len(self._pending) >= self.cfg.batch_frames:
            self.flush()

    def flush(self) -> None:
        """Fold the buffered frames into the running minimum."""
        if not self._pending:
            return
        pts = np.concatenate(self._pending)
        self._pending = []
        dist, _ = cKDTree(pts).query(self.gt, k=1, workers=-1)
        np.minimum(self.min_dist, dist, out=self.min_dist)

    def metrics(self) -> dict:
        """completion_ratio_pct, completion_cm (capped at 1 m), completion_cm_uncapped and helpers."""
        self.flush()
        capped = np.minimum(self.min_dist, self.cfg.cap_m)
        finite = np.isfinite(self.min_dist)
        return {
            "completion_ratio_pct": float(100.0 * np.mean(capped < self.cfg.threshold_m)),
            "completion_cm": float(100.0 * capped.mean()),
            "completion_cm_uncapped": float(100.0 * self.min_dist[finite].mean()) if finite.any() else None,
            "observed_gt_share_pct": float(100.0 * finite.mean()),
            "n_gt_points": len(self.gt),
            "frames": self.frames,
        }
