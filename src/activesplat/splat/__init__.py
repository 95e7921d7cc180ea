"""Gaussian map: parameters, rasterizer backends, online mapper (paper sec. III-A)."""

from activesplat.splat.rasterize import RenderOutput, rasterize

__all__ = ["RenderOutput", "rasterize"]

# --- online mapper (paper sec. III-A)
from activesplat.splat.config import MapperConfig  # noqa: E402
from activesplat.splat.gaussians import GaussianMap  # noqa: E402
from activesplat.splat.keyframes import Keyframe  # noqa: E402
from activesplat.splat.mapper import FrameStats, Mapper  # noqa: E402
from activesplat.splat.ply import load_ply, save_ply  # noqa: E402

__all__ += ["FrameStats", "GaussianMap", "Keyframe", "Mapper", "MapperConfig", "load_ply", "save_ply"]

# --- 2D Gaussian surfels (refine --method 2dgs)
from activesplat.splat.surfel import SurfelRenderOutput, rasterize_surfels  # noqa: E402

__all__ += ["SurfelRenderOutput", "rasterize_surfels"]
