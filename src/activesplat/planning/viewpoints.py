"""Viewpoint selection (paper sec. III-B): rotation candidates, invisible share, convex-hull volume,
high-loss samples (eq. 10), the node score (eq. 12) and the choice of the on-arrival rotation targets
(sec. III-B3, `select_rotation_targets`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from activesplat.geometry import wrap_angle, yaw_pitch_of
from activesplat.planning.clusters import grid_dbscan
from activesplat.planning.config import (
    HighLossConfig,
    HullConfig,
    PlanningConfig,
    RotationCandidateConfig,
    ScoreConfig,
)
from activesplat.planning.controller import ControllerConfig, fewest_actions_order
from activesplat.planning.panorama import Panorama


@dataclass
class RotationTarget:
    """A direction worth looking at: yaw/pitch in radians (geometry.heading convention)."""

    yaw: float
    pitch: float
    weight: float
    """Invisibility mass (panorama) or cluster size (high-loss) behind the target."""
    source: str = "panorama"


def _downsample(img: np.ndarray, factor: int) -> np.ndarray:
    """Block-average an (H, W) image by an integer factor (crops the remainder)."""
    if factor <= 1:
        return img
    h, w = (img.shape[0] // factor) * factor, (img.shape[1] // factor) * factor
    return img[:h, :w].reshape(h // factor, factor, w // factor, factor).mean(axis=(1, 3))


def _seam_shift(mask: np.ndarray) -> int:
    """Column roll that puts the panorama's 360-deg seam where the mask is emptiest, so that a region
    straddling the seam is not split into two clusters."""
    return -int(np.argmin(mask.sum(axis=0)))


def _clusters(mask: np.ndarray, eps: float, min_samples: int) -> list[np.ndarray]:
    """DBSCAN over the (row, col) pixels of a boolean image (:func:`grid_dbscan`, scikit-learn's labels);
    a list of (k, 2) pixel arrays, one per cluster."""
    pix = np.argwhere(mask)
    if len(pix) < min_samples:
        return []
    labels = grid_dbscan(mask, eps, min_samples)
    return [pix[labels == lab] for lab in range(labels.max() + 1)]


def _full_res(pix: np.ndarray, factor: int, shift: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Downsampled, seam-rolled pixel coordinates back to full-resolution (rows, cols)."""
    rows = pix[:, 0] * factor + factor // 2
    cols = ((pix[:, 1] - shift // factor) * factor + factor // 2) % width
    return rows, cols


def rotation_candidates(pano: Panorama, cfg: RotationCandidateConfig | None = None) -> list[RotationTarget]:
    """Cluster low-visibility pixels with DBSCAN; each cluster's mean ray gives a yaw/pitch target.

    Sorted by invisibility mass, largest first.
    """
    cfg = cfg or RotationCandidateConfig()
    inv = _downsample(pano.invisibility, cfg.downsample)
    mask = inv > cfg.invisibility_threshold
    shift = _seam_shift(mask)
    inv, mask = np.roll(inv, shift, axis=1), np.roll(mask, shift, axis=1)
    shift *= cfg.downsample
    targets = []
    for pix in _clusters(mask, cfg.dbscan_eps, cfg.dbscan_min_samples):
        mass = float(inv[pix[:, 0], pix[:, 1]].sum())
        if mass <= cfg.min_cluster_invisibility:
            continue
        rows, cols = _full_res(pix, cfg.downsample, shift, pano.shape[1])
        rays = pano.rays[rows, cols]
        w = pano.solid_angle[rows, cols][:, None]
        mean_dir = (w * rays / np.linalg.norm(rays, axis=1, keepdims=True)).sum(axis=0)
        yaw, pitch = yaw_pitch_of(mean_dir)
        targets.append(RotationTarget(yaw, pitch, mass, "panorama"))
    return sorted(targets, key=lambda t: -t.weight)


def invisible_share(pano: Panorama, cfg: RotationCandidateConfig | None = None) -> float:
    """s_o before normalisation: the share of the panorama's solid angle that is invisible (invisibility of
    the low-visibility pixels, weighted by each pixel's solid angle, over the total)."""
    cfg = cfg or RotationCandidateConfig()
    inv = pano.invisibility
    w = pano.solid_angle
    return float((w * inv * (inv > cfg.invisibility_threshold)).sum() / w.sum())


def hull_volume(pano: Panorama, cfg: HullConfig | None = None) -> float:
    """s_c before normalisation: summed 3D convex-hull volume (m^3) of the invisible regions.

    As the paper describes: cluster the invisible pixels, dilate each cluster, take its outer contour and
    back-project the contour pixels (which lie on observed geometry around the hole) with the panorama's
    median depth; the convex hull of those points (plus the node itself) approximates the unseen volume.
    """
    cfg = cfg or HullConfig()
    f = cfg.downsample
    mask = _downsample(pano.invisibility, f) > cfg.invisibility_threshold
    shift = _seam_shift(mask)
    mask = np.roll(mask, shift, axis=1)
    k = max(3, (cfg.dilate_px // f) | 1)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    total = 0.0
    for pix in _clusters(mask, cfg.dbscan_eps, cfg.dbscan_min_samples):
        blob = np.zeros(mask.shape, np.uint8)
        blob[pix[:, 0], pix[:, 1]] = 1
        blob = cv2.dilate(blob, kernel)
        contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        if not contours:
            continue
        contour = max(contours, key=len)[:, 0, :]  # (k, 2) as (col, row)
        rows, cols = _full_res(contour[:, ::-1], f, shift * f, pano.shape[1])
        rows = np.clip(rows, 0, pano.shape[0] - 1)
        valid = pano.median_depth[rows, cols] > 0
        if valid.sum() < 3:
            continue
        pts = np.vstack([pano.points(rows[valid], cols[valid]), pano.origin[None, :]])
        total += _hull_volume(pts)
    return total


def _hull_volume(points: np.ndarray) -> float:
    """Volume of the convex hull of points; 0 for fewer than 4 or (nearly) coplanar points."""
    if len(points) < 4:
        return 0.0
    try:
        return float(ConvexHull(points).volume)
    except (QhullError, ValueError):
        return 0.0


# --------------------------------------------------------------------------- high-loss samples (eq. 10)
@dataclass
class HighLossSample:
    """A 3D point of a high-loss region, kept until the camera has looked at it."""

    point: np.ndarray
    weight: float
    step: int


class HighLossTracker:
    """Keeps the high-loss samples of eq. 10 over time ("clustered with temporal propagation").

    Each mapped frame's eq. 10 mask (computed by the mapper before densification, see
    `activesplat.splat.densify.high_loss_mask`) is downsampled, clustered with DBSCAN and
    the largest cluster's centre is back-projected with the observed depth into a world point. A sample is
    forgotten once the camera heading comes within `drop_within_deg` of it.
    """

    def __init__(self, cfg: HighLossConfig | None = None):
        self.cfg = cfg or HighLossConfig()
        self.samples: list[HighLossSample] = []

    def update(self, mask: np.ndarray, depth: np.ndarray, pose: np.ndarray, K: np.ndarray, step: int) -> None:
        """Add the sample of one frame's high-loss mask (if any), then drop what this view covers."""
        cfg = self.cfg
        self.observe(pose)
        mask = np.asarray(mask, bool)
        if mask.sum() <= cfg.min_pixels:
            return
        small = cv2.resize(mask.astype(np.float32), (cfg.grid, cfg.grid), interpolation=cv2.INTER_AREA) > 0
        clusters = [c for c in _clusters(small, cfg.dbscan_eps, cfg.dbscan_min_samples)
                    if len(c) > cfg.min_cluster_sum]
        if not clusters:
            return
        best = max(clusters, key=len)
        h, w = mask.shape
        rows = ((best[:, 0] + 0.5) * h / cfg.grid).astype(int)
        cols = ((best[:, 1] + 0.5) * w / cfg.grid).astype(int)
        z = depth[rows, cols]
        ok = z > 0
        if not ok.any():
            return
        u, v, z = cols[ok] + 0.5, rows[ok] + 0.5, z[ok]
        cam = np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], axis=1).mean(axis=0)
        point = pose[:3, :3] @ cam + pose[:3, 3]
        self.samples.append(HighLossSample(point, float(len(best)), step))
        self.samples = self.samples[-cfg.max_samples:]

    def observe(self, pose: np.ndarray) -> None:
        """Forget the samples the camera now looks straight at (within drop_within_deg)."""
        axis = pose[:3, 2]
        keep = []
        for s in self.samples:
            d = s.point - pose[:3, 3]
            n = np.linalg.norm(d)
            if n < 1e-6 or math.degrees(math.acos(np.clip(axis @ d / n, -1, 1))) > self.cfg.drop_within_deg:
                keep.append(s)
        self.samples = keep

    def targets(self, position: np.ndarray, max_distance: float | None = None) -> list[RotationTarget]:
        """Rotation targets toward the tracked samples seen from `position`, heaviest first, at most
        `max_targets` of them (0: all)."""
        out = []
        for s in self.samples:
            d = s.point - np.asarray(position)
            if max_distance is not None and np.linalg.norm(d) > max_distance:
                continue
            yaw, pitch = yaw_pitch_of(d)
            out.append(RotationTarget(yaw, pitch, s.weight, "high_loss"))
        out.sort(key=lambda t: -t.weight)
        return out[:self.cfg.max_targets] if self.cfg.max_targets > 0 else out


# --------------------------------------------------------------------------- node score (eq. 12)
def information_scores(inv_share, hull_vol, cfg: ScoreConfig | None = None) -> np.ndarray:
    """The information part of eq. 12 (what a node promises to show): w_o s_o + w_c s_c, with s_o and s_c
    the invisible share and hull volume divided by their maximum over the candidates (release:
    2*ceil(10*inv/max) + 1*ceil(10*vol/max))."""
    cfg = cfg or ScoreConfig()
    inv = np.asarray(inv_share, float)
    vol = np.asarray(hull_vol, float)
    s_o = inv / inv.max() if inv.size and inv.max() > 0 else np.zeros_like(inv)
    s_c = vol / vol.max() if vol.size and vol.max() > 0 else np.zeros_like(vol)
    if cfg.preset == "release":
        return 2 * np.ceil(10 * s_o) + 1 * np.ceil(10 * s_c)
    if cfg.preset != "paper":
        raise ValueError(f"unknown score preset {cfg.preset!r} (expected 'paper' or 'release')")
    return cfg.w_o * s_o + cfg.w_c * s_c


def node_scores(inv_share, hull_vol, unvisited, in_horizon, failed,
                cfg: ScoreConfig | None = None) -> np.ndarray:
    """Eq. 12 for a set of candidate nodes (1D arrays of equal length).

    paper:   S = w_o * inv/max(inv) + w_c * vol/max(vol) + w_u * unvisited + w_h * in_horizon - penalty*failed
    release: S = 20*unvisited + 10*in_horizon + 2*ceil(10*inv/max) + 1*ceil(10*vol/max) - 60*failed
    """
    cfg = cfg or ScoreConfig()
    info = information_scores(inv_share, hull_vol, cfg)
    s_u = np.asarray(unvisited, float)
    s_h = np.asarray(in_horizon, float)
    pen = cfg.failed_penalty * np.asarray(failed, float)
    if cfg.preset == "release":
        return info + 20 * s_u + 10 * s_h - pen
    return info + cfg.w_u * s_u + cfg.w_h * s_h - pen


# ------------------------------------------------------------------------- rotations on arrival (sec. III-B3)
def select_rotation_targets(targets: Sequence[RotationTarget], yaw: float, pcfg: PlanningConfig,
                            max_views: int, pitch: float = 0.0, ctrl: ControllerConfig | None = None,
                            final_yaw: float | None = None) -> list[RotationTarget]:
    """On-arrival rotation targets (sec. III-B3): the heaviest panorama / high-loss targets, skipping those
    lighter than `RotationCandidateConfig.min_relative_weight` of their source's heaviest, those already in
    view (within their source's minimum offset of the heading, and less than 20 deg off level) and those
    within 20 deg of a chosen one, at most `max_views`. Returned in counter-clockwise order from
    the heading, or, given the controller `ctrl`, in the order that visits them in the fewest turns and
    tilts from (`yaw`, `pitch`), levelling and the turn back to `final_yaw` (if given) included
    (`controller.fewest_actions_order`)."""
    chosen: list[RotationTarget] = []
    heaviest: dict[str, float] = {}
    for t in targets:
        heaviest[t.source] = max(heaviest.get(t.source, 0.0), t.weight)
    for t in sorted(targets, key=lambda t: -t.weight):
        if t.weight < pcfg.rotation.min_relative_weight * heaviest[t.source]:
            continue
        limit = pcfg.high_loss.min_offset_deg if t.source == "high_loss" else pcfg.rotation.min_offset_deg
        if abs(math.degrees(float(wrap_angle(t.yaw - yaw)))) <= limit and abs(math.degrees(t.pitch)) < 20:
            continue
        if any(abs(float(wrap_angle(t.yaw - c.yaw))) < math.radians(20) for c in chosen):
            continue
        chosen.append(t)
        if len(chosen) >= max_views:
            break
    chosen.sort(key=lambda t: float(wrap_angle(t.yaw - yaw)) % (2 * math.pi))
    if ctrl is None:
        return chosen
    order = fewest_actions_order(yaw, pitch, [(t.yaw, t.pitch) for t in chosen], ctrl, final_yaw)
    return [chosen[i] for i in order]
