"""Completion ratio and completion (paper sec. IV-B; docs/protocol.md §6).

These measure the *observed sensor data*, not the map: after the reset and after every action, the
ground-truth depth (at 128 x 128) is back-projected into world points; 200,000 points sampled (seeded) on
the full ground-truth mesh keep the running minimum distance to any frame's points, initialised to 1 m.
completion = mean of that minimum (cm); completion ratio = share below 5 cm. The uncapped variant keeps
the true minimum distance (None until anything has been observed).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from activesplat.errors import check_fields
from activesplat.geometry import backproject, merge_sorted, unique_first, voxel_keys


@dataclass(frozen=True)
class CoverageConfig:
    """Evaluation protocol constants (docs/protocol.md §6)."""

    resolution: int = 128
    """Replay depth is rendered at this many pixels square, 128 (half the default 256 x 256 sensor), with the
    sensor's field of view (paper protocol); it does not follow --sim.width."""
    n_gt_points: int = 200_000
    """Points sampled area-uniformly on the ground-truth mesh (paper protocol: 200,000)."""
    seed: int = 0
    """Seed of the ground-truth point sample (ours: fixed so that runs compare)."""
    cap_m: float = 1.0
    """The running minimum distance starts at 1 m, which caps completion (paper protocol)."""
    threshold_m: float = 0.05
    """A ground-truth point counts as completed when observed within 5 cm (paper protocol)."""
    far_voxel_m: float = 0.02
    """Beyond the cap (uncapped variant only) distances are measured to observed points thinned to one per
    voxel of this size (ours): error below sqrt(3) x size on distances over 1 m; exact within the cap."""
    batch_frames: int = 50
    """Frames whose points are pooled into one KD-tree per update (ours: a speed knob; the result is
    exact)."""
    background: bool | None = None
    """Run the live evaluation of `activesplat explore` (ground-truth depth renders, KD-tree updates, curve
    points) on a worker thread, off the exploration step's critical path (ours: a speed knob; the frames
    are folded in the same order, so every number is the same). None: on where the map is on a GPU (the
    gsplat backend) and the process may use at least two threads; off on CPU-only runs and in benchmark
    workers (one thread each). On the CPU the worker takes a core from the step's parallel kernels, which
    wait for their slowest thread: medium-0, 2000 steps, 2 cores, 167 ms/step with the mapper at 75.5 on a
    worker thread against 144 / 56.7 in the loop (small-0: 48 against 51-52). At a lower CPU priority it
    was faster (nice 19: 152 / 67.2; the idle scheduling policy: 139 / 61.4), but a worker at low priority
    is starved while other jobs keep the cores busy, and the run then waits for it at its end. On an H100
    machine's 16 cores it takes the evaluation's 12-19 ms off the step."""

    def __post_init__(self) -> None:
        check_fields(self, positive=("cap_m", "threshold_m", "far_voxel_m"),
                     at_least_one=("resolution", "n_gt_points", "batch_frames"))


def _tree(points: np.ndarray) -> cKDTree:
    """A KD-tree split at sliding midpoints. scipy's default median-balanced, compacted tree is pathological
    on depth-camera points (dense, regularly spaced, on planes): a 1 m bounded nearest-neighbour query of
    the 200k GT points against one batch of 50 frames (819k points) took 247 s instead of 0.7 s. The
    distances are exact either way."""
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


class CoverageAccumulator:
    """Running minimum distance from each ground-truth point to everything observed so far.

    Frames are buffered and folded in by batches (one KD-tree over the batch's points, one query of the GT
    points), which gives exactly the per-frame running minimum at a fraction of the cost.
    """

    def __init__(self, gt_points: np.ndarray, cfg: CoverageConfig | None = None):
        self.cfg = cfg or CoverageConfig()
        self.gt = np.asarray(gt_points, np.float64)
        self.min_dist = np.full(len(self.gt), np.inf)
        self._pending: list[np.ndarray] = []
        self._pending_frames: list[int] = []
        self.first_frame = np.full(len(self.gt), -1, np.int64)
        """Per ground-truth point: the index of the frame (0 = the first added) that first observed it within
        the threshold, -1 while none has (`gain_by_frame`)."""
        self._voxels = np.zeros(0, np.int64)
        self._thinned: list[np.ndarray] = []
        self.frames = 0

    def add_frame(self, depth: np.ndarray, pose: np.ndarray, K: np.ndarray) -> None:
        pts = backproject(depth, pose, K)
        if len(pts):
            self._pending.append(pts)
            self._pending_frames.append(self.frames)
        self.frames += 1
        if len(self._pending) >= self.cfg.batch_frames:
            self.flush()

    def flush(self) -> None:
        """Fold the buffered frames into the running minimum."""
        if not self._pending:
            return
        owner = np.repeat(self._pending_frames, [len(p) for p in self._pending])
        pts = np.concatenate(self._pending)
        self._pending, self._pending_frames = [], []
        # Exact within the cap: only GT points within the cap of the batch's bounding box can get closer
        # than the cap, and a bounded search returns inf beyond it.
        cap = self.cfg.cap_m
        columns = pts.T  # column by column: a reduction over axis 0 of (N, 3) is several times slower
        lo = np.array([c.min() for c in columns]) - cap
        hi = np.array([c.max() for c in columns]) + cap
        near = np.flatnonzero(np.all((self.gt >= lo) & (self.gt <= hi), axis=1))
        if len(near):
            tree = _tree(pts)
            dist, idx = self._bounded_query(tree, near)
            thr = self.cfg.threshold_m
            is_fresh = (dist < thr) & ~(self.min_dist[near] < thr)
            self.min_dist[near] = np.minimum(self.min_dist[near], dist)
            if is_fresh.any():
                self._first_frames(tree, owner, near[is_fresh], owner[idx[is_fresh]])
        self._keep_thinned(pts)

    def _bounded_query(self, tree: cKDTree, near: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest batch point of each GT point in `near`, searched only as far as could lower its running
        minimum: points already within the threshold up to the threshold, the others up to the cap (a
        search bounded by B returns inf beyond B, and min(m, inf) = m for any running minimum m <= B). The
        same minima, fresh points and their nearest points as one search up to the cap; most GT points
        near a batch are already completed late in a run, and their short searches end at once."""
        thr, cap = self.cfg.threshold_m, self.cfg.cap_m
        dist = np.full(len(near), np.inf)
        idx = np.zeros(len(near), np.int64)
        done = self.min_dist[near] < thr
        for group, bound in ((done, thr), (~done, cap)):
            if group.any():
                dist[group], idx[group] = tree.query(self.gt[near[group]], k=1, distance_upper_bound=bound,
                                                     workers=-1)
        return dist, idx

    def _first_frames(self, tree: cKDTree, owner: np.ndarray, fresh: np.ndarray, nearest: np.ndarray) -> None:
        """Record which frame of the batch first came within the threshold of the `fresh` GT points (those
        completed by this batch): the earliest frame owning a batch point that close (`nearest`: the frame
        of each one's nearest point, which is that close by definition). Batch points are in frame order,
        so the earliest frame is the owner of the lowest point index within the threshold."""
        hits = tree.query_ball_point(self.gt[fresh], r=np.nextafter(self.cfg.threshold_m, 0.0), workers=-1)
        counts = np.fromiter(map(len, hits), np.int64, len(hits))
        flat = np.fromiter(itertools.chain.from_iterable(hits), np.int64, int(counts.sum()))
        first = nearest.copy()
        some = counts > 0
        if some.any():
            starts = np.concatenate(([0], np.cumsum(counts)[:-1]))[some]
            first[some] = owner[np.minimum.reduceat(flat, starts)]
        self.first_frame[fresh] = np.minimum(first, nearest)

    def _keep_thinned(self, pts: np.ndarray) -> None:
        """One observed point per 2 cm voxel, for the uncapped distances beyond the cap."""
        keys = voxel_keys(pts, self.cfg.far_voxel_m)
        keys, first = unique_first(keys)
        self._voxels, fresh = merge_sorted(self._voxels, keys)
        if fresh.any():
            self._thinned.append(pts[first[fresh]])

    def _uncapped(self) -> np.ndarray:
        """True minimum distances: exact below the cap; beyond it, measured against the observed points
        thinned to one per `far_voxel_m` voxel: a kept point lies within the voxel's diagonal of the point it
        stands for, so such a distance is at most sqrt(3) x `far_voxel_m` too long (3.5 cm at 2 cm)."""
        out = self.min_dist.copy()
        far = ~(out < self.cfg.cap_m)
        if far.any() and self._thinned:
            dist, _ = _tree(np.concatenate(self._thinned)).query(self.gt[far], k=1, workers=-1)
            out[far] = dist
        return out

    def completed(self) -> np.ndarray:
        """Per ground-truth point: observed within the threshold (the points the completion ratio counts)."""
        self.flush()
        return self.min_dist < self.cfg.threshold_m

    def gain_by_frame(self) -> np.ndarray:
        """(frames,) how many ground-truth points each frame completed first: its cumulative sum is the
        completion curve at every frame, and it attributes the completion to the actions that led to each
        frame (`eval.behaviour.gain_by_cause`)."""
        self.flush()
        seen = self.first_frame[self.first_frame >= 0]
        return np.bincount(seen, minlength=self.frames)

    def metrics(self, uncapped: bool = True) -> dict:
        """completion_ratio_pct, completion_cm (capped at 1 m), completion_cm_uncapped (None until something
        was observed) and helpers. `uncapped=False` skips the (slower) uncapped distances."""
        self.flush()
        capped = np.minimum(self.min_dist, self.cfg.cap_m)
        uncapped = self._uncapped() if uncapped else None
        return {
            "completion_ratio_pct": float(100.0 * np.mean(capped < self.cfg.threshold_m)),
            "completion_cm": float(100.0 * capped.mean()),
            "completion_cm_uncapped": (float(100.0 * uncapped.mean())
                                       if uncapped is not None and np.isfinite(uncapped).all() else None),
            "within_cap_pct": float(100.0 * np.mean(self.min_dist < self.cfg.cap_m)),
            "n_gt_points": len(self.gt),
            "frames": self.frames,
        }
