"""Exploration benchmark: scenes x policies x seeds -> a markdown table like the paper's Tab. I.

    python benchmarks/explore.py --scenes small-0 small-1 small-2 small-3 --policies activesplat fbe random
    python benchmarks/explore.py --scenes small-0 --policies activesplat --steps 300   # quick look

Episodes go to --root (default runs/bench/SCENE-POLICY-sSEED); a complete episode is reused, so an
interrupted benchmark resumes. Prints completion ratio (%), completion (cm), path length (m) and ms/step,
mean over seeds per scene and the average over scenes, plus the paper's module timings (Tab. VI).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from activesplat.explore import TIMING_KEYS, run_exploration


def run_one(scene: str, policy: str, seed: int, steps: int | None, root: Path) -> dict:
    out = root / f"{scene}-{policy}-s{seed}"
    done = out / "metrics.json"
    if done.exists():
        m = json.loads(done.read_text())
        if m.get("complete", True) and (steps is None or m.get("steps") == steps):
            return m
    return run_exploration(scene, policy=policy, steps=steps, seed=seed, out=out, overwrite=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", nargs="+", default=["small-0", "small-1", "small-2", "small-3"])
    ap.add_argument("--policies", nargs="+", default=["activesplat", "fbe", "random"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--steps", type=int, default=None, help="default: the scene's budget (1000 small)")
    ap.add_argument("--root", type=Path, default=Path("runs/bench"))
    args = ap.parse_args()

    results: dict[tuple[str, str], list[dict]] = {}
    for scene in args.scenes:
        for policy in args.policies:
            for seed in args.seeds:
                m = run_one(scene, policy, seed, args.steps, args.root)
                results.setdefault((scene, policy), []).append(m)

    def cell(ms: list[dict], key: str, fmt: str) -> str:
        vals = np.array([m[key] for m in ms], float)
        return f"{vals.mean():{fmt}}" + (f" ± {vals.std():{fmt}}" if len(vals) > 1 else "")

    print(f"\n### Exploration ({len(args.seeds)} seed(s); steps: {args.steps or 'scene default'})\n")
    print("| scene | policy | completion ratio % ↑ | completion cm ↓ | path length m | ms/step |")
    print("|---|---|---|---|---|---|")
    for (scene, policy), ms in results.items():
        print(f"| {scene} | {policy} | {cell(ms, 'completion_ratio_pct', '.2f')} | "
              f"{cell(ms, 'completion_cm', '.2f')} | {cell(ms, 'path_length_m', '.1f')} | "
              f"{cell(ms, 'ms_per_step', '.0f')} |")
    for policy in args.policies:
        ms = [m for (_, p), lst in results.items() if p == policy for m in lst]
        print(f"| **mean** | {policy} | {cell(ms, 'completion_ratio_pct', '.2f')} | "
              f"{cell(ms, 'completion_cm', '.2f')} | {cell(ms, 'path_length_m', '.1f')} | "
              f"{cell(ms, 'ms_per_step', '.0f')} |")

    print("\n### Mean time per step by module (ms; paper Tab. VI on an RTX 3090: mapper 45.1, "
          "workspace 43.9, Voronoi 0.69, subregions 1.56, rotation 2.76, position 6.46, planner 0.20)\n")
    print("| policy | " + " | ".join(TIMING_KEYS) + " |")
    print("|---|" + "---|" * len(TIMING_KEYS))
    for policy in args.policies:
        ms = [m for (_, p), lst in results.items() if p == policy for m in lst]
        print(f"| {policy} | " + " | ".join(f"{np.mean([m['timing_ms'][k] for m in ms]):.1f}"
                                            for k in TIMING_KEYS) + " |")


if __name__ == "__main__":
    main()
