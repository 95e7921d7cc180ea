"""Top-down view of the Gaussian map and the free / obstacle / unknown grids (paper sec. III-A,
"the top-down view can be efficiently rendered using a large focal length as the orthographic
projection of the dense map"; docs/protocol.md §3).

Grid convention: row r grows with world +z, column c grows with world +x; pixel (r, c) covers
x in [x0 + c*res, x0 + (c+1)*res), z in [z0 + r*res, z0 + (r+1)*res). The top-down camera looks
along world -y with OpenCV axes x_cam = +x, y_cam = +z, z_cam = -y, so its image is this grid.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from activesplat.errors import InvalidInputError
from activesplat.workspace.config import WorkspaceConfig

# Camera-to-world rotation of the top-down camera: columns are x_cam, y_cam, z_cam in world axes.
TOPDOWN_ROTATION = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclass(frozen=True)
class GridGeometry:
    """Where a top-down grid lies on the floor plane (world x, z)."""

    origin: np.ndarray
    """(2,) world (x, z) of the grid's corner (pixel (0, 0)'s outer corner)."""
    resolution: float
    """Metres per pixel."""
    shape: tuple[int, int]
    """(rows, cols)."""

    def world_to_pixel(self, xz: np.ndarray) -> np.ndarray:
        """(..., 2) world (x, z) -> (..., 2) continuous pixel (row, col); pixel centres at integer + 0.5."""
        xz = np.asarray(xz, dtype=np.float64)
        rel = (xz - self.origin) / self.resolution
        return np.stack([rel[..., 1], rel[..., 0]], axis=-1)

    def pixel_to_world(self, rc: np.ndarray) -> np.ndarray:
        """(..., 2) continuous pixel (row, col) -> (..., 2) world (x, z)."""
        rc = np.asarray(rc, dtype=np.float64)
        return self.origin + self.resolution * np.stack([rc[..., 1], rc[..., 0]], axis=-1)

    def pixel_index(self, xz: np.ndarray) -> np.ndarray:
        """(..., 2) world (x, z) -> (..., 2) integer (row, col) of the containing pixel (may be outside)."""
        return np.floor(self.world_to_pixel(xz)).astype(np.int64)

    def contains(self, rc: np.ndarray) -> np.ndarray:
        """Whether integer pixel indices (..., 2) lie inside the grid."""
        rc = np.asarray(rc)
        rows, cols = rc[..., 0], rc[..., 1]
        return (rows >= 0) & (rows < self.shape[0]) & (cols >= 0) & (cols < self.shape[1])

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, z_min, z_max) of the grid in world metres."""
        x0, z0 = self.origin
        return (x0, x0 + self.shape[1] * self.resolution, z0, z0 + self.shape[0] * self.resolution)


@dataclass(frozen=True)
class TopDownGrids:
    """Free (navigable), obstacle and unknown boolean grids plus the band opacities they come from."""

    geometry: GridGeometry
    free: np.ndarray
    """(H, W) bool: observed ground with no obstacle above it."""
    obstacle: np.ndarray
    """(H, W) bool: obstacle-band opacity above the threshold."""
    unknown: np.ndarray
    """(H, W) bool: neither free nor obstacle."""
    ground_alpha: np.ndarray
    """(H, W) float32 accumulated opacity of the ground band."""
    obstacle_alpha: np.ndarray
    """(H, W) float32 accumulated opacity of the obstacle band."""
    floor_height: float
    """World y of the floor used for the height bands."""


def grid_geometry_from_points(xz: np.ndarray, cfg: WorkspaceConfig, agent_xz: np.ndarray | None = None
                              ) -> GridGeometry:
    """Map bounds grown from the mapped points (never the ground-truth mesh), padded and snapped to the
    resolution so consecutive calls share pixel boundaries."""
    res = cfg.resolution
    pts = np.asarray(xz, dtype=np.float64).reshape(-1, 2)
    if agent_xz is not None:
        pts = np.concatenate([pts, np.asarray(agent_xz, dtype=np.float64).reshape(1, 2)])
    if len(pts) == 0:
        pts = np.zeros((1, 2))
    lo = np.floor((pts.min(axis=0) - cfg.bounds_padding) / res) * res
    hi = np.ceil((pts.max(axis=0) + cfg.bounds_padding) / res) * res
    size = np.round((hi - lo) / res).astype(np.int64)
    if np.any(size > cfg.max_grid_pixels):
        centre = pts[-1] if agent_xz is not None else 0.5 * (lo + hi)
        half = cfg.max_grid_pixels // 2
        clipped_lo = np.floor(centre / res) * res - half * res
        lo = np.where(size > cfg.max_grid_pixels, clipped_lo, lo)
        size = np.minimum(size, cfg.max_grid_pixels)
    return GridGeometry(origin=lo, resolution=res, shape=(int(size[1]), int(size[0])))


def topdown_camera(geometry: GridGeometry, floor_height: float, cfg: WorkspaceConfig
                   ) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Camera straight down, `camera_height` above the floor over the grid centre, focal length chosen so
    one pixel spans `resolution` metres at the floor. Returns (viewmat 4x4 world-to-camera, K, W, H)."""
    height, width = geometry.shape
    x_min, x_max, z_min, z_max = geometry.extent
    centre = np.array([0.5 * (x_min + x_max), floor_height + cfg.camera_height, 0.5 * (z_min + z_max)])
    cam_to_world = np.eye(4)
    cam_to_world[:3, :3] = TOPDOWN_ROTATION
    cam_to_world[:3, 3] = centre
    focal = cfg.camera_height / geometry.resolution
    K = np.array([[focal, 0.0, width / 2.0], [0.0, focal, height / 2.0], [0.0, 0.0, 1.0]])
    return np.linalg.inv(cam_to_world), K, width, height


def height_band_masks(heights: np.ndarray, floor_height: float, cfg: WorkspaceConfig
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Per-Gaussian masks of the ground band and the obstacle band (docs/protocol.md §3): ground =
    [floor - ground_depth, floor + margin), obstacle = [floor + margin, floor + agent height]."""
    rel = heights - floor_height
    ground = (rel >= -cfg.ground_depth) & (rel < cfg.floor_margin)
    obstacle = (rel >= cfg.floor_margin) & (rel <= cfg.agent_height)
    return ground, obstacle


def observed_ground(ground_alpha: np.ndarray, cfg: WorkspaceConfig) -> np.ndarray:
    """Ground-band opacity above the threshold, closed with a `ground_closing` kernel so sparse far floor
    Gaussians (1 px each at the release's scale modifier) read as one observed floor, not stripes."""
    observed = (ground_alpha > cfg.ground_opacity).astype(np.uint8)
    k = cfg.ground_closing_px
    if k > 1:  # padded with unobserved pixels: cv2's default border would let the floor grow along the edge
        h = k // 2
        padded = cv2.copyMakeBorder(observed, h, h, h, h, cv2.BORDER_CONSTANT, value=0)
        observed = cv2.morphologyEx(padded, cv2.MORPH_CLOSE, np.ones((k, k), np.uint8))[h:-h, h:-h]
    return observed.astype(bool)


def grids_from_alpha(geometry: GridGeometry, ground_alpha: np.ndarray, obstacle_alpha: np.ndarray,
                     floor_height: float, cfg: WorkspaceConfig) -> TopDownGrids:
    """Free / obstacle / unknown from the two band opacities: obstacle where the obstacle band is opaque,
    free where the ground is observed and no obstacle is above it, unknown elsewhere."""
    obstacle = obstacle_alpha > cfg.obstacle_opacity
    free = observed_ground(ground_alpha, cfg) & ~obstacle
    return TopDownGrids(geometry=geometry, free=free, obstacle=obstacle, unknown=~(free | obstacle),
                        ground_alpha=ground_alpha.astype(np.float32),
                        obstacle_alpha=obstacle_alpha.astype(np.float32), floor_height=float(floor_height))


def _band_alpha(band: dict[str, Any], viewmat: np.ndarray, K: np.ndarray, width: int, height: int,
                cfg: WorkspaceConfig, backend: str) -> np.ndarray:
    """Accumulated opacity of one height band's Gaussians (dict of activated tensors), rendered top-down
    with scales times `scale_modifier` (docs/protocol.md §3)."""
    import torch

    from activesplat.splat import rasterize

    if len(band["means"]) == 0:
        return np.zeros((height, width), dtype=np.float32)
    dtype = band["means"].dtype
    with torch.no_grad():
        out = rasterize(band["means"], band["quats"], band["scales"] * cfg.scale_modifier, band["opacities"],
                        torch.zeros_like(band["means"]), torch.as_tensor(viewmat, dtype=dtype),
                        torch.as_tensor(K, dtype=dtype), width, height, backend=backend)
    return np.asarray(out.alpha.detach().cpu().numpy(), dtype=np.float32).reshape(height, width)


def _band_gaussians(gmap: Any, bands: list[np.ndarray]) -> list[dict[str, Any]]:
    """Activated means / quats / scales / opacities of each band (index arrays), each activation computed
    once for the whole map; colours are not needed for opacity."""
    import torch

    with torch.no_grad():
        params = {"means": gmap.means, "quats": gmap.quats, "scales": gmap.scales,
                  "opacities": gmap.opacities.reshape(-1)}
        params = {name: t.detach() for name, t in params.items()}
        return [{name: t[torch.from_numpy(idx).to(t.device)] for name, t in params.items()} for idx in bands]


def render_topdown(gmap: Any, floor_height: float, cfg: WorkspaceConfig | None = None,
                   agent_xz: np.ndarray | None = None, backend: str = "auto") -> TopDownGrids:
    """Render the Gaussian map straight down in the ground and obstacle height bands and split it into
    free / obstacle / unknown grids (paper sec. III-A; docs/protocol.md §3).

    `gmap` is any object with torch tensors `means (N,3)`, `quats (N,4)`, `scales (N,3)`,
    `opacities (N,)` (colours are not used). `floor_height` is the world y of the floor (from the agent's
    start pose). Bounds grow from the band Gaussians' means (and `agent_xz`, world (x, z), if given)."""
    cfg = cfg or WorkspaceConfig()
    if not np.isfinite(floor_height):
        raise InvalidInputError(f"floor_height must be finite, got {floor_height}")
    means = gmap.means.detach()
    if means.ndim != 2 or means.shape[-1] != 3:
        raise InvalidInputError(f"gmap.means must have shape (N, 3), got {tuple(means.shape)}")
    heights = means[:, 1].cpu().numpy()
    ground, obstacle = height_band_masks(heights, floor_height, cfg)
    band_xz = means[:, [0, 2]].cpu().numpy()[ground | obstacle]
    geometry = grid_geometry_from_points(band_xz, cfg, agent_xz)
    viewmat, K, width, height = topdown_camera(geometry, floor_height, cfg)
    ground_band, obstacle_band = _band_gaussians(gmap, [np.flatnonzero(ground), np.flatnonzero(obstacle)])
    ground_alpha = _band_alpha(ground_band, viewmat, K, width, height, cfg, backend)
    obstacle_alpha = _band_alpha(obstacle_band, viewmat, K, width, height, cfg, backend)
    return grids_from_alpha(geometry, ground_alpha, obstacle_alpha, floor_height, cfg)


def frontier_cells(free: np.ndarray, unknown: np.ndarray) -> np.ndarray:
    """Free cells with an unknown 8-neighbour: the frontiers of frontier-based exploration (the `fbe`
    baseline's goals; drawn in topdown.png)."""
    near_unknown = cv2.dilate(unknown.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    return free & near_unknown
