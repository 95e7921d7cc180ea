"""The planner's view of the house at chosen steps of an exploration, beside the ground truth.

    python benchmarks/plan_snapshots.py --scene medium-136 --steps 758 1999 --out runs/snapshots/m136
    python benchmarks/plan_snapshots.py --scene medium-136 --steps 758 --box 7.3 10.5 4.0 6.2 ...

Runs one exploration (the scene's default budget, or `--budget`) with the given settings and, at each
step of `--steps`, draws `step<N>.png` into `--out`: on the left the scene's navigation grid (what the
agent could really stand on), on the right the top-down grids of the online map as the explorer last
built them (free, obstacle, unknown; the workspace and the Voronoi graph over them), with the goals the
explorer had marked failed so far (red crosses, "no path" or "blocked") and the trajectory. `--box X0 X1
Z0 Z1` crops both panels to that part of the floor (world metres). Both are drawn from above, x to the
right and z down, like the episode's topdown.png and trajectory.png.

What it answers: whether a goal skipped for want of a path lies behind a squeeze of the scene or only of
the map (a door whose inside floor the camera has not seen, furniture the map makes wider).
The exploration itself writes its episode folder to OUT/episode; `--set field=value` passes any option of
`activesplat explore` as a RunConfig field path (e.g. `explorer.neck_margin_m=0.2`). Runs on the threads
numba is given: set NUMBA_NUM_THREADS=1 to reproduce a benchmark run.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from activesplat.config import RunConfig
from activesplat.explore import explore_episode
from activesplat.sim import load_scene
from activesplat.workspace.draw import grid_image
from activesplat.workspace.voronoi import node_positions


class Snapshots:
    """An exploration viewer (`explore_episode(viewer=...)`) that draws the plan at the given steps."""

    def __init__(self, navmap, steps: set[int], out: Path, box: tuple[float, float, float, float] | None,
                 title: str):
        self.navmap, self.steps, self.out, self.box, self.title = navmap, steps, out, box, title
        self.written: list[Path] = []

    def update(self, step, obs, mapper, explorer, final=False) -> None:
        if step not in self.steps:
            return
        plan, title = explorer.plan, f"{self.title}, step {step}"
        if plan.grids is None:  # no replan yet (the bootstrap look-around): the plan of the map as it is
            from activesplat.planning.controller import floor_xz
            from activesplat.workspace.plan import build_plan

            plan = build_plan(mapper.gaussians, explorer.floor_height, floor_xz(obs.pose),
                              explorer.cfg.workspace)
            title += " (no replan yet: the plan of the map at this step)"
        self.written.append(draw_snapshot(self.out / f"step{step}.png", self.navmap, explorer, plan, self.box,
                                          title))

    def close(self) -> None:
        pass


def draw_snapshot(out_png: Path, navmap, explorer, plan, box, title: str) -> Path:
    """Ground-truth navigation grid (left) and `plan` (right), both from above, with the explorer's
    trajectory and failed goals."""
    fig = Figure(figsize=(13, 6.5), dpi=100)
    left, right = fig.subplots(1, 2)
    res = navmap.resolution
    extent = (navmap.origin[0], navmap.origin[0] + navmap.grid.shape[0] * res,
              navmap.origin[1], navmap.origin[1] + navmap.grid.shape[1] * res)
    truth = np.where(navmap.largest, 0.93, np.where(navmap.grid, 0.8, 0.45))
    left.imshow(truth.T, origin="lower", extent=extent, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    left.set_title("scene: navigable floor (light)", fontsize=9)
    x0, x1, z0, z1 = plan.grids.geometry.extent
    right.imshow(grid_image(plan.grids, plan.workspace), extent=(x0, x1, z1, z0), interpolation="nearest")
    right.set_title("online map: workspace white, other free blue, obstacle black, unknown grey", fontsize=9)
    graph = plan.graph
    nodes = sorted(graph.nodes)
    pos = node_positions(graph) if nodes else np.zeros((0, 2))
    index = {n: i for i, n in enumerate(nodes)}
    trajectory = np.asarray(explorer.visited).reshape(-1, 2)
    for ax in (left, right):
        ax.add_collection(LineCollection([(pos[index[a]], pos[index[b]]) for a, b in graph.edges],
                                         colors="orange", linewidths=1.0))
        ax.scatter(pos[:, 0], pos[:, 1], s=6, c="orange", zorder=3)
        ax.plot(trajectory[:, 0], trajectory[:, 1], color="#1d4ed8", lw=0.8, zorder=4)
        for failure in explorer.failures:
            ax.plot(*failure["goal"], "x", color="red", ms=9, mew=2, zorder=5)
        if plan.path is not None:
            ax.plot(plan.path[:, 0], plan.path[:, 1], color="#e63946", lw=2, zorder=4)
        bx0, bx1, bz0, bz1 = box if box is not None else (x0, x1, z0, z1)
        ax.set_xlim(bx0, bx1)
        ax.set_ylim(bz1, bz0)
        ax.set_aspect("equal")
        ax.set_xlabel("world x (m)")
        ax.set_ylabel("world z (m)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png)
    return out_png


def _value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return {"None": None, "True": True, "False": False}.get(text, text)


def with_fields(run: RunConfig, settings: list[str]) -> RunConfig:
    """`run` with each "a.b.c=value" of `settings` set (nested dataclass fields)."""
    for item in settings:
        path, eq, text = item.partition("=")
        if not eq:
            raise SystemExit(f"--set wants field=value, got {item!r}")
        run = _set(run, path.split("."), _value(text), path)
    return run


def _set(obj, names: list[str], value, path: str):
    """`obj` (a dataclass) with the field at `names` replaced by `value`."""
    import dataclasses

    if not dataclasses.is_dataclass(obj) or not hasattr(obj, names[0]):
        raise SystemExit(f"--set: no field {path!r} in the run configuration")
    inner = value if len(names) == 1 else _set(getattr(obj, names[0]), names[1:], value, path)
    return dataclasses.replace(obj, **{names[0]: inner})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, nargs="+", required=True, help="steps to draw")
    ap.add_argument("--budget", type=int, default=None, help="steps to explore (default: the scene's)")
    ap.add_argument("--box", type=float, nargs=4, default=None, metavar=("X0", "X1", "Z0", "Z1"))
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    out = Path(args.out)
    run = with_fields(RunConfig(scene=args.scene, seed=args.seed, steps=args.budget), args.set)
    scene = load_scene(run.scene, z_up=run.z_up, floor=run.floor)
    budget = run.steps or scene.default_steps
    late = [s for s in args.steps if not 1 <= s <= budget]
    if late:
        raise SystemExit(f"--steps {late} lie outside the run's steps 1..{budget}")
    snaps = Snapshots(scene.navmap_for(run.sim), set(args.steps), out, args.box,
                      f"{args.scene} seed {args.seed}")
    metrics = explore_episode(run, out=out / "episode", overwrite=True, progress=False, viewer=snaps,
                              scene=scene)
    print(f"completion {metrics['completion_ratio_pct']:.2f} %")
    for path in snaps.written:
        print(path)


if __name__ == "__main__":
    main()
