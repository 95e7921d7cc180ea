"""Offline refinement of the map from the keyframe buffer (paper sec. III-D4): ``activesplat refine``.

``refine(DIR, method="3dgs" | "2dgs", iters=N)`` optimises the episode's map with RGB + depth losses and
3DGS adaptive density control (3dgs) or as 2D Gaussian surfels with the 2DGS regularisers (2dgs), and
writes ``DIR/refined_<method>/`` (gaussians.ply, render_metrics.json, refine.json, checkpoint.pt).
"""

from activesplat.refine.config import METHODS, RefineConfig
from activesplat.refine.summary import refine_from_command
from activesplat.refine.trainer import Refiner, RefineResult, refine

__all__ = ["METHODS", "RefineConfig", "RefineResult", "Refiner", "refine", "refine_from_command"]
