"""Per-call timing of each workspace stage on a mapped episode, next to the paper's GPU figures
(Tab. "system performance", RTX 3090 + i9-12900K: get workspace 43.9 ms, get Voronoi 0.69 ms,
get subregion 1.56 ms, path planner 0.20 ms).

Map: a `gaussians.ply` from an episode folder (agent = the last pose in poses.txt next to it, floor
from episode.json); by default a fresh `--steps`-step exploration of `--scene` in a temporary folder.
`--synthetic N` instead samples N points on the scene's ground-truth mesh (1 cm Gaussians), a stand-in
that has no sparse far floor. Usage:

    python benchmarks/workspace.py [PLY] [--scene small-0|medium-0] [--steps 300] [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import networkx as nx
import numpy as np
import torch

from activesplat.errors import InvalidInputError, check_output_folder
from activesplat.workspace.clean import extract_workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.paths import plan_safe_path
from activesplat.workspace.subregions import partition_subregions
from activesplat.workspace.topdown import grids_from_alpha, render_topdown
from activesplat.workspace.voronoi import build_voronoi_graph, node_positions

PAPER_MS = {"render": "43.9 (render + grids + polish)", "polish": "(in 43.9)", "voronoi": "0.69",
            "subregions": "1.56", "path": "0.20"}


def episode_map(ply: Path) -> tuple[object, float, np.ndarray | None, str]:
    """Gaussian map, floor height and last agent (x, z) of an episode folder's gaussians.ply."""
    from activesplat.splat import load_ply

    gmap = load_ply(ply)
    folder = ply.parent
    meta = json.loads((folder / "episode.json").read_text()) if (folder / "episode.json").is_file() else {}
    agent = None
    if (folder / "poses.txt").is_file():
        last = np.loadtxt(folder / "poses.txt", ndmin=2)[-1, 1:].reshape(4, 4)
        agent = last[[0, 2], 3]
    return gmap, float(meta.get("floor_height", 0.0)), agent, f"{ply} ({len(gmap)} Gaussians)"


def explored_map(scene: str, steps: int, workdir: Path):
    from activesplat.explore import run_exploration

    t0 = time.perf_counter()
    run_exploration(scene, steps=steps, out=workdir / "ep", overwrite=True, progress=False)
    print(f"explored {scene} for {steps} steps in {time.perf_counter() - t0:.0f} s")
    gmap, floor, agent, _ = episode_map(workdir / "ep" / "gaussians.ply")
    return gmap, floor, agent, f"{scene} after {steps} steps of exploration ({len(gmap)} Gaussians)"


def synthetic_map(scene_name: str, n: int, seed: int = 0):
    import trimesh

    from activesplat.sim import load_scene

    scene = load_scene(scene_name)
    points, _ = trimesh.sample.sample_surface(scene.mesh, n, seed=seed)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    gmap = SimpleNamespace(means=torch.as_tensor(points, dtype=torch.float32), quats=quats,
                           scales=torch.full((n, 3), 0.01), opacities=torch.full((n,), 0.9),
                           colors=torch.full((n, 3), 0.5))
    return gmap, float(scene.floor_height), None, f"synthetic ({n} points on the {scene_name} mesh)"


def timed(fn, *args, repeats: int):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn(*args)
        times.append(1e3 * (time.perf_counter() - t0))
    return out, float(np.median(times))


def agent_or_centre(grids, agent: np.ndarray | None) -> np.ndarray:
    """The recorded agent position, else the free pixel nearest the free area's centre."""
    if agent is not None:
        return np.asarray(agent, dtype=np.float64)
    free_rc = np.argwhere(grids.free)
    dist = np.linalg.norm(free_rc - free_rc.mean(axis=0), axis=1)
    return grids.geometry.pixel_to_world(free_rc[np.argmin(dist)] + 0.5)


def farthest_reachable_node(graph: nx.Graph, agent: np.ndarray) -> np.ndarray:
    pos = node_positions(graph)
    if len(pos) == 0:
        return agent
    start = int(np.argmin(np.linalg.norm(pos - agent, axis=1)))
    reachable = sorted(nx.node_connected_component(graph, start))
    return pos[reachable[int(np.argmax(np.linalg.norm(pos[reachable] - agent, axis=1)))]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("ply", nargs="?", type=Path, help="an episode's gaussians.ply (default: explore)")
    parser.add_argument("--scene", default="small-0")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--synthetic", type=int, default=0, metavar="N",
                        help="time on N points sampled on the scene mesh instead of a mapped episode")
    parser.add_argument("--out", type=Path, help="keep the exploration episode here (default: a temp folder)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--backend", default="auto")
    args = parser.parse_args()
    if args.out is not None:
        try:
            check_output_folder(args.out, "--out")  # before the exploration
        except InvalidInputError as exc:
            parser.error(str(exc))
    cfg = WorkspaceConfig()
    with tempfile.TemporaryDirectory() as tmp:
        if args.ply is not None:
            gmap, floor, agent, source = episode_map(args.ply)
        elif args.synthetic:
            gmap, floor, agent, source = synthetic_map(args.scene, args.synthetic)
        else:
            gmap, floor, agent, source = explored_map(args.scene, args.steps, args.out or Path(tmp))
    grids = render_topdown(gmap, floor, cfg, agent, args.backend)  # warm-up (numba JIT)
    agent = agent_or_centre(grids, agent)
    grids, t_render = timed(render_topdown, gmap, floor, cfg, agent, args.backend, repeats=args.repeats)
    _, t_grids = timed(grids_from_alpha, grids.geometry, grids.ground_alpha, grids.obstacle_alpha, floor, cfg,
                       repeats=args.repeats)
    workspace, t_polish = timed(extract_workspace, grids, agent, cfg, repeats=args.repeats)
    graph, t_vor = timed(build_voronoi_graph, workspace, cfg, repeats=args.repeats)
    _, t_sub = timed(partition_subregions, graph, cfg, repeats=args.repeats)
    goal = farthest_reachable_node(graph, agent)
    path, t_path = timed(plan_safe_path, graph, workspace, agent, goal, cfg, repeats=args.repeats)
    print(f"map: {source}; grid {grids.geometry.shape} at {cfg.resolution} m/px, "
          f"{graph.number_of_nodes()} nodes / {graph.number_of_edges()} edges, "
          f"path to the farthest reachable node {'found' if path is not None else 'none'} "
          f"({0 if path is None else len(path)} waypoints); median of {args.repeats} calls, "
          f"backend {args.backend}, CPU {torch.get_num_threads()} threads")
    print("| stage | ours (ms per call) | paper GPU (ms) |")
    print("|---|---|---|")
    render = f"{t_render:.1f} (of which grids {t_grids:.2f})"
    print(f"| top-down render + grids | {render} | {PAPER_MS['render']} |")
    print(f"| workspace polish | {t_polish:.2f} | {PAPER_MS['polish']} |")
    print(f"| Voronoi graph | {t_vor:.2f} | {PAPER_MS['voronoi']} |")
    print(f"| subregions (UPGMA) | {t_sub:.2f} | {PAPER_MS['subregions']} |")
    print(f"| safe path | {t_path:.2f} | {PAPER_MS['path']} |")


if __name__ == "__main__":
    main()
