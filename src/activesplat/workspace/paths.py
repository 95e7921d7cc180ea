"""Safe paths on the Voronoi graph (paper sec. III-C; docs/protocol.md §5): Dijkstra on the graph,
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


def enter_workspace(workspace: Workspace, a: np.ndarray, b: np.ndarray, cfg: WorkspaceConfig) -> np.ndarray:
    """Segment starts (M, 2): each `a` itself when it lies in the workspace, else the point one agent
    radius from `a` towards `b` (ours: the floor right under the agent is often unobserved, so the
    agent's own disc is not checked)."""
    offset = b - a
    length = np.linalg.norm(offset, axis=1, keepdims=True)
    step = np.minimum(1.0, cfg.agent_radius / np.maximum(length, 1e-12))
    inside = workspace.clearance_at(a)[:, None] > 0
    return np.where(inside, a, a + offset * step)


def lines_of_sight(workspace: Workspace, a: np.ndarray, b: np.ndarray, cfg: WorkspaceConfig) -> np.ndarray:
    """(M,) whether each straight segment a_i-b_i (M, 2) keeps the required clearance at every sample:
    2 agent radii, relaxed to the clearance at its endpoints when the agent already stands (or must stand)
    closer to an obstacle than that, but always strictly inside the workspace (an endpoint outside it
    must not license a segment through walls)."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 2)
    a, b = enter_workspace(workspace, a, b, cfg), enter_workspace(workspace, b, a, cfg)
    ends = np.minimum(workspace.clearance_at(a), workspace.clearance_at(b))
    need = np.maximum(np.minimum(cfg.path_clearance, ends), MIN_CLEARANCE)
    return workspace.segments_clearance(a, b) >= need - 1e-9


def line_of_sight(workspace: Workspace, a: np.ndarray, b: np.ndarray, cfg: WorkspaceConfig) -> bool:
    """Whether the straight segment a-b keeps the required clearance (see :func:`lines_of_sight`)."""
    return bool(lines_of_sight(workspace, a, b, cfg)[0])


def visible_nodes(graph: nx.Graph, workspace: Workspace, xz: np.ndarray, cfg: WorkspaceConfig) -> list[int]:
    """The up to `entry_candidates` nearest nodes that are in line of sight of `xz`, nearest first."""
    nodes = sorted(graph.nodes)
    positions = node_positions(graph)
    dist = np.linalg.norm(positions - xz, axis=1)
    order = np.argsort(dist, kind="stable")[: cfg.entry_candidates]
    visible = lines_of_sight(workspace, np.broadcast_to(xz, (len(order), 2)), positions[order], cfg)
    return [nodes[i] for i in order[visible]]


def shortcut(waypoints: np.ndarray, workspace: Workspace, cfg: WorkspaceConfig) -> np.ndarray:
    """From each kept waypoint jump to the farthest later waypoint in line of sight (docs/protocol.md §5)."""
    kept, i = [0], 0
    last = len(waypoints) - 1
    while i < last:
        later = np.arange(i + 2, last + 1)
        here = np.broadcast_to(waypoints[i], (len(later), 2))
        visible = lines_of_sight(workspace, here, waypoints[later], cfg)
        i = int(later[visible].max()) if visible.any() else i + 1
        kept.append(i)
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


def needed_clearance(workspace: Workspace, here: np.ndarray, cfg: WorkspaceConfig) -> float:
    """Clearance a path from `here` must keep: the agent's radius, or less where the agent already stands
    closer to the workspace border (the polished workspace can be thinner than the agent in a doorway it
    stands in; a path out of there is fine)."""
    return min(cfg.agent_radius, float(workspace.clearance_at(here)) - 1e-6)


def _toward(start: np.ndarray, target: np.ndarray, length_m: float) -> np.ndarray:
    """The point `length_m` from `start` toward `target`, or `target` when nearer."""
    d = target - start
    return start + d * min(1.0, length_m / max(float(np.hypot(*d)), 1e-9))


def path_ahead_clear(workspace: Workspace | None, here: np.ndarray, waypoint: np.ndarray, lookahead_m: float,
                     tolerance_m: float, cfg: WorkspaceConfig,
                     segment_start: np.ndarray | None = None) -> bool:
    """Whether the next `lookahead_m` toward `waypoint` is still passable on the current workspace: blocked
    when it gets narrower than `needed_clearance` less `tolerance_m`, and always when it leaves the
    workspace. No workspace (or an empty one) blocks nothing.

    Given `segment_start` (the waypoint the agent reached last), a line from here that fails is still clear
    when it stays inside the workspace and the planned segment itself, from `segment_start` toward
    `waypoint`, passes with the planner's bound (:func:`lines_of_sight`: relaxed to the clearance at the
    segment's ends). The agent reaches a waypoint within the arrival radius, not on it, and from there the
    straight line to the next waypoint can graze a corner the planned segment clears: FBE paths that start
    at the agent's grid cell were refused at their first step, dozens of times per episode."""
    if workspace is None or workspace.empty:
        return True
    need = needed_clearance(workspace, here, cfg)
    line = workspace.segments_clearance(here[None], _toward(here, waypoint, lookahead_m)[None])[0]
    if line >= max(need - tolerance_m, 1e-6):
        return True
    if segment_start is None:
        return False
    start = np.asarray(segment_start, float)
    ends = workspace.clearance_at(np.stack([start, np.asarray(waypoint, float)]))
    planned_need = max(min(need, float(ends.min())) - tolerance_m, 1e-6)
    reach = lookahead_m + float(np.hypot(*(here - start)))
    planned = workspace.segments_clearance(start[None], _toward(start, waypoint, reach)[None])[0]
    return bool(line >= 1e-6 and planned >= planned_need)
