"""A tiny episode folder for refinement tests, rendered from a known Gaussian scene.

Ground truth: a textured wall of Gaussians at z = 2 m and a grey box face at z = 1.4 m, seen by a few 32x32
pinhole cameras (90 deg) that slide and turn a little. The keyframes are renders of that scene (so the
ground truth is reachable exactly); the "online map" written next to them is the ground truth spoiled
(colour noise, jittered centres, wider scales, and a share of the Gaussians removed), so refinement
has colour, geometry and coverage to recover. Written with :meth:`Mapper.save` (the episode format).
"""

from pathlib import Path

import numpy as np
import torch

from activesplat.splat import GaussianMap, Mapper, rasterize
from activesplat.splat.keyframes import Keyframe

SIZE = 32


def intrinsics(size: int = SIZE) -> np.ndarray:
    f = size / 2.0
    return np.array([[f, 0, size / 2], [0, f, size / 2], [0, 0, 1]])


def camera(tx: float, yaw_deg: float) -> np.ndarray:
    a = np.radians(yaw_deg)
    p = np.eye(4)
    p[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    p[:3, 3] = [tx, 0.0, 0.0]
    return p


def ground_truth() -> GaussianMap:
    """A 24x24 wall of Gaussians (z = 2) with a smooth colour pattern, and a 6x6 box face (z = 1.4)."""
    xs = np.linspace(-1.8, 1.8, 24)
    gx, gy = np.meshgrid(xs, xs)
    wall = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, 2.0)], axis=1)
    wall_rgb = np.stack([0.5 + 0.35 * np.sin(2.5 * gx), 0.5 + 0.35 * np.cos(2.0 * gy),
                         0.5 + 0.2 * np.sin(gx + gy)], axis=-1).reshape(-1, 3)
    bs = np.linspace(-0.3, 0.3, 6)
    bx, by = np.meshgrid(bs, bs)
    box = np.stack([bx.ravel() + 0.2, by.ravel(), np.full(bx.size, 1.4)], axis=1)
    points = torch.tensor(np.concatenate([wall, box]), dtype=torch.float32)
    rgb = torch.tensor(np.concatenate([wall_rgb, np.full((len(box), 3), 0.25)]), dtype=torch.float32)
    radii = torch.cat([torch.full((len(wall),), 0.1), torch.full((len(box),), 0.07)])
    return GaussianMap.from_points(points, rgb, radii, opacity=0.98)


def render_views(gmap: GaussianMap, poses: list[np.ndarray], K: np.ndarray, size: int = SIZE):
    """(rgb uint8, depth float32) of every pose; depth = expected depth sum w z / O of the render."""
    views = []
    Kt = torch.tensor(K, dtype=torch.float32)
    with torch.no_grad():
        for p in poses:
            viewmat = torch.tensor(np.linalg.inv(p), dtype=torch.float32)
            out = rasterize(gmap.means, gmap.quats, gmap.scales, gmap.opacities, gmap.colors, viewmat, Kt,
                            size, size, backend="numba")
            rgb = (out.rgb.clamp(0, 1).numpy() * 255 + 0.5).astype(np.uint8)
            depth = torch.where(out.alpha > 0.5, out.depth / out.alpha.clamp_min(1e-6), 0.0).numpy()
            views.append((rgb, depth.astype(np.float32)))
    return views


def spoil(gmap: GaussianMap, seed: int = 0, drop: float = 0.2) -> GaussianMap:
    """The ground truth with colour noise, jittered centres, 1.2x scales, and ``drop`` of it removed."""
    gen = torch.Generator().manual_seed(seed)
    raw = gmap.raw()
    n = len(gmap)
    raw["f_dc"] = raw["f_dc"] + 0.3 * torch.randn(n, 3, generator=gen)
    raw["means"] = raw["means"] + 0.01 * torch.randn(n, 3, generator=gen)
    raw["log_scales"] = raw["log_scales"] + np.log(1.2)
    keep = torch.rand(n, generator=gen) >= drop
    return GaussianMap({k: v[keep] for k, v in raw.items()})


def make_episode(folder: str | Path, n_views: int = 6, seed: int = 0) -> Path:
    """Write keyframes.npz, mapper.json and gaussians.ply of the spoiled scene into ``folder``."""
    folder = Path(folder)
    K = intrinsics()
    shifts, yaws = np.linspace(-0.4, 0.4, n_views), np.linspace(-12, 12, n_views)
    poses = [camera(tx, yaw) for tx, yaw in zip(shifts, yaws, strict=True)]
    truth = ground_truth()
    mapper = Mapper(K, SIZE, SIZE, backend="numba")
    mapper.keyframes = [Keyframe(rgb, depth, p, i) for i, ((rgb, depth), p) in
                        enumerate(zip(render_views(truth, poses, K), poses, strict=True))]
    mapper.gaussians = spoil(truth, seed)
    mapper.frames = n_views
    mapper.save(folder)
    return folder
