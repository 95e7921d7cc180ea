"""The module path of :func:`rasterize` the mapper and older callers import; the rasterizer lives in
:mod:`activesplat.splat.raster`."""

from activesplat.splat.raster import BACKENDS, Backend, Projection, RenderOutput, gsplat_available, rasterize

__all__ = ["BACKENDS", "Backend", "Projection", "RenderOutput", "gsplat_available", "rasterize"]
