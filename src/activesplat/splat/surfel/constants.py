"""Constants of the 2D Gaussian surfel rasterizer (Huang et al., 2DGS, SIGGRAPH 2024) shared by its backends.

Blending thresholds (alpha cap, 1/255 skip, 1e-4 transmittance stop, median at T = 0.5, 16 px tiles,
near plane) are those of the 3D rasterizer (:data:`activesplat.splat.raster.constants.RASTER`), so a 3DGS
and a 2DGS map of the same scene composite alike; only the surfel-specific numbers live here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from activesplat.splat.raster.constants import RASTER


@dataclass(frozen=True)
class SurfelConstants:
    """Numbers of the 2DGS forward pass (paper sec. 4.2, eq. 11; ``diff-surfel-rasterization``)."""

    filter_inv_square: float = 2.0
    """Object-space low-pass of 2DGS eq. 11: G_2D(x) = exp(-0.5 filter_inv_square |x - c|^2) around the
    projected centre c, i.e. a screen Gaussian of sigma = sqrt(2)/2 px (2DGS ``FilterInvSquare``, gsplat
    ``FILTER_INV_SQUARE_2DGS``). A pixel uses max(G(u(x)), G_2D(x)); edge-on surfels stay visible."""
    box_pad: float = 0.01
    """Pixels added to the screen box of the alpha >= 1/255 footprint against float32 rounding."""
    power_pad: float = 1e-3
    """Margin on the exponent cut-off ln(255 o), so rounding never skips a term the exact test keeps."""

    @property
    def near(self) -> float:
        """Metres. A surfel is culled unless its whole alpha >= 1/255 disc lies beyond this view depth
        (then every ray-splat intersection that can contribute is in front of the camera)."""
        return RASTER.near

    @property
    def log_255(self) -> float:
        """ln(1 / alpha_min): alpha = o exp(-power) >= 1/255 iff power <= ln(255 o)."""
        return math.log(1.0 / RASTER.alpha_min)


SURFEL = SurfelConstants()
