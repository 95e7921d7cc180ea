"""Constants of the 3DGS rasterizer shared by every backend (Kerbl et al. 2023, CUDA reference code).

They are the semantics of ``activesplat.splat.rasterize``; a backend that changes one no longer
renders the same image. Each is a float the numba kernels read as a compile-time float32 constant.
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class RasterConstants:
    """Numbers of the 3DGS forward pass (``forward.cu`` / ``backward.cu`` of diff-gaussian-rasterization)."""

    tile_size: int = 16
    """Pixels per side of a screen tile (3DGS ``BLOCK_X`` = ``BLOCK_Y``)."""
    low_pass: float = 0.3
    """Added to the diagonal of the 2D covariance (EWA low-pass filter, 3DGS ``computeCov2D``)."""
    alpha_max: float = 0.99
    """alpha_i = min(alpha_max, o_i exp(-power))."""
    alpha_min: float = 1.0 / 255.0
    """Contributions with alpha below this are skipped."""
    transmittance_min: float = 1e-4
    """A pixel stops as soon as T * (1 - alpha) would fall below this (the Gaussian is not blended)."""
    median_transmittance: float = 0.5
    """Median depth = view depth of the Gaussian at which T first drops below this."""
    near: float = 0.01
    """Gaussians with view-space z <= near (metres) are culled."""
    extent_sigmas: float = 3.0
    """Screen radius = ceil(extent_sigmas sqrt(largest eigenvalue of the 2D covariance)) (tile binning)."""
    min_eigen_gap: float = 0.1
    """3DGS floors (mid^2 - det) at this before the square root of the eigenvalue computation."""
    fov_clamp: float = 0.3
    """The Jacobian is evaluated at x/z clamped to the image edge plus this fraction of tan(fov/2) (3DGS)."""
    cull_outside_clamp: bool = True
    """Gaussians whose centre lies outside that clamp window (x/z or y/z beyond it) are culled (ours; 3DGS
    and gsplat render them with the Jacobian of the window's edge). Their screen covariance is then that of
    a Gaussian somewhere else: a flat Gaussian of a wall a few cm beside and in front of the camera, seen
    edge-on, becomes a blob over much of the image, and render-eval's test views that stand beside a wall
    showed that wall where the corridor beyond it is (a 39 cm depth L1 view on medium-3). The live seed-0
    maps of medium-0..3 rendered again with it: test depth L1 4.65 -> 4.26 cm, the other metrics equal or
    better (docs/protocol.md §6, "Views beside a wall")."""


RASTER = RasterConstants()
