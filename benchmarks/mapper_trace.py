"""Per-step trace of the online mapper inside a real exploration: where its time goes as the episode grows.

Runs ``activesplat explore`` with the given arguments and records, for every step, the mapper's wall time,
the map size and the mapper's phase timings (``FrameStats.timings``), and every ``--every`` steps the
spread of the Gaussians' sizes. Prints a table per bin of steps and writes the raw trace as JSON.

    python benchmarks/mapper_trace.py --trace runs/trace.json -- --scene small-0 --steps 1000 --seed 0 \
        --backend gsplat --out runs/small-0 --overwrite --no-progress

Written to find why small-0's mapper slows down on the GPU late in the episode (docs/gpu.md).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trace", type=Path, required=True, help="JSON file for the per-step trace")
    parser.add_argument("--bin", type=int, default=100, help="steps per row of the printed table")
    parser.add_argument("--every", type=int, default=100, help="steps between Gaussian size summaries")
    parser.add_argument("explore", nargs=argparse.REMAINDER,
                        help="arguments of `activesplat explore` (after --)")
    args = parser.parse_args(argv)
    explore_args = [a for a in args.explore if a != "--"]

    import torch

    from activesplat.cli import main as cli_main
    from activesplat.splat import Mapper

    rows: list[dict] = []
    original = Mapper.add_frame

    def traced(self, rgb, depth, pose, dense: bool = False):
        t0 = time.perf_counter()
        stats = original(self, rgb, depth, pose, dense=dense)
        row = {"step": len(rows) + 1, "ms": 1000.0 * (time.perf_counter() - t0), "n": len(self.gaussians),
               "mapped": bool(stats.mapped), "phases": dict(stats.timings)}
        if row["step"] % args.every == 0 and len(self.gaussians):
            with torch.no_grad():
                s = torch.exp(self.gaussians.params["log_scales"].detach()).max(dim=1).values.float()
                q = torch.quantile(s[torch.randperm(s.numel(), device=s.device)[:100_000]],
                                   torch.tensor([0.5, 0.99], device=s.device))
                row["scale"] = {"median": float(q[0]), "p99": float(q[1]), "max": float(s.max()),
                                "n_over_0.2m": int((s > 0.2).sum()), "n_over_1m": int((s > 1.0).sum())}
        rows.append(row)
        return stats

    Mapper.add_frame = traced
    try:
        rc = cli_main(["explore", *explore_args])
    finally:
        Mapper.add_frame = original
        args.trace.parent.mkdir(parents=True, exist_ok=True)
        args.trace.write_text(json.dumps(rows))
    _print_table(rows, args.bin)
    return rc or 0


def _print_table(rows: list[dict], width: int) -> None:
    phases = sorted({k for r in rows for k in r["phases"]})
    print(f"{'steps':>11} {'ms/step':>8} {'gaussians':>10} " + " ".join(f"{p[:10]:>10}" for p in phases))
    for lo in range(0, len(rows), width):
        chunk = rows[lo:lo + width]
        ms = sum(r["ms"] for r in chunk) / len(chunk)
        per = [sum(r["phases"].get(p, 0.0) for r in chunk) / len(chunk) for p in phases]
        print(f"{lo + 1:>5}-{lo + len(chunk):<5} {ms:8.1f} {chunk[-1]['n']:>10} "
              + " ".join(f"{v:10.1f}" for v in per))
    for r in rows:
        if "scale" in r:
            print(f"step {r['step']:>5}: Gaussian largest scale " + ", ".join(
                f"{k} {v:.3g}" for k, v in r["scale"].items()))


if __name__ == "__main__":
    sys.exit(main())
