"""2DGS surfel rasterizer speed: numba (CPU) vs the torch reference.

Scene: the room of ``benchmarks/raster.py`` (6 x 4 x 2.8 m, camera inside at 1.25 m looking along the
long axis, 256x256, 90 deg hfov) covered by N surfels of 1-3 cm lying flat on its walls, floor and
ceiling (random in-plane rotation). Prints a markdown table of forward and forward+backward
milliseconds (median of repeats; the loss sums rgb, depth, alpha, normal and distortion), the numba
compile/warm time, and the torch reference at the sizes up to ``--torch-max`` for the speed ratio.

    python benchmarks/raster_surfel.py [--sizes 10000 50000 200000] [--repeats 5] [--torch-sizes 2000]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import torch

from activesplat.splat import rasterize_surfels
from raster import HEIGHT, ROOM, WIDTH, camera, room_gaussians

OUTPUTS = ("rgb", "depth", "alpha", "normal", "distortion")


def room_surfels(n: int, seed: int = 0):
    """N surfels of 1-3 cm on the room's faces, normals along the face normals."""
    means, _quats, scales, opacities, colors = room_gaussians(n, seed)
    on_face = (means == 0) | (means == torch.tensor(ROOM))  # the coordinate that room_gaussians pinned
    axis = torch.argmax(on_face.int(), dim=1)
    half = math.sqrt(0.5)
    to_axis = torch.tensor([[half, 0, half, 0], [half, -half, 0, 0], [1.0, 0, 0, 0]])[axis]  # z -> x, y, z
    spin = torch.rand(n, generator=torch.Generator().manual_seed(seed + 1)) * math.pi
    in_plane = torch.stack([torch.cos(spin), torch.zeros(n), torch.zeros(n), torch.sin(spin)], dim=1)
    return means, quat_mul(to_axis, in_plane), scales[:, :2].contiguous(), opacities, colors


def quat_mul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product of (N,4) wxyz quaternions."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                        aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], dim=-1)


def time_backend(params, backend: str, repeats: int) -> tuple[float, float, int]:
    """Median forward ms and forward+backward ms; also the number of rendered surfels."""
    view, K = camera()
    leaves = [p.clone().requires_grad_(True) for p in params]
    fwd, both = [], []
    visible = 0
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = rasterize_surfels(*leaves, view, K, WIDTH, HEIGHT, backend=backend)
        t1 = time.perf_counter()
        sum(out[name].sum() for name in OUTPUTS).backward()
        t2 = time.perf_counter()
        fwd.append(1e3 * (t1 - t0))
        both.append(1e3 * (t2 - t0))
        visible = int((out.radii > 0).sum())
    return statistics.median(fwd), statistics.median(both), visible


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 50_000, 200_000])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--torch-sizes", type=int, nargs="*", default=[2_000],
                        help="N also timed with the torch reference (slow)")
    parser.add_argument("--torch-repeats", type=int, default=1)
    args = parser.parse_args()
    from activesplat.splat.surfel.numba_backend import warm_up

    t0 = time.perf_counter()
    warm_up()
    warm = time.perf_counter() - t0
    print(f"numba warm-up (compile or cache load): {warm:.2f} s; torch threads {torch.get_num_threads()}\n")
    print("| N | visible | numba fwd ms | numba fwd+bwd ms | torch fwd ms | torch fwd+bwd ms"
          " | speedup fwd+bwd |")
    print("|---|---|---|---|---|---|---|")
    for n in sorted(set(args.sizes) | set(args.torch_sizes)):
        params = room_surfels(n)
        nf, nb, vis = time_backend(params, "numba", args.repeats)
        row = f"| {n} | {vis} | {nf:.1f} | {nb:.1f} |"
        if n in args.torch_sizes:
            tf, tb, _ = time_backend(params, "torch", args.torch_repeats)
            row += f" {tf:.0f} | {tb:.0f} | {tb / nb:.1f}x |"
        else:
            row += " - | - | - |"
        print(row, flush=True)


if __name__ == "__main__":
    main()
