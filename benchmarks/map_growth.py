"""How a live episode's map grows against the surface its camera has observed.

    python benchmarks/map_growth.py runs/medium-0-4000 [--every 1000] [--earlier runs/medium-0-2000]

Reads the episode folder of `activesplat explore` (its poses and the map size at each point of the
completion curve in metrics.json) and re-renders the simulator's depth at the run's own poses: nothing is
mapped again. Observed surface is counted as `benchmarks/mapper.py` counts it (5 cm voxels hit by
back-projected observed depth, every 4th pixel), here of every second frame. Prints, at every `--every`
steps: observed m², completion %, Gaussians and Gaussians per m² observed. A map whose memory grows with
the scene, not with time, keeps its Gaussians per m² from one row to the next (docs/mapping.md, "The
4000-step criterion against the observed surface").

With ``--earlier E2`` (the episode folder of a shorter run with the same first actions, so that its
final map is the longer run's map at that step) it also says where the Gaussians added after that step
lie: in cells of ``--cell-m`` whose observed surface grew, or in cells whose surface did not, and what
a hard cap of B Gaussians per m² of each cell's observed surface, applied to both maps, would leave of
the growth (docs/mapping.md, "An area budget per cell of observed surface").
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))  # benchmarks/mapper.py, also when loaded from a file
from mapper import SURFACE_VOXEL_M, episode_poses, observed_voxels  # noqa: E402


def first_seen(episode: Path) -> tuple[np.ndarray, np.ndarray]:
    """The observed 5 cm voxels of an episode (integer indices, (M, 3)) and the step each was first hit
    at (every second frame, as :func:`growth_rows`)."""
    sim, poses, _dense = episode_poses(episode, None)
    first: dict[tuple[int, int, int], int] = {}
    for step, pose in enumerate(poses):
        if step % 2 == 0:
            _rgb, depth = sim.render(pose)
            for v in map(tuple, observed_voxels(depth, pose, sim.K)):
                first.setdefault(v, step)
    return np.array(list(first), dtype=np.int64).reshape(-1, 3), np.array(list(first.values()))


def cell_growth(earlier: Path, later: Path, cell_m: float = 0.2,
                caps: tuple[float, ...] = (600.0, 1000.0, 3000.0),
                seen: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """Where the Gaussians of ``later``'s final map that ``earlier``'s final map lacks lie (module
    docstring): counts per cell of ``cell_m`` (a multiple of 5 cm), and for each cap B the growth of
    sum(min(count, B x observed m²)) over the cells against the growth of the observed surface (a cell
    with no surface observed by the earlier step is not capped there). ``seen``: ``first_seen(later)``
    when the caller has it already (it renders every second frame)."""
    from activesplat.geometry import in_sorted, voxel_keys
    from activesplat.splat.ply import load_ply

    step = int(json.loads((earlier / "metrics.json").read_text())["steps"])
    voxels, steps = first_seen(later) if seen is None else seen
    ratio = int(round(cell_m / SURFACE_VOXEL_M))
    cells, inverse = np.unique(np.floor_divide(voxels, ratio), axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    area_then = np.bincount(inverse, weights=(steps <= step) * SURFACE_VOXEL_M ** 2, minlength=len(cells))
    area_now = np.bincount(inverse, minlength=len(cells)) * SURFACE_VOXEL_M ** 2

    cell_keys = voxel_keys(cells + 0.5, 1.0)  # one int64 per integer cell index (np.unique sorted them)

    def counts(episode: Path) -> tuple[np.ndarray, int]:
        means = load_ply(episode / "gaussians.ply").params["means"].detach().numpy()
        index = np.floor_divide(np.floor(means / SURFACE_VOXEL_M).astype(np.int64), ratio)
        keys = voxel_keys(index + 0.5, 1.0)
        inside = in_sorted(cell_keys, keys)
        mine = np.searchsorted(cell_keys, keys[inside])
        return np.bincount(mine, minlength=len(cells)), int((~inside).sum())

    (then, out_then), (now, out_now) = counts(earlier), counts(later)
    grew = area_now > area_then
    added = now - then
    area_growth = area_now.sum() / area_then.sum()
    capped = {}
    for cap in caps:  # a cell with no surface observed yet keeps what it holds
        kept_then = np.where(area_then > 0, np.minimum(then, np.ceil(cap * area_then)), then).sum() + out_then
        kept_now = np.minimum(now, np.ceil(cap * area_now)).sum() + out_now
        capped[cap] = kept_now / kept_then / area_growth - 1.0
    return {"step": step, "gaussians_then": int(then.sum()) + out_then,
            "gaussians_now": int(now.sum()) + out_now,
            "area_growth": area_growth - 1.0, "added_where_surface_grew": int(added[grew].sum()),
            "added_elsewhere": int(added[~grew].sum()), "added_outside_observed": out_now - out_then,
            "excess_with_cap": capped}


def growth_rows(episode: Path, every: int, seen: tuple[np.ndarray, np.ndarray] | None = None) -> list[dict]:
    """One row per `every` steps of the episode's completion curve: step, observed m², completion %,
    Gaussians and Gaussians per m² observed. ``seen``: ``first_seen(episode)`` when the caller has it."""
    at = {p["step"]: p for p in json.loads((episode / "metrics.json").read_text())["curve"]}
    _voxels, first = first_seen(episode) if seen is None else seen
    rows = []
    for step in sorted(at):
        if step > 0 and step % every == 0:
            area = int((first <= step).sum()) * SURFACE_VOXEL_M ** 2
            n = at[step]["n_gaussians"]
            rows.append({"step": step, "observed_m2": area, "gaussians": n, "per_m2": n / area,
                         "completion_pct": at[step]["completion_ratio_pct"]})
    return rows


def check_earlier(earlier: Path, later: Path, cell_m: float) -> None:
    """Exit with a message unless ``earlier`` is a shorter run whose actions begin ``later``'s and
    ``cell_m`` is a positive multiple of 5 cm."""
    ratio = cell_m / SURFACE_VOXEL_M
    if ratio < 0.999 or abs(ratio - round(ratio)) > 1e-6:
        sys.exit(f"map_growth: --cell-m must be a positive multiple of {SURFACE_VOXEL_M} m, got {cell_m}")
    first, second = ((folder / "actions.txt").read_text().split() for folder in (earlier, later))
    if len(first) >= len(second) or second[: len(first)] != first:
        sys.exit(f"map_growth: {earlier} must be a shorter run whose actions begin those of {later} "
                 f"({len(first)} and {len(second)} actions)")


def print_cell_growth(g: dict) -> None:
    print(f"\nGaussians added after step {g['step']:,}: {g['gaussians_now'] - g['gaussians_then']:+,} "
          f"({g['gaussians_now'] / g['gaussians_then'] - 1:+.1%}; observed surface {g['area_growth']:+.1%})")
    print(f"- in cells whose observed surface grew: {g['added_where_surface_grew']:+,}")
    print(f"- in cells whose observed surface did not grow: {g['added_elsewhere']:+,}")
    print(f"- outside every observed cell: {g['added_outside_observed']:+,}")
    print("\n| cap per m² of a cell's observed surface | growth beyond the surface's |\n|---|---|")
    for cap, excess in g["excess_with_cap"].items():
        print(f"| {cap:,.0f} | {excess:+.1%} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("episode", type=Path, help="episode folder of `activesplat explore`")
    parser.add_argument("--every", type=int, default=1000, help="steps between rows")
    parser.add_argument("--earlier", type=Path,
                        help="a shorter run's episode folder with the same first actions")
    parser.add_argument("--cell-m", type=float, default=0.2,
                        help="cell size for --earlier (a multiple of 5 cm)")
    args = parser.parse_args()
    for folder in (args.episode, args.earlier):
        if folder is not None and not (folder / "metrics.json").is_file():
            sys.exit(f"map_growth: {folder} has no metrics.json: not a finished explore episode")
    if args.earlier is not None:
        check_earlier(args.earlier, args.episode, args.cell_m)
    print("| step | observed m² | completion % | Gaussians | per m² |")
    print("|---|---|---|---|---|")
    seen = first_seen(args.episode)  # the slow part (a render per second frame), done once
    for r in growth_rows(args.episode, args.every, seen):
        print(f"| {r['step']} | {r['observed_m2']:.1f} | {r['completion_pct']:.2f} | {r['gaussians']:,} | "
              f"{r['per_m2']:.0f} |")
    if args.earlier is not None:
        print_cell_growth(cell_growth(args.earlier, args.episode, args.cell_m, seen=seen))


if __name__ == "__main__":
    main()
