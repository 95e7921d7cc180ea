"""How a live episode's map grows against the surface its camera has observed.

    python benchmarks/map_growth.py runs/medium-0-4000 [--every 1000]

Reads the episode folder of `activesplat explore` (its poses and the map size at each point of the
completion curve in metrics.json) and re-renders the simulator's depth at the run's own poses: nothing is
mapped again. Observed surface is counted as `benchmarks/mapper.py` counts it (5 cm voxels hit by
back-projected observed depth, every 4th pixel), here of every second frame. Prints, at every `--every`
steps: observed m², completion %, Gaussians and Gaussians per m² observed. A map whose memory grows with
the scene, not with time, keeps its Gaussians per m² from one row to the next (docs/mapping.md, "The
4000-step criterion against the observed surface").
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))  # benchmarks/mapper.py, also when loaded from a file
from mapper import SURFACE_VOXEL_M, episode_poses, observed_voxels  # noqa: E402


def growth_rows(episode: Path, every: int) -> list[dict]:
    """One row per `every` steps of the episode's completion curve: step, observed m², completion %,
    Gaussians and Gaussians per m² observed."""
    at = {p["step"]: p for p in json.loads((episode / "metrics.json").read_text())["curve"]}
    sim, poses, _dense = episode_poses(episode, None)
    voxels: set[tuple[int, int, int]] = set()
    rows = []
    for step, pose in enumerate(poses):
        if step % 2 == 0:
            _rgb, depth = sim.render(pose)
            voxels.update(map(tuple, observed_voxels(depth, pose, sim.K)))
        if step > 0 and step % every == 0 and step in at:
            area = len(voxels) * SURFACE_VOXEL_M ** 2
            n = at[step]["n_gaussians"]
            rows.append({"step": step, "observed_m2": area, "gaussians": n, "per_m2": n / area,
                         "completion_pct": at[step]["completion_ratio_pct"]})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("episode", type=Path, help="episode folder of `activesplat explore`")
    parser.add_argument("--every", type=int, default=1000, help="steps between rows")
    args = parser.parse_args()
    print("| step | observed m² | completion % | Gaussians | per m² |")
    print("|---|---|---|---|---|")
    for r in growth_rows(args.episode, args.every):
        print(f"| {r['step']} | {r['observed_m2']:.1f} | {r['completion_pct']:.2f} | {r['gaussians']:,} | "
              f"{r['per_m2']:.0f} |")


if __name__ == "__main__":
    main()
