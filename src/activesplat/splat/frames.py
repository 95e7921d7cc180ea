"""Checks and conversions of one posed RGB-D frame before it reaches the mapper (``Mapper.add_frame``).

Wrong shapes or dtypes, non-finite colours, float colours beyond [0, 1] (0-255 values), integer depth or
depth that reads as millimetres, and poses that are not finite proper rigid transforms (a mirror is not one)
raise :class:`InvalidInputError`; NaN / inf / negative depth pixels and those nearer than the sensor's minimum
are made invalid (0), as the mapper treats depth 0 everywhere.
"""

from __future__ import annotations

import numpy as np
import torch

from activesplat.errors import InvalidInputError

MAX_MEDIAN_DEPTH_M = 100.0
"""A frame whose valid depth has a median beyond this is taken for depth in other units (millimetres)."""


def _float_array(value, name: str, expected: str) -> np.ndarray:
    """``value`` as a float64 array; InvalidInputError naming it when it is not numbers (a string, None's
    elements, ragged nested lists)."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be {expected} of numbers, got {type(value).__name__} "
                                f"{str(value)[:60]!r}") from None


def as_intrinsics(K) -> np.ndarray:
    """K as a float64 3x3 matrix; InvalidInputError unless finite with positive focal lengths."""
    K = _float_array(K, "intrinsics K", "a 3x3 matrix")
    if K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise InvalidInputError(f"intrinsics K must be a finite 3x3 matrix with positive focal lengths, "
                                f"got {K.tolist()}")
    return K


def as_pose(pose) -> np.ndarray:
    """A camera-to-world pose as a float64 4x4; InvalidInputError unless finite and rigid."""
    pose = _float_array(pose, "pose", "a 4x4 camera-to-world matrix")
    if pose.shape != (4, 4):
        raise InvalidInputError(f"pose must be a 4x4 camera-to-world matrix, got shape {pose.shape}")
    if not np.isfinite(pose).all():
        bad = int((~np.isfinite(pose)).sum())
        raise InvalidInputError(f"pose must be finite, got {bad} NaN / inf entries")
    rot = pose[:3, :3]
    if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-4) or not np.allclose(pose[3], [0, 0, 0, 1]):
        raise InvalidInputError("pose must be rigid: orthonormal rotation and last row [0, 0, 0, 1]")
    if np.linalg.det(rot) < 0:
        raise InvalidInputError("pose must be a proper rotation (determinant +1): this one mirrors the "
                                "camera (an axis flipped, e.g. a left-handed frame)")
    return pose


def check_frame(rgb, depth, pose, height: int, width: int, min_depth_m: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Checked copies of one frame: uint8 colours (floats in [0, 1] are converted), float32 depth with the
    invalid pixels set to 0, the pose as a float64 4x4; and how many depth pixels were NaN, inf or
    negative. InvalidInputError on anything the map cannot take."""
    rgb, depth = np.asarray(rgb), np.asarray(depth)
    hw = (height, width)
    if rgb.shape != (*hw, 3):
        raise InvalidInputError(f"rgb must have shape {(*hw, 3)}, got {rgb.shape}")
    if depth.shape != hw:
        raise InvalidInputError(f"depth must have shape {hw}, got {depth.shape}")
    if rgb.dtype != np.uint8:
        if not np.issubdtype(rgb.dtype, np.floating) or not np.isfinite(rgb).all():
            raise InvalidInputError(f"rgb must be uint8 or finite floats in [0,1], got {rgb.dtype}")
        if rgb.size and float(rgb.max()) > 1.0 + 1e-3:
            raise InvalidInputError(f"float rgb must be in [0, 1], got values up to {float(rgb.max()):.4g} "
                                    f"(0-255 colours: divide by 255 or pass uint8)")
        rgb = (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    if not np.issubdtype(depth.dtype, np.floating):
        hint = " (millimetres? divide by 1000, or by the camera's depth scale)" \
            if np.issubdtype(depth.dtype, np.integer) else ""
        raise InvalidInputError(f"depth must be float metres, got {depth.dtype}{hint}")
    pose = as_pose(pose)
    depth = depth.astype(np.float32)
    broken = ~np.isfinite(depth) | (depth < 0)
    invalid = broken | (depth < min_depth_m)
    depth = np.where(invalid, np.float32(0.0), depth)
    sample = depth[::4, ::4]  # every 16th pixel: the median of a frame's scale, cheaply
    sample = sample[sample > 0]
    median = float(np.median(sample)) if sample.size else 0.0
    if median > MAX_MEDIAN_DEPTH_M:
        raise InvalidInputError(f"depth must be in metres: its median is {median:.4g} (over "
                                f"{MAX_MEDIAN_DEPTH_M:g} m for an indoor scene; millimetres? divide by 1000)")
    return np.ascontiguousarray(rgb), depth, pose, int(broken.sum())


def downsample_observation(rgb: torch.Tensor, depth: torch.Tensor,
                           d: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Average d x d blocks (the image of a camera with K[:2] / d): colour is the block mean, depth the
    block mean where every pixel of the block is valid, else 0 (invalid)."""
    if d == 1:
        return rgb, depth
    h, w = depth.shape[0] // d, depth.shape[1] // d
    rgb = rgb[: h * d, : w * d].reshape(h, d, w, d, 3).mean(dim=(1, 3))
    blocks = depth[: h * d, : w * d].reshape(h, d, w, d)
    all_valid = (blocks > 0).all(dim=3).all(dim=1)
    return rgb, torch.where(all_valid, blocks.mean(dim=(1, 3)), depth.new_zeros(()))
