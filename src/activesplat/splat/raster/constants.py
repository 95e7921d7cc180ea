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
    clamp_cull_depth: float = 0.0
    """Cull a Gaussian whose centre lies outside that clamp window and nearer than this view depth
    (metres; ours; 0 = never, as 3DGS and gsplat, which render it with the Jacobian of the window's edge;
    inf = at any depth). Its screen covariance is that of a Gaussian elsewhere: a flat Gaussian of a wall
    just beside and in front of the camera, seen edge-on, becomes a blob over much of the image (a
    render-eval test view 16 cm from a wall on medium-3: 39 cm depth L1). The live seed-0 maps of
    medium-0..3 rendered again with inf: test depth L1 4.65 -> 4.26 cm, the rest equal or better; mapping
    and exploring with inf lost completion (tuning houses 86.60 -> 86.48 %, small houses 98.7 -> 98.5 % of
    the ceiling, fresh medium-100..109 seed 0 86.37 -> 85.60 %, 7 of 10 lower). Nearly all of the depth
    gain comes from Gaussians nearer than 0.5 m (medium-2 / medium-3 maps: 5.13 / 4.34 cm -> 4.65 / 3.44
    with 0.5, 4.64 / 3.44 with inf), yet mapping and exploring with 0.5 lost as much: tuning houses 86.33
    vs 86.60 %, fresh 85.38 vs 86.37 % (docs/protocol.md §6, "Views beside a wall"). A compile-time
    constant of the numba kernels: change `raster/numba_project.py` with it (numba's cache is keyed on
    that file)."""


RASTER = RasterConstants()
