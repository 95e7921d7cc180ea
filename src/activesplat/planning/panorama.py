"""Panoramas of visibility at a Voronoi node (paper sec. III-B2 and III-D2).

Three pinhole cameras (120 deg wide, 150 deg tall) rotated 0/120/240 deg in yaw are rendered from the
Gaussian map and stacked side by side into a 360 x 150 image of invisibility (1 - accumulated opacity)
and median depth. Every pixel also keeps its exact world ray, so cluster centres turn into yaw/pitch
targets and contour pixels back-project into 3D without the "1 px = 1 degree" approximation.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from activesplat.geometry import camera_pose, intrinsics
from activesplat.planning.config import PanoramaConfig

RenderFn = Callable[..., object]
"""`render(pose, K=..., width=..., height=...)` returning an object with `.alpha` and `.median_depth`
(e.g. `Mapper.render`)."""


@dataclass
class Panorama:
    """A stacked panorama at one position. All arrays are (H, W) or (H, W, 3), float32."""

    origin: np.ndarray
    """Camera centre in world coordinates (3,)."""
    invisibility: np.ndarray
    """1 - accumulated opacity, in [0, 1]."""
    median_depth: np.ndarray
    """z-depth along each camera's axis where transmittance first drops below 0.5 (0 = none)."""
    rays: np.ndarray
    """World direction per pixel scaled so that `origin + rays * median_depth` is the 3D point."""
    yaw: np.ndarray
    """World yaw of each pixel's ray (radians, geometry.heading convention)."""
    pitch: np.ndarray
    """World pitch of each pixel's ray (radians, up positive)."""
    solid_angle: np.ndarray
    """Solid angle of each pixel (sr). A 150-deg pinhole is far from 1 px per degree: its pixels near the
    horizon cover ~3x more angle than those near the top and bottom, so shares and cluster centres are
    weighted by this."""

    @property
    def shape(self) -> tuple[int, int]:
        return self.invisibility.shape

    def points(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """World points of the given pixels (using their median depth)."""
        z = self.median_depth[rows, cols][:, None]
        return self.origin[None, :] + self.rays[rows, cols] * z


def _camera_rays(cfg: PanoramaConfig) -> tuple[np.ndarray, np.ndarray]:
    """K and the camera-space rays (H, w, 3) with z = 1 of one panorama camera."""
    w, h = cfg.width_per_camera, cfg.height
    K = intrinsics(w, h, cfg.hfov_deg, cfg.vfov_deg)
    u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)
    return K, rays


def _pixel_solid_angle(K: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """Solid angle of pinhole pixels: cos(theta)^3 / (fx fy), theta the angle off the optical axis."""
    cos = 1.0 / np.linalg.norm(rays, axis=-1)
    return cos**3 / (K[0, 0] * K[1, 1])


def panorama_poses(origin, cfg: PanoramaConfig) -> list[np.ndarray]:
    """Camera-to-world poses of the panorama cameras, left to right in the stacked image.

    Camera c looks at yaw = -c * 360/n (yaw grows to the left, so stacking in decreasing yaw keeps the
    image continuous from left to right).
    """
    step = 2 * math.pi / cfg.n_cameras
    return [camera_pose(origin, -c * step, 0.0) for c in range(cfg.n_cameras)]


def render_panorama(render: RenderFn, origin, cfg: PanoramaConfig | None = None,
                    front_faces: bool = False) -> Panorama:
    """Render the visibility panorama at `origin` (world, camera height) with `render`. `front_faces`:
    visibility of surfaces from the side that observed them only (`PanoramaConfig.front_faces_targets`),
    where `render` can tell (a ``front_alpha`` parameter)."""
    cfg = cfg or PanoramaConfig()
    origin = np.asarray(origin, dtype=np.float64)
    poses = panorama_poses(origin, cfg)
    geometry = _geometry(cfg, poses)
    inv, med = [], []
    # a world model that cannot tell faces apart (no ``front_alpha`` parameter) gives the plain opacity
    front = ({"front_alpha": True, "behind_margin_deg": cfg.back_face_margin_deg}
             if front_faces and _takes(render, "front_alpha") else {})
    K = geometry.K
    for pose in poses:
        out = render(pose, K=K, width=cfg.width_per_camera, height=cfg.height, **front)
        inv.append(1.0 - _np(out.alpha))
        med.append(_np(out.median_depth))
    return Panorama(
        origin=origin,
        invisibility=np.clip(np.concatenate(inv, axis=1), 0.0, 1.0).astype(np.float32),
        median_depth=np.concatenate(med, axis=1).astype(np.float32),
        rays=geometry.rays,
        solid_angle=geometry.solid_angle,
        yaw=geometry.yaw,
        pitch=geometry.pitch,
    )


@dataclass(frozen=True)
class _Geometry:
    """What a panorama's pixels are, whatever is rendered into them: the cameras' K, and each pixel's world
    ray, yaw, pitch and solid angle (read-only arrays, shared by every panorama with these cameras)."""

    K: np.ndarray
    rays: np.ndarray
    yaw: np.ndarray
    pitch: np.ndarray
    solid_angle: np.ndarray


_GEOMETRY: dict[tuple, _Geometry] = {}
"""The pixel geometry per (config, camera rotations): the panorama cameras turn with their index only, so
every node of every replan shares one entry."""


def _geometry(cfg: PanoramaConfig, poses: list[np.ndarray]) -> _Geometry:
    """The :class:`_Geometry` of cameras ``poses`` (computed once per config and rotations)."""
    key = (cfg, np.stack([pose[:3, :3] for pose in poses]).tobytes())
    found = _GEOMETRY.get(key)
    if found is not None:
        return found
    K, cam_rays = _camera_rays(cfg)
    rays = np.concatenate([cam_rays @ pose[:3, :3].T for pose in poses], axis=1).astype(np.float32)
    horiz = np.hypot(rays[..., 0], rays[..., 2])
    arrays = (rays, np.arctan2(rays[..., 1], horiz).astype(np.float32),
              np.arctan2(rays[..., 0], rays[..., 2]).astype(np.float32),
              np.tile(_pixel_solid_angle(K, cam_rays), (1, cfg.n_cameras)).astype(np.float32))
    for a in (K, *arrays):
        a.setflags(write=False)
    rays, pitch, yaw, solid = arrays
    if len(_GEOMETRY) >= 16:  # a few configs per process at most; never grow without bound
        _GEOMETRY.clear()
    _GEOMETRY[key] = found = _Geometry(K, rays, yaw, pitch, solid)
    return found


def _takes(fn, name: str) -> bool:
    """Whether callable `fn` accepts keyword argument `name`."""
    try:
        params = inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())


def _np(x) -> np.ndarray:
    """A torch tensor or array as a float32 numpy array."""
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype=np.float32)
