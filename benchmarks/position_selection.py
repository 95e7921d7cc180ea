"""Where a replan's position selection spends its time, on an episode's final map.

    python benchmarks/position_selection.py EPISODE [--panoramas 30] [--threads 2] [--seed 0]

Loads EPISODE's final map and renders scoring panoramas as a replan does (from the coarser copy,
``PanoramaConfig.score_lod_voxel_m``, plain opacity) at ``--panoramas`` positions of
the trajectory, then prints one table: the merge into the coarser copy
(its first call, when its arrays are new, and a repeat), and per panorama the render, split by the
rasterizer's kernels (cProfile's own time per function), the rotation targets, the hull volume and the
invisible share. Wall-clock ms; numba kernels are compiled (and cached) before the clock starts.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from pathlib import Path

import numba
import numpy as np
import torch

from activesplat.planning.config import PlanningConfig
from activesplat.planning.panorama import render_panorama
from activesplat.planning.viewpoints import hull_volume, invisible_share, rotation_candidates
from activesplat.splat.lod import voxel_lod
from activesplat.splat.mapper import Mapper

KERNELS = {  # cProfile function name -> row label
    "bin_features": "tile binning",
    "composite_forward": "blending",
    "cull_rows": "frustum culling",
    "stable_depth_order": "depth sort",
    "project_forward": "projection",
    "index_select": "row gathers",
}


def _ms(fn, *args, **kw) -> tuple[float, object]:
    t = time.perf_counter()
    out = fn(*args, **kw)
    return 1000.0 * (time.perf_counter() - t), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("episode", type=Path)
    ap.add_argument("--panoramas", type=int, default=30, help="scoring panoramas to time")
    ap.add_argument("--threads", type=int, default=2, help="torch and numba threads")
    ap.add_argument("--seed", type=int, default=0, help="which trajectory positions")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    numba.set_num_threads(args.threads)
    mapper = Mapper.load(args.episode)
    pcfg = PlanningConfig()
    voxel = pcfg.panorama.score_lod_voxel_m
    poses = np.loadtxt(args.episode / "poses.txt", ndmin=2)[:, 1:].reshape(-1, 4, 4)
    pick = np.random.default_rng(args.seed).choice(len(poses), min(args.panoramas, len(poses)), replace=False)
    origins = poses[pick, :3, 3]
    params = {k: v.detach() for k, v in mapper.gaussians.params.items()}
    first, copy = _ms(voxel_lod, params, voxel)
    repeat, _ = _ms(voxel_lod, params, voxel)
    snap = mapper.snapshot(lod_voxel_m=voxel)
    warm = render_panorama(snap, origins[0], pcfg.panorama)  # merge, activation, kernels loaded
    rotation_candidates(warm, pcfg.rotation)
    hull_volume(warm, pcfg.hull)
    totals = {"render": 0.0, "rotation targets": 0.0, "hull volume": 0.0, "invisible share": 0.0}
    prof = cProfile.Profile()
    for origin in origins:
        prof.enable()
        ms, pano = _ms(render_panorama, snap, origin, pcfg.panorama)
        prof.disable()
        totals["render"] += ms
        totals["rotation targets"] += _ms(rotation_candidates, pano, pcfg.rotation)[0]
        totals["hull volume"] += _ms(hull_volume, pano, pcfg.hull)[0]
        totals["invisible share"] += _ms(invisible_share, pano, pcfg.rotation)[0]
    own = {label: 0.0 for label in KERNELS.values()}
    for (_, _, name), stat in pstats.Stats(prof).stats.items():
        for key, label in KERNELS.items():
            if key in name:
                own[label] += 1000.0 * stat[2]
    n = len(origins)
    print(f"## Position selection on {args.episode} ({len(params['means']):,} Gaussians, coarser copy "
          f"{len(copy['means']):,}; {n} panoramas, {args.threads} threads)\n")
    print("| part | ms |\n|---|---|")
    print(f"| merge into the coarser copy, first call / repeat (per replan) | {first:.0f} / {repeat:.0f} |")
    for label, total in totals.items():
        print(f"| {label}, per panorama | {total / n:.1f} |")
        if label == "render":
            for kernel, t in own.items():
                print(f"| &nbsp;&nbsp;of it {kernel} (cProfile own time) | {t / n:.1f} |")


if __name__ == "__main__":
    main()
