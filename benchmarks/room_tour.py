"""How many steps does it take just to go into every room? The shortest walk from an episode's start
through the middle of every room of a built-in house, in forward steps, with a full look around in each.

    python benchmarks/room_tour.py --scenes medium-100 medium-101 --seeds 0 1 2
    python benchmarks/room_tour.py --ceilings runs/benchmark   # and what that route sees

The middle of a room is its navigable cell farthest from walls and furniture, among the cells at least
`BehaviourConfig.entered_inset_m` inside the room (where the benchmark counts the room as entered). Walks
are geodesic on the simulator's navigability map (8-connected cells, exact lengths), the start is the
simulator's random start of each seed, and the order of the rooms is the best of all orders (dynamic
programming over subsets). A walk ends in the last room; it does not come back. Corridors are walked
through, not visited. This is a scale for the step budget, not a bound on coverage: an agent sees part
of a room from its door, and needs more than the middle of a large or L-shaped room to see all of it.

Columns: rooms, walk (m), forward steps (walk / MOVE_FORWARD), the same plus a full look around in every
room (360 / TURN degrees each) and the turns of the walk itself (each change of direction at a room, in
whole turns), and how many rooms' look arounds are done by step 1000 (half the medium budget).

With ``--ceilings DIR`` (the benchmark's ``DIR/<scene>/sweep.json``, written by ``activesplat benchmark``)
the route is also walked in the simulator's sensor and counted with the episodes' coverage protocol:
one frame per forward step along the geodesic path (facing the way it goes), one per turn of each look
around (level camera), none for the turns between legs. It prints the share of the sweep ceiling seen by
step 1000 and at the route's end: what an agent that knew the house beforehand would see by then on
this simple route (no tilts, no stops in the doors).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
from scipy.sparse.csgraph import dijkstra

from activesplat.eval.behaviour import BehaviourConfig
from activesplat.eval.coverage import CoverageAccumulator, CoverageConfig
from activesplat.geometry import camera_pose, intrinsics
from activesplat.planning.travel import shortest_tour
from activesplat.sim import SimConfig, Simulator, load_scene
from activesplat.sim.navmap import grid_graph


def shortest_open_walk(dist: np.ndarray) -> tuple[float, list[int]]:
    """Shortest walk from node 0 through every other node of the (symmetric) distance matrix, ending
    anywhere: its length and the node order (`planning.travel.shortest_tour`, exact up to 10 stops)."""
    order = [0, *(1 + i for i in shortest_tour(dist[0, 1:], dist[1:, 1:]))]
    return float(sum(dist[a, b] for a, b in zip(order[:-1], order[1:], strict=True))), order


def room_middles(scene, nav, inset: float) -> dict[str, np.ndarray]:
    """Per (non-corridor) room: the (ix, iz) of its navigable cell, `inset` inside it, farthest from
    obstacles."""
    house = scene.house
    cells = np.argwhere(nav.largest)
    xz = nav.cell_centre(cells[:, 0], cells[:, 1])
    labels = house.label_points(xz, inset=inset)
    names, corridors = house.room_names, set(house.corridor_names)
    out = {}
    for i, name in enumerate(names):
        if name in corridors:
            continue
        mine = cells[labels == i]
        if len(mine):
            out[name] = mine[int(np.argmax(nav.clearance[mine[:, 0], mine[:, 1]]))]
    return out


def leg_turns(points: np.ndarray, turn_deg: float) -> list[int]:
    """Per leg of a polyline of room middles, the whole turns to face it from the previous leg (0 for the
    first: the start heading is free; straight legs, so a lower count than a real path's)."""
    turns = [0]
    for a, b, c in zip(points[:-2], points[1:-1], points[2:], strict=True):
        u, v = b - a, c - b
        angle = abs(math.degrees(math.atan2(u[0] * v[1] - u[1] * v[0], float(u @ v))))
        turns.append(int(round(angle / turn_deg)))
    return turns


def route_poses(points: list[np.ndarray], sim: SimConfig, floor_height: float) -> list[np.ndarray]:
    """Camera poses of the route through `points` (each a polyline (M, 2) of one leg in x, z): a frame
    every forward step along each leg, facing along it, then a full look around at its end."""
    poses, yaw = [], 0.0
    height = floor_height + sim.sensor_height
    turns = int(round(360.0 / sim.turn_deg))
    for leg in points:
        seg = np.diff(leg, axis=0)
        lengths = np.hypot(seg[:, 0], seg[:, 1])
        along = np.concatenate([[0.0], np.cumsum(lengths)])
        for d in np.arange(sim.forward_step, along[-1] + 1e-9, sim.forward_step):
            i = min(int(np.searchsorted(along, d)) - 1, len(seg) - 1)
            xz = leg[i] + seg[i] * ((d - along[i]) / max(lengths[i], 1e-12))
            ahead = leg[min(i + 4, len(leg) - 1)] - xz  # face ~0.2 m ahead along the cell path
            if np.hypot(*ahead) > 1e-6:
                yaw = math.atan2(ahead[0], ahead[1])
            poses.append(camera_pose([xz[0], height, xz[1]], yaw))
        for _ in range(turns):
            yaw += math.radians(sim.turn_deg)
            poses.append(camera_pose([leg[-1][0], height, leg[-1][1]], yaw))
    return poses


def route_coverage(scene, sim: SimConfig, poses: list[np.ndarray], at_step: int) -> tuple[float, float]:
    """Completion ratio % of the route's frames by `at_step` and at its end (docs/protocol.md §6)."""
    cfg = CoverageConfig()
    sensor = scene.sensor_for(sim)
    K = intrinsics(cfg.resolution, cfg.resolution, sim.hfov_deg)
    cov = CoverageAccumulator(scene.sample_surface(cfg.n_gt_points, seed=cfg.seed), cfg)
    start = camera_pose(poses[0][:3, 3], 0.0)  # the episode's first frame comes before any action
    at = None
    for i, pose in enumerate([start, *poses]):
        cov.add_frame(sensor.render(pose, K, cfg.resolution, cfg.resolution)[1], pose, K)
        if i == at_step:
            at = cov.metrics()["completion_ratio_pct"]
    end = cov.metrics()["completion_ratio_pct"]
    return (end if at is None else at), end


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=[f"medium-{i}" for i in range(100, 110)])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--ceilings", type=Path, default=None,
                    help="folder with <scene>/sweep.json: also walk the route and count what it sees")
    ap.add_argument("--at-step", type=int, default=1000)
    args = ap.parse_args()
    sim = SimConfig()
    inset = BehaviourConfig().entered_inset_m
    look = int(round(360.0 / sim.turn_deg))
    extra = f" | of ceiling by step {args.at_step} % | of ceiling at the end % | route steps"
    print("| scene | seed | rooms | walk m | forward steps | + a look around per room and the turns between "
          f"| rooms looked around in by step {args.at_step}{extra if args.ceilings else ''} |")
    print("|---|---|---|---|---|---|---|" + ("---|---|---|" if args.ceilings else ""))
    totals = []
    for name in args.scenes:
        scene = load_scene(name)
        nav = scene.navmap_for(sim)
        graph, cells = grid_graph(nav.largest, nav.resolution)
        node_of = {tuple(c): i for i, c in enumerate(cells)}
        middles = room_middles(scene, nav, inset)
        ceiling = None
        if args.ceilings is not None:
            ceiling = json.loads((args.ceilings / name / "sweep.json").read_text())["completion_ratio_pct"]
        for seed in args.seeds:
            start = Simulator(scene, seed=seed, config=sim).start.position[[0, 2]]  # the episode's start
            six, siz = nav.cell_of(*start)
            nodes = [node_of[(int(six), int(siz))]] + [node_of[tuple(c)] for c in middles.values()]
            dist, pred = dijkstra(graph, indices=nodes, return_predecessors=True)
            length, order = shortest_open_walk(dist[:, nodes])
            points = nav.cell_centre(cells[nodes][:, 0], cells[nodes][:, 1])[order]
            forward = int(math.ceil(length / sim.forward_step))
            legs = [dist[order[i], nodes[order[i + 1]]] / sim.forward_step for i in range(len(order) - 1)]
            costs = np.array(legs) + look + np.array(leg_turns(points, sim.turn_deg))
            actions = int(math.ceil(costs.sum()))
            reached = int((np.cumsum(costs) <= args.at_step).sum())
            row = [len(middles), length, forward, actions, reached]
            text = (f"| {name} | {seed} | {len(middles)} | {length:.1f} | {forward} | {actions} | "
                    f"{reached} / {len(middles)}")
            if ceiling is not None:
                polylines = []
                for i in range(len(order) - 1):
                    src, node = order[i], nodes[order[i + 1]]
                    path = [node]
                    while path[-1] != nodes[src]:
                        path.append(pred[src, path[-1]])
                    polylines.append(nav.cell_centre(cells[path[::-1]][:, 0], cells[path[::-1]][:, 1]))
                poses = route_poses(polylines, sim, nav.floor_height)
                at, end = route_coverage(scene, sim, poses, args.at_step)
                row += [100 * at / ceiling, 100 * end / ceiling, len(poses)]
                text += f" | {row[5]:.1f} | {row[6]:.1f} | {len(poses)}"
            totals.append(row)
            print(text + " |", flush=True)
    a = np.array(totals, float)
    text = (f"| **mean** | | {a[:, 0].mean():.1f} | {a[:, 1].mean():.1f} | {a[:, 2].mean():.0f} | "
            f"{a[:, 3].mean():.0f} | {a[:, 4].mean():.1f} / {a[:, 0].mean():.1f}")
    if args.ceilings is not None:
        text += f" | {a[:, 5].mean():.1f} | {a[:, 6].mean():.1f} | {a[:, 7].mean():.0f}"
    print(text + " |")


if __name__ == "__main__":
    main()
