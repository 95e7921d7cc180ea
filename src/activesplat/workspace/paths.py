"""Safe paths on the Voronoi graph (paper sec. III-C; REFERENCE.md sec. 5): Dijkstra on the graph,
entered and left at the nearest vertex visible from the start / goal, shortcut to the farthest
waypoint in line of sight; line of sight needs 2 agent radii of clearance on the workspace."""

from __future__ import annotations

import networkx as nx
import numpy as np

from activesplat.workspace.clean import Workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.voronoi import node_positions

MIN_CLEARANCE = 1e-6
"""Metres: every checked sample of a segment must lie inside the workspace."""


def required_clearance(workspace: Workspace, a: np.ndarray, b: np.ndarray, cfg: WorkspaceConfig) -> float:
    """Clearance a segment a-b must keep: 2 agent radii, relaxed to the clearance at its endpoints when
    the agent already stands (or must stand) closer to an obstacle than that, but always strictly inside
    the workspace (an endpoint outside it must not license a segment through walls)."""
    ends = workspace.clearance_at(np.stack([a, b]))
    return max(float(min(cfg.path_clearance, ends.min())), MIN_CLEARANCE)


def enter_workspace(workspace: Workspace, a: np.ndarray, b: np.ndarray, cfg: WorkspaceConfig) -> np.ndarray:
    """`a` itself when it lies in the workspace; else the point one agent radius from `a` towards `b`
    (ours: the floor right under the agent is often unobserved, so the agent's own disc is not checked)."""
    if workspace.clearance_at(a) > 0:
        return a
    offset = b - a
    length = float(np.linalg.norm(offset))
    return a if length == 0 else a + offset * min(1.0, cfg.agent_radius / length)


def line_of_sight(workspace: Workspace, a: np.ndarray, b: np.ndarray, cfg: WorkspaceConfig) -> bool:
    """Whether the straight segment a-b keeps the required clearance at every sample."""
    a, b = enter_workspace(workspace, a, b, cfg), enter_workspace(workspace, b, a, cfg)
    need = required_clearance(workspace, a, b, cfg)
    return bool(workspace.segments_clearance(a[None], b[None])[0] >= need - 1e-9)


def visible_nodes(graph: nx.Graph, workspace: Workspace, xz: np.ndarray, cfg: WorkspaceConfig) -> list[int]:
    """The up to `entry_candidates` nearest nodes that are in line of sight of `xz`, nearest first."""
    nodes = sorted(graph.nodes)
    positions = node_positions(graph)
    dist = np.linalg.norm(positions - xz, axis=1)
    order = np.argsort(dist, kind="stable")[: cfg.entry_candidates]
    return [nodes[i] for i in order if line_of_sight(workspace, xz, positions[i], cfg)]


def shortcut(waypoints: np.ndarray, workspace: Workspace, cfg: WorkspaceConfig) -> np.ndarray:
    """From each kept waypoint jump to the farthest later waypoint in line of sight (REFERENCE sec. 5)."""
    kept, i = [0], 0
    last = len(waypoints) - 1
    while i < last:
        here = waypoints[i]
        visible = (j for j in range(last, i + 1, -1) if line_of_sight(workspace, here, waypoints[j], cfg))
        j = next(visible, i + 1)
        kept.append(j)
        i = j
    return waypoints[kept]


def plan_safe_path(graph: nx.Graph, workspace: Workspace, start_xz: np.ndarray, goal_xz: np.ndarray,
                   cfg: WorkspaceConfig | None = None) -> np.ndarray | None:
    """World (x, z) waypoints (K, 2) from start to goal, both included, or None when no safe path exists.

    A direct line of sight is taken as is; otherwise Dijkstra (edge weight = length) between the nearest
    vertices visible from the start and from the goal, then shortcut."""
    cfg = cfg or WorkspaceConfig()
    start = np.asarray(start_xz, dtype=np.float64).reshape(2)
    goal = np.asarray(goal_xz, dtype=np.float64).reshape(2)
    if workspace.empty:
        return None
    if line_of_sight(workspace, start, goal, cfg):
        return np.stack([start, goal])
    if graph.number_of_nodes() == 0:
        return None
    entries = visible_nodes(graph, workspace, start, cfg)
    exits = visible_nodes(graph, workspace, goal, cfg)
    for entry in entries:
        for exit_ in exits:
            if nx.has_path(graph, entry, exit_):
                nodes = nx.dijkstra_path(graph, entry, exit_, weight="weight")
                route = np.stack([start, *(graph.nodes[n]["pos"] for n in nodes), goal])
                return shortcut(route, workspace, cfg)
    return None


def path_length(waypoints: np.ndarray) -> float:
    """Total length in metres of a polyline (K, 2)."""
    return float(np.linalg.norm(np.diff(waypoints, axis=0), axis=1).sum()) if len(waypoints) > 1 else 0.0
