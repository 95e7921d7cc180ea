"""Time a whole gsplat render with the median depth (the Triton kernel of splat/raster/median_triton.py) on
a sensor camera and on one panorama face, with centre and planar depth (splat/raster/planar.py), for 300k
and 1M Gaussians on the walls of a room (the scene of benchmarks/raster.py). Needs CUDA, gsplat and Triton.
docs/gpu.md, "Planar depth on the GPU".

    python benchmarks/median_gpu.py [--sizes 300000 1000000] [--repeats 20]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).parent))
from activesplat.geometry import intrinsics  # noqa: E402
from activesplat.planning.config import PanoramaConfig  # noqa: E402
from raster import room_gaussians  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[300_000, 1_000_000])
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args()
    if not torch.cuda.is_available():
        sys.exit("benchmarks/median_gpu.py needs CUDA (and gsplat, Triton)")
    from activesplat.splat.raster.gsplat_backend import rasterize_gsplat

    pano = PanoramaConfig()
    c2w = torch.eye(4, dtype=torch.float64)
    c2w[:3, :3] = torch.tensor([[0.0, 0, 1], [0, -1, 0], [1, 0, 0]], dtype=torch.float64)
    c2w[:3, 3] = torch.tensor([1.0, 1.25, 2.0], dtype=torch.float64)
    view = torch.linalg.inv(c2w).float().cuda()
    w, h = pano.width_per_camera, pano.height
    cameras = {"256 x 256, 90 deg": (256, 256, intrinsics(256, 256, 90.0)),
               f"panorama face {w} x {h}, {pano.hfov_deg:.0f} x {pano.vfov_deg:.0f} deg":
               (w, h, intrinsics(w, h, pano.hfov_deg, pano.vfov_deg))}
    print("| Gaussians | camera | render with median depth, ms: centre depth | planar depth |")
    print("|---|---|---|---|")
    for n in args.sizes:
        params = [t.cuda() for t in room_gaussians(n)]
        for name, (w, h, K) in cameras.items():
            Kt = torch.tensor(K, dtype=torch.float32).cuda()
            call = (*params, view, Kt, w, h, torch.zeros(3).cuda(), None)
            ms = []
            for planar in (False, True):
                for _ in range(3):
                    rasterize_gsplat(*call, planar_depth=planar)
                torch.cuda.synchronize()
                t0 = time.perf_counter()
                for _ in range(args.repeats):
                    rasterize_gsplat(*call, planar_depth=planar)
                torch.cuda.synchronize()
                ms.append(1000 * (time.perf_counter() - t0) / args.repeats)
            print(f"| {n:,} | {name} | {ms[0]:.2f} | {ms[1]:.2f} |", flush=True)


if __name__ == "__main__":
    main()
