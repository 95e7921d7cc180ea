"""Small random Gaussian scenes shared by the rasterizer tests."""

from __future__ import annotations

import math

import torch


def intrinsics(width: int, height: int, hfov_deg: float = 90.0, dtype=torch.float32) -> torch.Tensor:
    """Pinhole K with the principal point at the image centre (project convention)."""
    f = 0.5 * width / math.tan(math.radians(hfov_deg) / 2)
    return torch.tensor([[f, 0, width / 2], [0, f, height / 2], [0, 0, 1]], dtype=dtype)


def random_scene(n: int, seed: int, *, iso: bool = False, scale=(0.05, 0.3), opacity=(0.05, 0.95),
                 depth=(1.0, 4.0), spread: float = 1.0, dtype=torch.float32):
    """N Gaussians in front of a camera at the origin looking down +z (viewmat = identity)."""
    g = torch.Generator().manual_seed(seed)
    z = depth[0] + (depth[1] - depth[0]) * torch.rand(n, generator=g, dtype=dtype)
    xy = (torch.rand(n, 2, generator=g, dtype=dtype) * 2 - 1) * spread * z[:, None]
    means = torch.cat([xy, z[:, None]], dim=1)
    quats = torch.randn(n, 4, generator=g, dtype=dtype)
    cols = 1 if iso else 3
    s = scale[0] + (scale[1] - scale[0]) * torch.rand(n, cols, generator=g, dtype=dtype)
    scales = s.expand(n, 3).clone()
    opacities = opacity[0] + (opacity[1] - opacity[0]) * torch.rand(n, generator=g, dtype=dtype)
    colors = torch.rand(n, 3, generator=g, dtype=dtype)
    return means, quats, scales, opacities, colors


def look_down_viewmat(height: float, centre=(0.0, 0.0), dtype=torch.float32) -> torch.Tensor:
    """World-to-camera of a camera `height` m above (centre[0], 0, centre[1]) looking down -y.

    Image right = world +x, image down = world +z (OpenCV axes, y-up world).
    """
    c2w = torch.eye(4, dtype=torch.float64)
    c2w[:3, :3] = torch.tensor([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=torch.float64)
    c2w[:3, 3] = torch.tensor([centre[0], height, centre[1]], dtype=torch.float64)
    return torch.linalg.inv(c2w).to(dtype)
