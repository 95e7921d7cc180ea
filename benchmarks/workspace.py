"""Per-stage timing of the workspace step (paper Tab. "system performance": get workspace 43.9 ms,
get Voronoi 0.69 ms, get subregion 1.56 ms, path planner 0.20 ms on an RTX 3090 + i9-12900K).

Map: a synthetic Gaussian map of the built-in `medium-0` house, NOT a mapped one: points sampled
uniformly on the ground-truth mesh (seeded), isotropic 1 cm Gaussians, opacity 0.9 (stand-in until a
mapped medium-0 map is saved). Usage: python benchmarks/workspace.py [--gaussians 300000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import time
from types import SimpleNamespace

import networkx as nx
import numpy as np
import torch
import trimesh

from activesplat.sim import load_scene
from activesplat.workspace.clean import extract_workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.paths import plan_safe_path
from activesplat.workspace.subregions import partition_subregions
from activesplat.workspace.topdown import render_topdown
from activesplat.workspace.voronoi import build_voronoi_graph, node_positions


def synthetic_map(scene_name: str, n: int, seed: int = 0) -> tuple[SimpleNamespace, float]:
    scene = load_scene(scene_name)
    points, _ = trimesh.sample.sample_surface(scene.mesh, n, seed=seed)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    gmap = SimpleNamespace(means=torch.as_tensor(points, dtype=torch.float32), quats=quats,
                           scales=torch.full((n, 3), 0.01), opacities=torch.full((n,), 0.9),
                           colors=torch.full((n, 3), 0.5))
    return gmap, float(scene.floor_height)


def timed(fn, *args, repeats: int):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn(*args)
        times.append(1e3 * (time.perf_counter() - t0))
    return out, float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default="medium-0")
    parser.add_argument("--gaussians", type=int, default=300_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--backend", default="auto")
    args = parser.parse_args()
    cfg = WorkspaceConfig()
    gmap, floor = synthetic_map(args.scene, args.gaussians)
    render_topdown(gmap, floor, cfg, backend=args.backend)  # warm-up (numba JIT)
    grids, t_render = timed(render_topdown, gmap, floor, cfg, None, args.backend, repeats=args.repeats)
    free_rc = np.argwhere(grids.free)
    dist = np.linalg.norm(free_rc - free_rc.mean(axis=0), axis=1)
    agent = grids.geometry.pixel_to_world(free_rc[np.argmin(dist)] + 0.5)
    workspace, t_clean = timed(extract_workspace, grids, agent, cfg, repeats=args.repeats)
    graph, t_vor = timed(build_voronoi_graph, workspace, cfg, repeats=args.repeats)
    _, t_sub = timed(partition_subregions, graph, cfg, repeats=args.repeats)
    pos = node_positions(graph)
    goal = agent
    if len(pos):  # the farthest node in the agent's component of the graph
        start = int(np.argmin(np.linalg.norm(pos - agent, axis=1)))
        reachable = sorted(nx.node_connected_component(graph, start))
        goal = pos[reachable[int(np.argmax(np.linalg.norm(pos[reachable] - agent, axis=1)))]]
    path, t_path = timed(plan_safe_path, graph, workspace, agent, goal, cfg, repeats=args.repeats)
    print(f"map: synthetic ({args.gaussians} Gaussians sampled on the {args.scene} mesh), grid "
          f"{grids.geometry.shape} at {cfg.resolution} m/px, {graph.number_of_nodes()} nodes, "
          f"path {'found' if path is not None else 'none'}; median of {args.repeats}, CPU")
    print("| stage | ours (ms) | paper GPU (ms) |")
    print("|---|---|---|")
    print(f"| top-down render + grids | {t_render:.1f} | 43.9 (render + grids + polish) |")
    print(f"| workspace polish | {t_clean:.1f} | (in 43.9) |")
    print(f"| Voronoi | {t_vor:.2f} | 0.69 |")
    print(f"| subregions | {t_sub:.2f} | 1.56 |")
    print(f"| path | {t_path:.2f} | 0.20 |")


if __name__ == "__main__":
    main()
