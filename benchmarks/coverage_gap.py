"""What an episode left unobserved that the exhaustive sweep observes, and where that is.

    python benchmarks/coverage_gap.py runs/benchmark/medium-100/activesplat/s0
    python benchmarks/coverage_gap.py --root runs/benchmark          # every episode folder under it

The sweep ceiling (eval/sweep.py: every navigable spot of a 1 m grid, all around, at -45 / 0 / 45 deg) is
what an agent could observe at all. The gap of an episode is the ground-truth points the sweep observes
and the episode did not (the episode's `coverage.npz`, written by every run with live evaluation), as a
share of all ground-truth points: completion + gap = ceiling, up to the few points the episode observed
and the sweep did not. The script prints, per episode, the gap split by height above the floor and by
horizontal distance from the agent's trajectory, and draws `gap.png` into the episode folder: the
missed points from above, coloured by height, over the trajectory.

The sweep's per-point mask takes minutes per medium house; it is cached in `--cache` (default
`~/.cache/activesplat/sweep_masks`) per scene and coverage settings.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

HEIGHT_BANDS_M = (0.05, 0.5, 1.0, 2.0)
"""Upper edges of the height bands (above the floor): floor, low furniture and wall bottoms, table
height, walls, and what is above 2 m (the last band)."""
DISTANCE_BANDS_M = (1.0, 2.0, 3.0)
"""Upper edges of the horizontal-distance bands from the trajectory."""


def _labels(edges: tuple[float, ...], unit: str) -> list[str]:
    lows = ("", *(f"{e:g}" for e in edges))
    highs = (*(f"{e:g}" for e in edges), "")
    return [f"<{h} {unit}" if not lo else (f">{lo} {unit}" if not h else f"{lo}-{h} {unit}")
            for lo, h in zip(lows, highs, strict=True)]


def sweep_mask(scene_name: str, n: int, seed: int, threshold_m: float, cache: Path) -> np.ndarray:
    """The exhaustive sweep's per-point completed mask for `n` ground-truth points of `seed`, cached."""
    from dataclasses import asdict, replace

    from activesplat.eval.coverage import CoverageConfig
    from activesplat.eval.sweep import SweepConfig, exhaustive_sweep

    cov = replace(CoverageConfig(), n_gt_points=n, seed=seed, threshold_m=threshold_m)
    key = json.dumps({"scene": scene_name, "coverage": asdict(cov), "sweep": asdict(SweepConfig())},
                     sort_keys=True)
    path = cache / f"{scene_name}.npz"
    if path.is_file():
        found = np.load(path)
        if str(found["key"]) == key:
            return np.unpackbits(found["completed"])[:n].astype(bool)
    out = exhaustive_sweep(scene_name, coverage_config=cov, progress=True, with_completed=True)
    cache.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, completed=np.packbits(out["completed"]), key=key)
    return out["completed"]


def episode_gap(ep: Path, cache: Path, draw: bool = True) -> dict:
    """The gap of one episode folder: totals, by height band and by distance band (% of all points)."""
    from activesplat.sim import load_scene

    meta = json.loads((ep / "episode.json").read_text())
    name = meta["scene_name"]
    cov = np.load(ep / "coverage.npz")
    n, seed = int(cov["n"]), int(cov["seed"])
    done = np.unpackbits(cov["completed"])[:n].astype(bool)
    scene = load_scene(name)
    pts = scene.sample_surface(n, seed=seed)
    ceiling = sweep_mask(name, n, seed, float(cov["threshold_m"]), cache)
    gap = ceiling & ~done
    height = pts[:, 1] - float(meta.get("floor_height", 0.0))
    poses = np.loadtxt(ep / "poses.txt")[:, 1:].reshape(-1, 4, 4)
    track = poses[:, [0, 2], 3]
    dist, _ = cKDTree(track).query(pts[gap][:, [0, 2]])
    by_height = np.bincount(np.digitize(height[gap], HEIGHT_BANDS_M), minlength=len(HEIGHT_BANDS_M) + 1)
    by_dist = np.bincount(np.digitize(dist, DISTANCE_BANDS_M), minlength=len(DISTANCE_BANDS_M) + 1)
    out = {"episode": str(ep), "scene": name, "completion_pct": 100 * done.mean(),
           "ceiling_pct": 100 * ceiling.mean(), "gap_pct": 100 * gap.mean(),
           "by_height_pct": (100 * by_height / n).tolist(), "by_distance_pct": (100 * by_dist / n).tolist()}
    if draw:
        run = f"{name} / {meta.get('policy', '')} s{meta.get('seed', '')}"
        _draw(ep / "gap.png", pts, gap, height, track,
              f"{run}: {out['gap_pct']:.2f} % of the points seen by the sweep and not by the run")
    return out


def _draw(path: Path, pts: np.ndarray, gap: np.ndarray, height: np.ndarray, track: np.ndarray,
          title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    span = np.ptp(pts[:, [0, 2]], axis=0)
    fig, ax = plt.subplots(figsize=(2 + 10 * span[0] / max(span), 1 + 10 * span[1] / max(span)))
    ax.scatter(pts[::10, 0], pts[::10, 2], s=0.2, c="0.85", rasterized=True)
    dots = ax.scatter(pts[gap, 0], pts[gap, 2], s=1.5, c=height[gap], cmap="viridis", vmin=0, vmax=2.5,
                      rasterized=True)
    ax.plot(track[:, 0], track[:, 1], "r-", lw=0.6, label="trajectory")
    fig.colorbar(dots, ax=ax, label="height above the floor (m)", shrink=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper right", fontsize=8)
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("episodes", nargs="*", type=Path, help="episode folders (with coverage.npz)")
    ap.add_argument("--root", type=Path, help="every episode folder under this benchmark root")
    ap.add_argument("--cache", type=Path, default=Path.home() / ".cache" / "activesplat" / "sweep_masks")
    ap.add_argument("--no-figures", action="store_true", help="do not write gap.png")
    args = ap.parse_args()
    eps = list(args.episodes)
    if args.root is not None:
        eps += sorted(p.parent for p in args.root.glob("*/*/s*/coverage.npz"))
    if not eps:
        ap.error("give episode folders or --root")
    missing = [str(e) for e in eps if not ((e / "coverage.npz").is_file() and (e / "episode.json").is_file())]
    if missing:
        ap.error(f"not a finished episode with live evaluation (no coverage.npz / episode.json): "
                 f"{', '.join(missing)}")
    heads = _labels(HEIGHT_BANDS_M, "m high")
    dists = _labels(DISTANCE_BANDS_M, "m away")
    rows = [episode_gap(e, args.cache, draw=not args.no_figures) for e in eps]
    print("| episode | completion % | ceiling % | gap % | " + " | ".join(heads + dists) + " |")
    print("|---" * (4 + len(heads) + len(dists)) + "|")
    for r in [*rows, None]:
        if r is None:
            if len(rows) < 2:
                break
            r = {"episode": f"**mean of {len(rows)}**",
                 **{k: np.mean([x[k] for x in rows], axis=0) for k in ("completion_pct", "ceiling_pct",
                                                                      "gap_pct", "by_height_pct",
                                                                      "by_distance_pct")}}
        cells = [r["episode"], *(f"{r[k]:.2f}" for k in ("completion_pct", "ceiling_pct", "gap_pct")),
                 *(f"{v:.2f}" for v in r["by_height_pct"]), *(f"{v:.2f}" for v in r["by_distance_pct"])]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
