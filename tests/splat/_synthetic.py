"""A tiny analytic RGB-D "scene" for mapper tests: a textured wall at z = WALL_Z (world), optionally
with a box face in front of it, seen by a pinhole camera. Ground truth is computed by ray casting
against the planes, independent of the rasterizer."""

import numpy as np

WALL_Z = 2.0


def intrinsics(size: int) -> np.ndarray:
    f = size / 2.0  # 90 deg field of view
    return np.array([[f, 0, size / 2], [0, f, size / 2], [0, 0, 1]])


def pose(tx: float = 0.0, ty: float = 0.0, yaw_deg: float = 0.0) -> np.ndarray:
    a = np.radians(yaw_deg)
    p = np.eye(4)
    p[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    p[:3, 3] = [tx, ty, 0.0]
    return p


def wall_color(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Smooth colour pattern on the wall (values in [0.15, 0.85])."""
    return np.stack([0.5 + 0.35 * np.sin(2.5 * x), 0.5 + 0.35 * np.cos(2.0 * y), 0.5 + 0.2 * np.sin(x + y)],
                    axis=-1)


def observe(cam_pose: np.ndarray, size: int, box: tuple[float, float, float, float, float] | None = None):
    """RGB (uint8) and z-depth of the wall; ``box`` = (x0, x1, y0, y1, z) adds a grey face at depth z."""
    K = intrinsics(size)
    j, i = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    dirs_cam = np.stack([(j - K[0, 2]) / K[0, 0], (i - K[1, 2]) / K[1, 1], np.ones_like(j)], axis=-1)
    dirs = dirs_cam @ cam_pose[:3, :3].T
    origin = cam_pose[:3, 3]
    t = (WALL_Z - origin[2]) / dirs[..., 2]
    hit = origin + t[..., None] * dirs
    rgb = wall_color(hit[..., 0], hit[..., 1])
    if box is not None:
        x0, x1, y0, y1, zb = box
        tb = (zb - origin[2]) / dirs[..., 2]
        hb = origin + tb[..., None] * dirs
        on_box = (hb[..., 0] > x0) & (hb[..., 0] < x1) & (hb[..., 1] > y0) & (hb[..., 1] < y1) & (tb < t)
        t = np.where(on_box, tb, t)
        rgb[on_box] = 0.3
    depth = (t * dirs_cam[..., 2]).astype(np.float32)  # z-depth in the camera
    return (rgb * 255 + 0.5).astype(np.uint8), depth
