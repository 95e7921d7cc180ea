"""Rasterizer speed: numba (CPU) vs the torch reference (and gsplat when CUDA is available).

Scene: N anisotropic Gaussians of 1-3 cm on the walls, floor and ceiling of a 6 x 4 x 2.8 m room,
camera inside at 1.25 m looking along the long axis; 256x256, 90 deg hfov. Prints a markdown table
of forward and forward+backward milliseconds (median of repeats) and the numba compile/warm time.
``--stages`` adds a table of the numba backend's CPU milliseconds per stage on one thread (minimum
over repeats, ``time.process_time``), which stays meaningful on a busy machine; "other" is the rest
of the forward+backward (Python, torch autograd, input checks).

    python benchmarks/raster.py [--sizes 10000 50000 200000] [--repeats 5] [--torch-max 200000] [--image 256]
                                [--stages] [--planar-depth]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import time

import torch

from activesplat.splat import rasterize
from activesplat.splat.raster import numba_backend as _raster_numba

WIDTH = HEIGHT = 256
ROOM = (6.0, 2.8, 4.0)  # x, y (up), z extents in metres
PLANAR = False  # --planar-depth


def room_gaussians(n: int, seed: int = 0):
    """N Gaussians of 1-3 cm scattered uniformly over the six faces of the room (area-weighted)."""
    gen = torch.Generator().manual_seed(seed)
    sx, sy, sz = ROOM
    faces = [(0, sx * sz), (1, sx * sy), (2, sy * sz)]  # normal axis, area; two faces each
    areas = torch.tensor([a for _, a in faces for _ in range(2)])
    face = torch.multinomial(areas, n, replacement=True, generator=gen)
    pts = torch.rand(n, 3, generator=gen) * torch.tensor(ROOM)
    axis = torch.tensor([1, 1, 2, 2, 0, 0])[face]  # y for floor/ceiling, z for long walls, x for short
    side = (face % 2).float() * torch.tensor(ROOM)[axis]
    pts[torch.arange(n), axis] = side
    quats = torch.randn(n, 4, generator=gen)
    scales = 0.01 + 0.02 * torch.rand(n, 3, generator=gen)
    opacities = 0.3 + 0.7 * torch.rand(n, generator=gen)
    colors = torch.rand(n, 3, generator=gen)
    return pts, quats, scales, opacities, colors


def camera():
    """viewmat and K: camera at the room centre, 1.25 m high, looking along +x, 90 deg hfov."""
    c2w = torch.eye(4, dtype=torch.float64)
    c2w[:3, :3] = torch.tensor([[0.0, 0, 1], [0, -1, 0], [1, 0, 0]], dtype=torch.float64)  # columns x, y, z
    c2w[:3, 3] = torch.tensor([ROOM[0] / 2 - 2.0, 1.25, ROOM[2] / 2], dtype=torch.float64)
    f = 0.5 * WIDTH / math.tan(math.radians(90) / 2)
    K = torch.tensor([[f, 0, WIDTH / 2], [0, f, HEIGHT / 2], [0, 0, 1]])
    return torch.linalg.inv(c2w).float(), K


def time_backend(params, backend: str, repeats: int) -> tuple[float, float, int]:
    """Median forward ms and forward+backward ms; also the number of rendered Gaussians."""
    view, K = camera()
    leaves = [p.clone().requires_grad_(True) for p in params]
    fwd, both = [], []
    visible = 0
    view, K = view.to(params[0].device), K.to(params[0].device)
    sync = torch.cuda.synchronize if params[0].is_cuda else (lambda: None)
    for _ in range(repeats + params[0].is_cuda):  # on the GPU the first run only warms up
        sync()
        t0 = time.perf_counter()
        out = rasterize(*leaves, view, K, WIDTH, HEIGHT, backend=backend, planar_depth=PLANAR)
        sync()
        t1 = time.perf_counter()
        (out.rgb.sum() + out.depth.sum() + out.alpha.sum()).backward()
        sync()
        t2 = time.perf_counter()
        fwd.append(1e3 * (t1 - t0))
        both.append(1e3 * (t2 - t0))
        visible = int((out.radii > 0).sum())
    return statistics.median(fwd), statistics.median(both), visible


STAGES = ("project", "sort", "bin", "composite", "composite_backward", "sum_grads", "project_backward")


def numba_stage_cpu(params, repeats: int) -> dict[str, float]:
    """Minimum CPU ms of each numba stage, and of the whole forward+backward. Only meaningful in a
    process with one thread (see :func:`print_stage_table`): process_time counts every thread."""
    view, K = camera()
    leaves = [p.clone().requires_grad_(True) for p in params]
    best: dict[str, float] = {}
    try:
        for _ in range(repeats + 1):  # the first run only warms caches
            _raster_numba.STAGE_CPU_MS = {}
            t0 = time.process_time()
            out = rasterize(*leaves, view, K, WIDTH, HEIGHT, backend="numba", planar_depth=PLANAR)
            (out.rgb.sum() + out.depth.sum() + out.alpha.sum()).backward()
            times = dict(_raster_numba.STAGE_CPU_MS, total=1e3 * (time.process_time() - t0))
            times["other"] = times["total"] - sum(times[k] for k in STAGES)
            best = times if not best else {k: min(v, times[k]) for k, v in best.items()}
    finally:
        _raster_numba.STAGE_CPU_MS = None
    return best


def stage_table_in_child(sizes, repeats: int) -> None:
    """Run :func:`print_stage_table` in a fresh process with one numba / torch / OpenMP thread (idle
    pool threads would otherwise add their spin-waiting to the process CPU time)."""
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    cmd = [sys.executable, __file__, "--stage-table-only", "--repeats", str(repeats),
           "--sizes", *map(str, sizes), *(["--planar-depth"] if PLANAR else [])]
    subprocess.run(cmd, env=env, check=True)


def print_stage_table(sizes, repeats: int) -> None:
    torch.set_num_threads(1)
    warm_time()
    print("\nnumba CPU ms per stage, one thread (min of repeats):\n")
    cols = (*STAGES, "other", "total")
    print("| N | " + " | ".join(cols) + " |")
    print("|" + "---|" * (len(cols) + 1))
    for n in sizes:
        best = numba_stage_cpu(room_gaussians(n), repeats)
        print(f"| {n} | " + " | ".join(f"{best[c]:.1f}" for c in cols) + " |", flush=True)


def warm_time() -> float:
    """Seconds to compile (or load from the disk cache) the numba kernels in this process."""
    from activesplat.splat.raster.numba_backend import warm_up

    t0 = time.perf_counter()
    warm_up()
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 50_000, 200_000])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--torch-max", type=int, default=200_000, help="largest N timed with torch")
    parser.add_argument("--torch-repeats", type=int, default=1)
    parser.add_argument("--image", type=int, default=256, help="square image side in pixels")
    parser.add_argument("--stages", action="store_true", help="also print per-stage CPU ms on one thread")
    parser.add_argument("--planar-depth", action="store_true", help="planar depth (splat.raster.planar)")
    parser.add_argument("--stage-table-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    global WIDTH, HEIGHT, PLANAR
    WIDTH = HEIGHT = args.image
    PLANAR = args.planar_depth
    if args.stage_table_only:
        print_stage_table(args.sizes, args.repeats)
        return
    warm = warm_time()
    cuda = torch.cuda.is_available()
    print(f"numba warm-up (compile or cache load): {warm:.2f} s; torch threads {torch.get_num_threads()}\n")
    head = ("| N | visible | numba fwd ms | numba fwd+bwd ms | torch fwd ms | torch fwd+bwd ms"
            " | speedup fwd+bwd |")
    print(head + (" gsplat fwd ms | gsplat fwd+bwd ms |" if cuda else ""))
    print("|" + "---|" * (7 + 2 * cuda))
    for n in args.sizes:
        params = room_gaussians(n)
        nf, nb, vis = time_backend(params, "numba", args.repeats)
        row = f"| {n} | {vis} | {nf:.1f} | {nb:.1f} |"
        if n <= args.torch_max:
            tf, tb, _ = time_backend(params, "torch", args.torch_repeats)
            row += f" {tf:.0f} | {tb:.0f} | {tb / nb:.1f}x |"
        else:
            row += " skipped | skipped | - |"
        if cuda:
            gparams = [p.cuda() for p in params]
            gf, gb, _ = time_backend(gparams, "gsplat", args.repeats)
            row += f" {gf:.2f} | {gb:.2f} |"
        print(row, flush=True)
    if args.stages:
        stage_table_in_child(args.sizes, args.repeats)


if __name__ == "__main__":
    main()
