"""Error budget of an episode's map: which pixels cost how many dB of render-eval's PSNR.

    python benchmarks/render_error.py EPISODE [EPISODE ...] [--gaussians PLY] [--splits train test]
                                      [--n-train 50] [--n-test 50] [--seed 0] [--json OUT]

EPISODE is an exploration episode folder with its ``gaussians.ply`` (or ``--gaussians``, e.g. the map a
``benchmarks/mapper.py --out DIR`` replay wrote: ``--gaussians DIR/gaussians.ply``). The views are exactly
render-eval's. Every pixel gets one class (``activesplat.eval.render_error``): holes the trajectory never
saw (the explorer's share), holes it saw only edge-on (more than 70 degrees off the surface normal),
holes it saw (the mapper's), translucent gaps, depth in front / behind by more than 10 cm, depth edges,
floor, ceiling and the rest. The table gives each class's share of the
pixels and of the squared colour error, how much the split's PSNR would rise were the class's error
halved (at most 3.01 dB), and its part of the depth L1 (cm; the parts add up to render-eval's depth
L1). With several episodes, a last table averages them.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from activesplat.eval.evaluate import parse_sim_overrides
from activesplat.eval.render_error import PIXEL_CLASSES, error_budget, format_budget


def average(results: list[dict], split: str) -> dict:
    rows = [r[split] for r in results if split in r]
    keys = ["pixels_pct", "error_pct", "gain_db"]
    out = {"psnr": float(np.mean([r["psnr"] for r in rows])), "n_views": sum(r["n_views"] for r in rows)}
    if all(r.get("depth_l1_cm") is not None for r in rows):
        keys.append("depth_l1_cm")
        out["depth_l1_cm"] = float(np.mean([r["depth_l1_cm"] for r in rows]))
    out["classes"] = {name: {key: float(np.mean([r["classes"][name][key] for r in rows])) for key in keys}
                      for name in PIXEL_CLASSES}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("episodes", type=Path, nargs="+")
    parser.add_argument("--gaussians", type=Path, nargs="*", default=None,
                        help="the map of each episode (default: EPISODE/gaussians.ply)")
    parser.add_argument("--splits", nargs="+", default=["train", "test"], choices=["train", "test"])
    parser.add_argument("--n-train", type=int, default=50)
    parser.add_argument("--n-test", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--backend", default="auto")
    parser.add_argument("--sim", nargs="*", default=[], metavar="FIELD=VALUE",
                        help="SimConfig overrides of the ground truth, e.g. texture_filter=nearest")
    parser.add_argument("--json", type=Path, help="write every budget here")
    args = parser.parse_args()
    maps = args.gaussians or [None] * len(args.episodes)
    if len(maps) != len(args.episodes):
        parser.error("give one --gaussians per episode")
    sim_overrides = parse_sim_overrides(args.sim)
    results = []
    for episode, gaussians in zip(args.episodes, maps, strict=True):
        result = error_budget(episode, gaussians, n_train=args.n_train, n_test=args.n_test, seed=args.seed,
                              splits=tuple(args.splits), backend=args.backend, sim_overrides=sim_overrides)
        results.append(result)
        print(f"## {result['scene']} ({episode})\n")
        print(format_budget(result))
    if len(results) > 1:
        print(f"## mean of {len(results)} episodes\n")
        print(format_budget({s: average(results, s) for s in args.splits}))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
