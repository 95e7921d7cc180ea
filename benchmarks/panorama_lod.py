"""Scoring panoramas from the map itself against the coarser copy (``PanoramaConfig.score_lod_voxel_m``).

    python benchmarks/panorama_lod.py EPISODE [--every 80] [--voxel 0.05] [--inflate 1.3] [--threads 1]

Loads EPISODE's final map, renders a scoring panorama (plain opacity, as a replan does) at the
trajectory's floor position every ``--every`` steps, at the panorama height, once from the map and once
from ``splat.lod.voxel_lod``'s copy, and prints eq. 12's two information terms for both (invisible share
s_o and hull volume s_c, before normalisation), their correlation, whether the best position agrees, the
Gaussian counts and the CPU time per panorama (the copy's merge counted once). An episode saved partway
(``--steps``) gives the map of that moment.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from activesplat.planning.config import PlanningConfig
from activesplat.planning.explorer_config import ExplorerConfig
from activesplat.planning.panorama import render_panorama
from activesplat.planning.viewpoints import hull_volume, invisible_share
from activesplat.splat.mapper import Mapper


def scores(render, origins, pcfg: PlanningConfig) -> tuple[np.ndarray, float]:
    """(n, 2) invisible share and hull volume at ``origins``, and the CPU ms per panorama."""
    out, c0 = [], time.process_time()
    for o in origins:
        pano = render_panorama(render, o, pcfg.panorama)
        out.append((invisible_share(pano, pcfg.rotation), hull_volume(pano, pcfg.hull)))
    return np.array(out), 1000.0 * (time.process_time() - c0) / len(origins)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("episode", type=Path)
    ap.add_argument("--every", type=int, default=80, help="a panorama every this many trajectory steps")
    ap.add_argument("--voxel", type=float, default=0.05)
    ap.add_argument("--inflate", type=float, default=1.3)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    mapper = Mapper.load(args.episode)
    floor = json.loads((args.episode / "episode.json").read_text())["floor_height"]
    poses = np.loadtxt(args.episode / "poses.txt")[:, 1:].reshape(-1, 4, 4)
    height = floor + ExplorerConfig().panorama_height_m
    origins = [np.array([p[0, 3], height, p[2, 3]]) for p in poses[:: args.every]]
    pcfg = PlanningConfig()
    scores(mapper.snapshot(), origins[:1], pcfg)  # load the kernels
    full, ms_full = scores(mapper.snapshot(), origins, pcfg)
    c0 = time.process_time()
    coarse_snapshot = mapper.snapshot(lod_voxel_m=args.voxel, lod_inflate=args.inflate)
    coarse_snapshot(np.eye(4))  # builds the copy
    merge_s = time.process_time() - c0
    coarse, ms_coarse = scores(coarse_snapshot, origins, pcfg)
    n_coarse = len(coarse_snapshot._params["means"])
    print(f"{args.episode}: {len(origins)} panoramas, {len(mapper.gaussians)} -> {n_coarse} Gaussians "
          f"(voxel {args.voxel} m, inflate {args.inflate}), merge {merge_s:.2f} s")
    print("| term | mean, map | mean, copy | correlation | best position the same |")
    print("|---|---|---|---|---|")
    for k, name in enumerate(("invisible share s_o", "hull volume s_c (m^3)")):
        a, b = full[:, k], coarse[:, k]
        corr = float(np.corrcoef(a, b)[0, 1]) if a.std() > 0 and b.std() > 0 else float("nan")
        same = int(a.argmax()) == int(b.argmax())
        print(f"| {name} | {a.mean():.4f} | {b.mean():.4f} | {corr:.3f} | {same} |")
    print(f"CPU ms per panorama: map {ms_full:.0f}, copy {ms_coarse:.0f} "
          f"(+{1000 * merge_s / len(origins):.0f} for the merge spread over these panoramas)")


if __name__ == "__main__":
    main()
