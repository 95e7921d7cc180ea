"""Is the recording's depth in metres? A check of the depth against the camera motion, run by
`robot.recording.open_recording` before anything is mapped.

A wrong depth unit (a TUM folder saved at 1000 units per metre read with ``--depth-scale 5000``, a bag whose
16UC1 depth is not millimetres) scales every depth by one factor; the map is then that much too small or too
large, and the held-out evaluation, scaled alike, does not notice. The poses are metric, so the depth is not:
back-projected from frame i with the poses, the depth of a pair of frames that moved apart agrees with frame
j's depth only at the right scale.

For a few pairs of frames at least ``min_move`` apart (and turned at most ``max_turn_deg``), near the start
of the recording: frame i's depth (a subsampled grid of pixels) multiplied by s, back-projected with the
poses (`geometry.backproject`'s convention, pixel centres at integer + 0.5, `Recording.mapper_K`),
projected into frame j and compared with frame j's depth times s; the score of s is the mean relative
depth disagreement, capped at ``cap`` per pixel, over the pixels that land on frame j's depth. Each pair's
estimate is the s of the lowest score over a log-spaced search; the recording's is the median of the pairs.
It is refused (RecordingError) when that is outside [1 / ``tolerance``, ``tolerance``] and confident: at
least ``min_pairs`` pairs with ``min_pixels`` compared pixels, all within ``agree`` of their median, and a
score at s = 1 at least 1.5 times the best. Anything less is reported (``Recording.info["depth_check"]``)
and not refused: a recording that never moves ``min_move`` is not checked.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from activesplat.errors import RecordingError


@dataclass(frozen=True)
class DepthCheckConfig:
    min_move: float = 0.1
    """Metres the camera moves between the two frames of a pair (less: the depth hardly constrains s)."""
    max_turn_deg: float = 30.0
    """At most this rotation between the two frames of a pair (more: little overlap)."""
    pairs: int = 4
    """Pairs compared, the first ones found from the start of the recording."""
    pixels: int = 4000
    """About this many pixels of frame i per pair (a regular grid)."""
    min_pixels: int = 200
    """Compared pixels (landing on frame j's depth) for a pair to count."""
    min_pairs: int = 2
    """Pairs needed to refuse; fewer (a recording with one usable pair) is only reported."""
    tolerance: float = 1.25
    """A scale within [1 / tolerance, tolerance] passes."""
    agree: float = 1.25
    """Pairs agree when each estimate is within this factor of their median."""
    cap: float = 0.1
    """Per-pixel relative depth disagreement counted at most this much (occlusions, moving things)."""
    s_range: tuple[float, float] = (0.05, 20.0)
    """Scales searched (log-spaced, 5% apart, then refined to 0.5%)."""


def pick_pairs(poses: np.ndarray, cfg: DepthCheckConfig) -> list[tuple[int, int]]:
    """Up to ``cfg.pairs`` (i, j), j the first frame after i at least ``min_move`` from it, turned at most
    ``max_turn_deg``; pairs do not overlap (the next i is at least j); the first found from the start."""
    pos = poses[:, :3, 3]
    n = len(poses)
    cos_max = math.cos(math.radians(cfg.max_turn_deg))
    pairs: list[tuple[int, int]] = []
    # candidates for i: at most 2000, from the start; each looks at the next 2000 frames
    i_all = np.unique(np.linspace(0, n - 1, min(n, 2000)).astype(np.int64))
    for i in i_all:
        if pairs and i < pairs[-1][1]:
            continue
        d = np.linalg.norm(pos[i + 1: i + 2001] - pos[i], axis=1)
        far = np.flatnonzero(d >= cfg.min_move)
        if not len(far):
            continue
        j = int(i + 1 + far[0])
        cos = (np.trace(poses[i, :3, :3].T @ poses[j, :3, :3]) - 1.0) / 2.0
        if cos >= cos_max:
            pairs.append((int(i), j))
            if len(pairs) == cfg.pairs:
                break
    return pairs


def _grid(depth: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    h, w = depth.shape
    step = max(1, int(math.sqrt(h * w / max(n, 1))))
    v, u = np.mgrid[step // 2: h: step, step // 2: w: step]
    v, u = v.ravel(), u.ravel()
    keep = np.isfinite(depth[v, u]) & (depth[v, u] > 0)
    return v[keep], u[keep]


def pair_scores(d_i, d_j, pose_i, pose_j, K, scales, cfg: DepthCheckConfig) -> tuple[np.ndarray, np.ndarray]:
    """(score, compared pixels) of each scale in ``scales`` for one pair (module docstring)."""
    from activesplat.geometry import backproject

    v, u = _grid(d_i, cfg.pixels)
    h, w = d_j.shape
    # frame i's points (depth as recorded) in frame j's camera, without the translation: x_j = s * a + b
    cam_i = backproject(d_i, np.eye(4), K, v, u)
    rel = np.linalg.inv(pose_j) @ pose_i
    a = cam_i @ rel[:3, :3].T
    b = rel[:3, 3]
    score = np.full(len(scales), np.inf)
    count = np.zeros(len(scales), dtype=np.int64)
    for k, s in enumerate(scales):
        x = s * a + b
        z = x[:, 2]
        front = z > 1e-3
        x, z = x[front], z[front]
        uj = np.floor(K[0, 0] * x[:, 0] / z + K[0, 2]).astype(np.int64)  # pixel centres at integer + 0.5
        vj = np.floor(K[1, 1] * x[:, 1] / z + K[1, 2]).astype(np.int64)
        inside = (uj >= 0) & (uj < w) & (vj >= 0) & (vj < h)
        dj = d_j[vj[inside], uj[inside]]
        ok = np.isfinite(dj) & (dj > 0)
        count[k] = int(ok.sum())
        if count[k]:
            zk = z[inside][ok]
            score[k] = float(np.minimum(np.abs(zk - s * dj[ok]) / zk, cfg.cap).mean())
    return score, count


def estimate_pair(d_i, d_j, pose_i, pose_j, K, cfg: DepthCheckConfig) -> dict | None:
    """{"s", "score", "score_at_1", "pixels"} of one pair, or None when too few pixels compare."""
    lo, hi = cfg.s_range
    coarse = np.exp(np.arange(math.log(lo), math.log(hi) + 1e-9, math.log(1.05)))
    score, count = pair_scores(d_i, d_j, pose_i, pose_j, K, coarse, cfg)
    score[count < cfg.min_pixels] = np.inf
    if not np.isfinite(score).any():
        return None
    best = coarse[int(np.argmin(score))]
    fine = best * np.exp(np.linspace(-math.log(1.05), math.log(1.05), 21))
    fscore, fcount = pair_scores(d_i, d_j, pose_i, pose_j, K, fine, cfg)
    fscore[fcount < cfg.min_pixels] = np.inf
    k = int(np.argmin(fscore))
    at1, n1 = pair_scores(d_i, d_j, pose_i, pose_j, K, np.array([1.0]), cfg)
    return {"s": float(fine[k]), "score": float(fscore[k]), "pixels": int(fcount[k]),
            "score_at_1": float(at1[0]) if n1[0] >= cfg.min_pixels else None}


def check_depth_scale(rec, cfg: DepthCheckConfig | None = None, poses: np.ndarray | None = None) -> dict:
    """The depth check of a scanned recording (module docstring): a dict for ``rec.info["depth_check"]``,
    or a RecordingError when the depth is confidently off by a factor."""
    import time

    cfg = cfg or DepthCheckConfig()
    t0 = time.perf_counter()
    poses = rec.poses if poses is None else poses
    pairs = pick_pairs(poses, cfg)
    result: dict = {"pairs": [], "scale": None}
    if not pairs:
        result["note"] = f"not checked: no two frames {cfg.min_move:g} m apart"
        result["seconds"] = round(time.perf_counter() - t0, 3)
        return result
    need = sorted({k for p in pairs for k in p})
    depth = {k: d for k, _, d in rec.frames(only=need)}
    K = rec.mapper_K
    for i, j in pairs:
        est = estimate_pair(depth[i], depth[j], poses[i], poses[j], K, cfg)
        if est is not None:
            result["pairs"].append({"frames": [i, j], **{k: (round(v, 4) if isinstance(v, float) else v)
                                                          for k, v in est.items()}})
    usable = result["pairs"]
    result["seconds"] = round(time.perf_counter() - t0, 3)
    if not usable:
        result["note"] = "not checked: no pair of frames overlaps enough"
        return result
    s = float(np.median([p["s"] for p in usable]))
    result["scale"] = round(s, 4)
    confident = len(usable) >= cfg.min_pairs and all(max(p["s"] / s, s / p["s"]) <= cfg.agree for p in usable)
    result["confident"] = confident
    if 1.0 / cfg.tolerance <= s <= cfg.tolerance:
        return result
    # off: refused when the pairs agree and each fits clearly worse at s = 1 (or does not overlap at all)
    clear = all(p["score_at_1"] is None or p["score_at_1"] >= 1.5 * p["score"] for p in usable)
    if confident and clear:
        raise RecordingError(scale_message(rec, s))
    result["note"] = "the depth's scale looks off, but the pairs of frames do not agree enough to refuse"
    return result


def scale_message(rec, s: float) -> str:
    """The one line for a depth ``s`` times too small (s > 1) or too large, with the likely fix."""
    what = f"{s:.1f}x too small" if s > 1 else f"{1.0 / s:.1f}x too large"
    head = (f"{rec.path}: the depth looks {what} for the camera motion (scale {s:.2f} aligns frames "
            f"that moved apart)")
    skip = " (--no-depth-check maps it anyway)"
    if rec.kind == "tum":
        current = float(rec.info.get("depth_scale", 5000.0))
        guess = current / s
        nice = min((1000.0, 5000.0, 10000.0, 4000.0, 2000.0, 100.0), key=lambda c: abs(math.log(c / guess)))
        if abs(math.log(nice / guess)) > math.log(1.1):
            nice = float(f"{guess:.3g}")
        return f"{head}: is --depth-scale {current:g} right for this folder? Try --depth-scale {nice:g}{skip}"
    return (f"{head}: {rec.info.get('depth_topic', 'the depth topic')} is read as millimetres (16UC1 / "
            f"mono16) or metres (32FC1): is it recorded in another unit?{skip}")


__all__ = ["DepthCheckConfig", "check_depth_scale", "estimate_pair", "pick_pairs", "scale_message"]
