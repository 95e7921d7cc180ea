"""Exhaustive-sweep reference per scene: the coverage ceiling an explorer can approach (issue #6).

    python benchmarks/sweep.py --scenes small-0 small-1 small-2 small-3

Prints a markdown table (completion ratio %, completion cm, uncapped cm, standing positions, views, s).
"""

from __future__ import annotations

import argparse
import time

from activesplat.eval.sweep import SweepConfig, exhaustive_sweep


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["small-0", "small-1", "small-2", "small-3"])
    ap.add_argument("--spacing", type=float, default=SweepConfig.spacing_m, help="grid spacing (m)")
    ap.add_argument("--yaw-step", type=float, default=SweepConfig.yaw_step_deg, help="yaw step (deg)")
    args = ap.parse_args()
    cfg = SweepConfig(spacing_m=args.spacing, yaw_step_deg=args.yaw_step)
    print("| scene | completion ratio % | completion cm | uncapped cm | positions | views | s |")
    print("|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        t0 = time.perf_counter()
        m = exhaustive_sweep(scene, cfg=cfg)
        print(f"| {scene} | {m['completion_ratio_pct']:.2f} | {m['completion_cm']:.2f} | "
              f"{m['completion_cm_uncapped']:.2f} | {m['n_positions']} | {m['n_views']} | "
              f"{time.perf_counter() - t0:.0f} |", flush=True)


if __name__ == "__main__":
    main()
