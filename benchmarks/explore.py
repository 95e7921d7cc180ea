"""Exploration benchmark: scenes x policies x seeds -> the paper-style tables of `activesplat benchmark`.

    python benchmarks/explore.py --scenes small-0 small-1 small-2 small-3 --policies activesplat fbe random
    python benchmarks/explore.py --scenes small-0 --policies activesplat --steps 300   # quick look

A thin wrapper over `activesplat.bench.run_benchmark` (the same as `activesplat benchmark`) that takes any
list of seeds. Episodes go to ROOT/SCENE/POLICY/sSEED (default root runs/bench); complete ones are reused, so
an interrupted benchmark resumes. Prints and writes ROOT/results.md (Tab. I, per-scene table, Tab. VI),
ROOT/results.csv and ROOT/curves_*.png; docs/benchmark.md has the details.
"""

from __future__ import annotations

import argparse

from activesplat.bench import run_benchmark


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", nargs="+", default=["small-0", "small-1", "small-2", "small-3"])
    ap.add_argument("--policies", nargs="+", default=["activesplat", "fbe", "random"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--steps", type=int, default=None, help="default: the scene's budget (1000 small)")
    ap.add_argument("--root", default="runs/bench")
    ap.add_argument("--workers", type=int, default=1, help="parallel processes")
    ap.add_argument("--no-ceiling", action="store_true",
                    help="skip the sweep ceiling of each scene (the multi-room table's reference)")
    args = ap.parse_args()
    report = run_benchmark(args.scenes, args.policies, trials=max(1, len(args.seeds)), seeds=args.seeds,
                           steps=args.steps, root=args.root, workers=args.workers,
                           ceiling=not args.no_ceiling)
    print("\n" + report.markdown)


if __name__ == "__main__":
    main()
