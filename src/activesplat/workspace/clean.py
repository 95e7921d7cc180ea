"""Workspace polish (docs/protocol.md §3, release): keep the observed free region the agent stands in,
open then dilate it, keep its outer contour (simplified with approxPolyDP) and its inner contours as
obstacles, and rasterise the polygons back into a clean workspace mask with a clearance map."""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.topdown import GridGeometry, TopDownGrids


@dataclass(frozen=True)
class Workspace:
    """The navigable workspace: a simplified outer polygon minus obstacle polygons."""

    geometry: GridGeometry
    mask: np.ndarray
    """(H, W) bool: inside the outer polygon and outside every obstacle polygon."""
    clearance: np.ndarray
    """(H, W) float32 metres from each pixel centre to the edge of the nearest non-workspace pixel
    (0 outside)."""
    outer: np.ndarray
    """(K, 2) world (x, z) vertices of the outer polygon; empty (0, 2) when there is no workspace."""
    holes: list[np.ndarray] = field(default_factory=list)
    """World (x, z) polygons of the obstacles inside the workspace."""

    @property
    def empty(self) -> bool:
        return not bool(self.mask.any())

    def clearance_at(self, xz: np.ndarray) -> np.ndarray:
        """Clearance in metres at world points (..., 2); 0 outside the grid."""
        rc = self.geometry.pixel_index(xz)
        inside = self.geometry.contains(rc)
        rows = np.clip(rc[..., 0], 0, self.geometry.shape[0] - 1)
        cols = np.clip(rc[..., 1], 0, self.geometry.shape[1] - 1)
        return np.where(inside, self.clearance[rows, cols], 0.0)

    def segments_clearance(self, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """Smallest clearance in metres along each straight segment (M, 2) -> (M, 2), sampled every half
        pixel, endpoints included; (M,) result."""
        starts = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
        ends = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
        if len(starts) == 0:
            return np.zeros(0)
        lengths = np.linalg.norm(ends - starts, axis=1)
        counts = np.ceil(lengths / (0.5 * self.geometry.resolution)).astype(np.int64) + 1
        seg = np.repeat(np.arange(len(starts)), counts)
        offsets = np.concatenate([[0], np.cumsum(counts)[:-1]])
        t = (np.arange(counts.sum()) - offsets[seg]) / np.maximum(counts[seg] - 1, 1)
        points = starts[seg] + t[:, None] * (ends[seg] - starts[seg])
        return np.minimum.reduceat(self.clearance_at(points), offsets)


def empty_workspace(geometry: GridGeometry) -> Workspace:
    """A workspace with nothing navigable (empty or all-unknown map)."""
    zeros = np.zeros(geometry.shape, dtype=bool)
    return Workspace(geometry, zeros, zeros.astype(np.float32), np.zeros((0, 2)), [])


def agent_region(free: np.ndarray, agent_rc: np.ndarray, open_kernel: int = 1) -> np.ndarray:
    """The connected free region containing the agent pixel, or the one nearest to it (the floor right
    under the agent is often unobserved); all False when nothing is free. With `open_kernel` > 1 only
    regions that survive the workspace's opening (`morphology`) count: a speck the opening removes, under
    the agent or nearest to it, would leave an empty workspace while a real region lies a little further
    (ours). A region survives when it holds a pixel of the free grid eroded by the kernel: the kernel's
    window at such a pixel is free and connected, so it lies inside the region."""
    count, labels = cv2.connectedComponents(free.astype(np.uint8), connectivity=8)
    if count <= 1:
        return np.zeros_like(free)
    candidates = labels > 0
    if open_kernel > 1:
        eroded = cv2.erode(free.astype(np.uint8), np.ones((open_kernel,) * 2, np.uint8)).astype(bool)
        surviving = np.isin(labels, np.unique(labels[eroded]))
        if surviving.any():
            candidates &= surviving
    r, c = np.clip(agent_rc, 0, np.array(free.shape) - 1)
    label = labels[r, c]
    if not candidates[r, c]:
        rows, cols = np.nonzero(candidates)
        nearest = np.argmin((rows - r) ** 2 + (cols - c) ** 2)
        label = labels[rows[nearest], cols[nearest]]
    return labels == label


def grow_into_unknown(free: np.ndarray, unknown: np.ndarray, margin_px: int) -> np.ndarray:
    """The free grid grown by `margin_px` pixels (a disc) into unknown pixels only: obstacles stay out."""
    if margin_px <= 0:
        return free
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1,) * 2)
    return free | (cv2.dilate(free.astype(np.uint8), kernel).astype(bool) & unknown)


def morphology(region: np.ndarray, cfg: WorkspaceConfig) -> np.ndarray:
    """Open (removes specks and thin slivers) then dilate (closes cracks between sparse Gaussians),
    kernel sizes as the release (docs/protocol.md §3)."""
    mask = region.astype(np.uint8)
    kernel = np.ones((cfg.open_kernel,) * 2, np.uint8)
    # An even kernel's anchor is off-centre: dilate with the mirrored anchor so the opening does not shift.
    mirrored = ((cfg.open_kernel - 1) // 2,) * 2
    mask = cv2.dilate(cv2.erode(mask, kernel), kernel, anchor=mirrored)
    return cv2.dilate(mask, np.ones((cfg.dilate_kernel,) * 2, np.uint8)).astype(bool)


def mask_boundaries(workspace: Workspace, epsilon_px: float, min_hole_area: float) -> list[np.ndarray]:
    """The outer boundaries and the holes of at least `min_hole_area` m^2 of the workspace mask as world
    (x, z) polygons simplified by `epsilon_px` pixels: the walls as they are (the 0.225 m polygons can cut
    a thin wall down to a spike and put no Voronoi vertex in its door)."""
    contours, hierarchy = cv2.findContours(workspace.mask.astype(np.uint8), cv2.RETR_CCOMP,
                                           cv2.CHAIN_APPROX_NONE)
    min_area_px = min_hole_area / workspace.geometry.resolution ** 2
    kept = [c for c, h in zip(contours, hierarchy[0] if contours else [], strict=True)
            if h[3] < 0 or cv2.contourArea(c) >= min_area_px]
    return [_contour_world(cv2.approxPolyDP(c, epsilon_px, True), workspace.geometry) for c in kept]


def _contour_world(contour: np.ndarray, geometry: GridGeometry) -> np.ndarray:
    """OpenCV contour (K, 1, 2) of pixel (col, row) -> (K, 2) world (x, z) at pixel centres."""
    cr = contour.reshape(-1, 2).astype(np.float64) + 0.5
    return geometry.pixel_to_world(cr[:, ::-1])


def outer_and_holes(mask: np.ndarray, agent_rc: np.ndarray, cfg: WorkspaceConfig
                    ) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """Simplified outer contour containing (or nearest to) the agent and its simplified inner contours,
    as OpenCV pixel polygons (docs/protocol.md §3: approxPolyDP with 0.225 m)."""
    contours, hierarchy = cv2.findContours(mask.astype(np.uint8), cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None, []
    hierarchy = hierarchy[0]
    outers = [i for i in range(len(contours)) if hierarchy[i][3] < 0]
    point = (float(agent_rc[1]), float(agent_rc[0]))
    signed = [cv2.pointPolygonTest(contours[i], point, True) for i in outers]
    best = outers[int(np.argmax(signed))]
    eps = cfg.polygon_epsilon / cfg.resolution
    outer = cv2.approxPolyDP(contours[best], eps, True)
    min_area_px = cfg.min_hole_area / cfg.resolution ** 2
    holes = [cv2.approxPolyDP(contours[i], eps, True) for i in range(len(contours))
             if hierarchy[i][3] == best and cv2.contourArea(contours[i]) >= min_area_px]
    return outer, [h for h in holes if len(h) >= 3]


def polygon_mask(shape: tuple[int, int], outer: np.ndarray, holes: list[np.ndarray]) -> np.ndarray:
    """Rasterise the outer polygon minus the obstacle polygons (hole borders stay outside)."""
    canvas = np.zeros(shape, dtype=np.uint8)
    cv2.fillPoly(canvas, [outer], 1)
    for hole in holes:
        cv2.fillPoly(canvas, [hole], 0)
        cv2.polylines(canvas, [hole], True, 0, 1)
    return canvas.astype(bool)


def clearance_map(mask: np.ndarray, resolution: float) -> np.ndarray:
    """Euclidean distance in metres from each workspace pixel centre to the nearest non-workspace pixel's
    edge (pixel-centre distance minus half a pixel), 0 outside the workspace."""
    padded = np.pad(mask.astype(np.uint8), 1)
    dist = cv2.distanceTransform(padded, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
    # Pixel-centre distance minus half a pixel: the obstacle's edge, not its centre (conservative).
    return (np.maximum(dist - 0.5, 0.0) * mask * resolution).astype(np.float32)


def extract_workspace(grids: TopDownGrids, agent_xz: np.ndarray, cfg: WorkspaceConfig | None = None
                      ) -> Workspace:
    """Polish the free grid into the workspace the agent can reach (docs/protocol.md §3, release)."""
    cfg = cfg or WorkspaceConfig()
    geometry = grids.geometry
    agent_rc = geometry.pixel_index(np.asarray(agent_xz, dtype=np.float64))
    free = grow_into_unknown(grids.free, grids.unknown, int(round(cfg.unknown_margin / cfg.resolution)))
    region = morphology(agent_region(free, agent_rc, cfg.open_kernel), cfg)
    outer, holes = outer_and_holes(region, agent_rc, cfg) if region.any() else (None, [])
    if outer is None or len(outer) < 3:
        return empty_workspace(geometry)
    # The simplified polygon may cut up to polygon_epsilon into walls or unobserved space: the polygons
    # shape the Voronoi sites, the mask keeps only the polished observed region (ours; the release uses
    # the polygon as is).
    mask = polygon_mask(geometry.shape, outer, holes) & region & ~grids.obstacle
    if not mask.any():
        return empty_workspace(geometry)
    return Workspace(geometry, mask, clearance_map(mask, cfg.resolution), _contour_world(outer, geometry),
                     [_contour_world(h, geometry) for h in holes])
