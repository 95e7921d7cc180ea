"""The way to a chosen goal, once the ranking (sec. III-C2) has chosen it: the release's long-path rule
(`closer_on_the_way`: a worthwhile node on a long path's way becomes the goal), and this project's
detour to a node worth a visit on the way (`worth_a_detour`). Not in the paper; the explorer applies them
to the goal `planning.goals.rank_goals` put first."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import networkx as nx
import numpy as np

from activesplat.planning.candidates import node_xz, open_node
from activesplat.planning.explorer_config import GoalRules
from activesplat.workspace.paths import path_length
from activesplat.workspace.plan import Plan


def distance_to_polyline(p: np.ndarray, path: np.ndarray) -> float:
    """Shortest distance from the point p (2,) to the polyline path (M,2)."""
    if len(path) == 1:
        return float(np.hypot(*(p - path[0])))
    a, b = path[:-1], path[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    return float(np.min(np.hypot(*(a + t[:, None] * ab - p).T)))


def closer_on_the_way(plan: Plan, goal: np.ndarray, path: np.ndarray, visited: Sequence[np.ndarray],
                      failed: Sequence[np.ndarray], unvisited_radius: float, rules: GoalRules,
                      find_path: Callable[[np.ndarray], np.ndarray | None]) -> tuple[np.ndarray, np.ndarray]:
    """The release's long-path rule: a goal more than `long_path_m` away is kept only if no closer,
    lower-scoring but still worthwhile node (information above the local threshold, unvisited, not failed)
    lies on the way (within `on_the_way_m` of the path); otherwise the best such node is the goal.
    `find_path(node_pos)` plans the path from the agent to a node (None: no safe path)."""
    best, best_score = None, -np.inf
    for node, score in plan.scores.items():
        if plan.info.get(node, 0.0) <= rules.local_score_threshold or score <= best_score:
            continue
        pos = node_xz(plan.graph, node)
        if not open_node(pos, visited, failed, unvisited_radius) or np.hypot(*(pos - goal)) < 1e-6:
            continue
        if distance_to_polyline(pos, path) <= rules.on_the_way_m:
            best, best_score = pos, score
    if best is None:
        return goal, path
    closer = find_path(best)
    if closer is None or path_length(closer) >= path_length(path):
        return goal, path
    return best, closer


def worth_a_detour(plan: Plan, goal_node: int, visited: Sequence[np.ndarray], failed: Sequence[np.ndarray],
                   unvisited_radius: float, detour_m: float, min_info: float) -> int | None:
    """A node worth a visit on the way to a global goal (ours): among the open nodes whose information
    exceeds `min_info`, nearer to the agent than the goal, and costing at most `detour_m` of extra
    travel (agent -> node -> goal along the graph, against agent -> goal), the nearest; None when there is
    none. A room passed on the way, whose door shows little of it, is looked into then rather than at the
    end of the episode."""
    graph = plan.graph
    if goal_node not in graph or goal_node not in plan.travel:
        return None
    to_goal = nx.single_source_dijkstra_path_length(graph, goal_node, weight="weight")
    direct = plan.travel[goal_node]
    best, best_travel = None, np.inf
    for node, info in plan.info.items():
        if node == goal_node or info <= min_info or node not in to_goal:
            continue
        travel = plan.travel.get(node, np.inf)
        if travel >= direct or travel + to_goal[node] - direct > detour_m:
            continue
        if not open_node(node_xz(graph, node), visited, failed, unvisited_radius):
            continue
        if travel < best_travel:
            best, best_travel = node, travel
    return best


__all__ = ["closer_on_the_way", "distance_to_polyline", "worth_a_detour"]
