"""Keyframe buffer and overlap-based window selection (SplaTAM's keyframe selection, as the release).

The mapping window of a frame is the ``k`` keyframes that see most of what the current frame sees,
plus the last keyframe, plus the current frame (docs/protocol.md §2). Overlap of a keyframe = the
share of ``n_pixels`` sampled valid-depth pixels of the current frame that, back-projected to the
world and projected into the keyframe, land in front of it and more than ``border`` pixels inside
its image.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from activesplat.geometry import backproject


@dataclass
class Keyframe:
    """One stored observation: ``rgb`` (H,W,3) uint8, ``depth`` (H,W) float32 metres (0 = invalid),
    ``pose`` 4x4 camera-to-world (OpenCV), ``step`` the index of the frame it came from."""

    rgb: np.ndarray
    depth: np.ndarray
    pose: np.ndarray
    step: int


def overlap_fractions(points: np.ndarray, poses: np.ndarray, K: np.ndarray, width: int, height: int,
                      border: int) -> np.ndarray:
    """For each camera of ``poses`` (M,4,4), the share of world ``points`` (P,3) that project in front
    of it and more than ``border`` px inside its image. Returns (M,)."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    if len(points) == 0 or len(poses) == 0:
        return np.zeros(len(poses))
    from activesplat.splat._mapper_numba import overlap_shares

    rot = np.ascontiguousarray(poses[:, :3, :3])  # world -> camera: R^T (p - t) = p R - t R
    offset = np.einsum("mi,mij->mj", poses[:, :3, 3], rot)  # (M,3)
    return overlap_shares(np.ascontiguousarray(points, dtype=np.float64), rot, offset, float(K[0, 0]),
                          float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), width, height, border)


def overlap_fraction(points: np.ndarray, pose: np.ndarray, K: np.ndarray, width: int, height: int,
                     border: int) -> float:
    """:func:`overlap_fractions` for a single camera."""
    return float(overlap_fractions(points, pose[None], K, width, height, border)[0])


def sample_valid_pixels(depth: np.ndarray, n_pixels: int, rng: np.random.Generator) -> tuple[np.ndarray,
                                                                                             np.ndarray]:
    """Up to ``n_pixels`` (row, column) indices drawn without replacement among valid-depth pixels."""
    v, u = np.nonzero(depth > 0)
    if len(v) > n_pixels:
        pick = rng.choice(len(v), size=n_pixels, replace=False)
        v, u = v[pick], u[pick]
    return v, u


def select_overlapping(depth: np.ndarray, pose: np.ndarray, K: np.ndarray, keyframes: list[Keyframe], k: int,
                       n_pixels: int, border: int, rng: np.random.Generator) -> list[int]:
    """Indices of the (at most) ``k`` keyframes with the largest non-zero overlap, best first."""
    if k <= 0 or not keyframes:
        return []
    v, u = sample_valid_pixels(depth, n_pixels, rng)
    points = backproject(depth, pose, K, v, u)
    height, width = depth.shape
    poses = np.stack([kf.pose for kf in keyframes])
    scores = overlap_fractions(points, poses, K, width, height, border)
    order = np.argsort(-scores, kind="stable")
    return [int(i) for i in order[:k] if scores[i] > 0]


def mapping_window(depth: np.ndarray, pose: np.ndarray, K: np.ndarray, keyframes: list[Keyframe], k: int,
                   n_pixels: int, border: int, rng: np.random.Generator) -> list[int]:
    """Keyframe indices of the mapping window: ``k`` best-overlap keyframes + the last keyframe
    (without duplicates). The current frame is added by the caller."""
    window = select_overlapping(depth, pose, K, keyframes, k, n_pixels, border, rng)
    if keyframes and (len(keyframes) - 1) not in window:
        window.append(len(keyframes) - 1)
    return window
