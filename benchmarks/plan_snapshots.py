"""The planner's view of the house at chosen steps of an exploration, beside the ground truth.

    python benchmarks/plan_snapshots.py --at 758 1999 --out runs/snapshots/m136 --scene medium-136
    python benchmarks/plan_snapshots.py --at 758 --box 7.3 10.5 4.0 6.2 --out DIR --scene medium-136 \
        --explorer.neck-margin-m None

Runs one exploration and, at each step of `--at`, draws `step<N>.png` into `--out`: on the left the
scene's navigation grid (what the agent could really stand on), on the right the top-down grids of the
online map as the explorer last built them (free, obstacle, unknown; the workspace and the Voronoi graph
over them), with the goals the explorer had marked failed so far (red crosses, "no path" or "blocked")
and the trajectory. `--box X0 X1 Z0 Z1` crops both panels to that part of the floor (world metres). Both
are drawn from above, x to the right and z down, like the episode's topdown.png and trajectory.png.

What it answers: whether a goal skipped for want of a path lies behind a squeeze of the scene or only of
the map (a door whose inside floor the camera has not seen, furniture the map makes wider).
Every other option is an option of `activesplat explore` and means the same there (`--scene`, `--seed`,
`--steps` for the budget, `--explorer.neck-margin-m 0.2`, ...); the episode folder goes to OUT/episode.
Runs on the threads numba is given: set NUMBA_NUM_THREADS=1 to reproduce a benchmark run.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from activesplat.cli_options import CommandLineError, parse_command
from activesplat.config import ExploreCommand, RunConfig
from activesplat.errors import InvalidInputError, check_output_folder
from activesplat.explore import explore_episode
from activesplat.sim import load_scene
from activesplat.viz.trajectory import draw_navigable
from activesplat.workspace.draw import draw_graph, grid_image


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
    draw_navigable(left, navmap)
    left.set_title("scene: navigable floor (light)", fontsize=9)
    x0, x1, z0, z1 = plan.grids.geometry.extent
    right.imshow(grid_image(plan.grids, plan.workspace), extent=(x0, x1, z1, z0), interpolation="nearest")
    right.set_title("online map: workspace white, other free blue, obstacle black, unknown grey", fontsize=9)
    trajectory = np.asarray(explorer.visited).reshape(-1, 2)
    for ax in (left, right):
        if plan.graph.number_of_nodes():
            draw_graph(ax, plan.graph)
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


def parse(argv: list[str] | None = None) -> tuple[argparse.Namespace, RunConfig]:
    """This script's own options, and the run the rest of `argv` describes as `activesplat explore`'s
    options would (the same parser: bad options raise `activesplat.cli_options.CommandLineError`)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--at", type=int, nargs="+", required=True, help="steps to draw")
    ap.add_argument("--box", type=float, nargs=4, default=None, metavar=("X0", "X1", "Z0", "Z1"))
    ap.add_argument("--out", required=True)
    args, rest = ap.parse_known_args(argv)
    return args, parse_command(ExploreCommand, rest, "plan_snapshots.py").run


def main() -> None:
    try:
        args, run = parse()
    except CommandLineError as exc:
        raise SystemExit(f"plan_snapshots.py: error: {exc}") from None
    out = Path(args.out)
    try:
        check_output_folder(out, "--out")  # before the scene is built
    except InvalidInputError as exc:
        raise SystemExit(f"plan_snapshots.py: error: {exc}") from None
    scene = load_scene(run.scene, z_up=run.z_up, floor=run.floor)
    budget = run.steps or scene.default_steps
    late = [s for s in args.at if not 1 <= s <= budget]
    if late:
        raise SystemExit(f"--at {late} lie outside the run's steps 1..{budget}")
    snaps = Snapshots(scene.navmap_for(run.sim), set(args.at), out, args.box, f"{run.scene} seed {run.seed}")
    metrics = explore_episode(run, out=out / "episode", overwrite=True, progress=False, viewer=snaps,
                              scene=scene)
    print(f"completion {metrics['completion_ratio_pct']:.2f} %")
    for path in snaps.written:
        print(path)


if __name__ == "__main__":
    main()
