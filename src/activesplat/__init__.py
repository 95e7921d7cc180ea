"""activesplat: autonomous exploration that builds a 3D Gaussian-splatting map (ActiveSplat, RA-L 2025).

The closed loop, one subpackage per part (each depends only on those before it):

- ``sim``       scenes (procedural houses, mesh loading), Embree RGB-D sensor, agent + actions
- ``splat``     Gaussian parameters, rasterizer backends, online mapper (paper sec. III-A)
- ``workspace`` top-down maps, Voronoi graph, subregions, safe paths (sec. III-A, III-C)
- ``planning``  viewpoint selection and hierarchical planning (sec. III-B, III-C)
- ``eval``      completion and rendering metrics (sec. IV)
- ``refine``    offline 3DGS / 2DGS refinement (sec. III-D4)
- ``viz``       plots and viewer
"""

from activesplat.errors import ActiveSplatError

__version__ = "0.1.0"
__all__ = ["ActiveSplatError", "__version__"]
