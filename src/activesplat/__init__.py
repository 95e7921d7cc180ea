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

import os

# OpenMP threads (torch's and numba's "omp" threading layer) busy-wait between parallel regions by default;
# on a machine whose cores are shared that makes every process crawl (measured under load: one LPIPS call
# 2.6 s -> 0.12 s, render-eval 402 s -> 41 s). Sleep instead; set OMP_WAIT_POLICY yourself to override.
# It must be set before torch / numba load libgomp, hence here, first.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from activesplat.errors import ActiveSplatError  # noqa: E402

__version__ = "0.1.0"
__all__ = ["ActiveSplatError", "__version__"]
