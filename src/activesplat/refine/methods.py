"""The two refinement methods as renderer adapters the trainer drives the same way.

A method renders the map from a keyframe camera, adds its own regularisers to the loss, reports the
view-space gradient statistic that density control accumulates, and says how its map is written to a
PLY file. ``3dgs`` renders 3D Gaussians with :func:`activesplat.splat.rasterize`; ``2dgs`` renders the
same parameters as 2D surfels (see :mod:`activesplat.refine.surfels`).
"""

from __future__ import annotations

import torch

from activesplat.refine.adc import ndc_grad_norm
from activesplat.refine.config import RefineConfig
from activesplat.splat.gaussians import GaussianMap


class Splatting3D:
    """3D Gaussian splatting (3DGS): the rasterizer of the online map, densified by the 2D-mean gradient."""

    name = "3dgs"
    ply_layout = "3dgs: the standard 3DGS PLY, as optimised"

    def __init__(self, cfg: RefineConfig, iters: int, backend: str = "auto", planar_depth: bool = False):
        self.cfg, self.iters, self.backend = cfg, iters, backend
        self.planar_depth = planar_depth
        """Render depth as the online map was trained (``MapperConfig.planar_depth``, from its mapper.json):
        the refined map keeps it, and render-eval reads it from refine.json."""

    def prepare(self, gmap: GaussianMap) -> GaussianMap:
        """The map the method optimises, made from the online map (3DGS: unchanged)."""
        return gmap

    def render(self, gmap: GaussianMap, viewmat: torch.Tensor, K: torch.Tensor, width: int, height: int,
               track_grad2d: bool = False):
        from activesplat.splat.rasterize import rasterize

        out = rasterize(gmap.means, gmap.quats, gmap.scales, gmap.opacities, gmap.colors, viewmat, K,
                        width, height, backend=self.backend, planar_depth=self.planar_depth)
        if track_grad2d and out.means2d.requires_grad:
            out.means2d.retain_grad()
        return out

    def regularisers(self, out, iteration: int, K: torch.Tensor) -> tuple[torch.Tensor | float, dict]:
        """Extra loss terms at (1-based) ``iteration``: none for 3DGS."""
        return 0.0, {}

    def grad_stats(self, out, gmap: GaussianMap, viewmat: torch.Tensor, K: torch.Tensor, width: int,
                   height: int) -> tuple[torch.Tensor, torch.Tensor]:
        """(N,) NDC norm of the 2D-mean gradient and (N,) visibility (screen radius > 0), after backward."""
        grad = out.means2d.grad
        if grad is None:
            grad = torch.zeros(len(gmap), 2, device=gmap.device)
        return ndc_grad_norm(grad, width, height), out.radii > 0

    def export(self, gmap: GaussianMap) -> GaussianMap:
        """The map as it goes into ``gaussians.ply`` (3DGS: as optimised)."""
        return gmap

    def eval_kwargs(self) -> dict:
        """Extra arguments of ``render_eval`` for maps of this method (3DGS: none, the default renderer)."""
        return {}

    def eval_renderer(self) -> str:
        """Which rasterizer render_metrics.json is computed with (recorded in refine.json)."""
        return "3D Gaussian rasterizer" + (", planar depth" if self.planar_depth else "")


def make_method(name: str, cfg: RefineConfig, iters: int, backend: str = "auto", planar_depth: bool = False):
    """The adapter of method ``name`` (validated by the caller); ``planar_depth`` applies to 3DGS only (the
    surfels of 2DGS have their own depth)."""
    if name == "3dgs":
        return Splatting3D(cfg, iters, backend, planar_depth)
    from activesplat.refine.surfels import Surfels2D

    return Surfels2D(cfg, iters, backend)
