"""Candidate nodes and their state (paper sec. III-B1: Voronoi nodes as position candidates), step 1 of goal
selection (`planning.goals.rank_goals`): which nodes are candidates, and of each node whether it is
unvisited (eq. 12's s_u), failed (the release's failure penalty), open (unvisited and not failed) and
worth a visit (open, with an information part above the local-score threshold). The later steps, the
late-episode reorderings and the on-the-way rules ask the same of single nodes."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import networkx as nx
import numpy as np

VISIT_MEMORY = 2000
"""Positions of the agent's most recent steps that count for the unvisited flag (every step of a 1000- or
2000-step episode)."""


def node_state(node_pos: np.ndarray, visited: Sequence[np.ndarray], failed: Sequence[np.ndarray],
               radius: float) -> tuple[bool, bool]:
    """(unvisited, failed) of a node: no recent position within `radius` of it (eq. 12's s_u), and a failed
    goal within `radius` of it."""
    return not _any_within(node_pos, visited[-VISIT_MEMORY:], radius), _any_within(node_pos, failed, radius)


def open_node(node_pos: np.ndarray, visited: Sequence[np.ndarray], failed: Sequence[np.ndarray],
              radius: float) -> bool:
    """Whether a node is open: unvisited and not failed (`node_state`)."""
    unvisited, is_failed = node_state(node_pos, visited, failed, radius)
    return unvisited and not is_failed


def node_xz(graph: nx.Graph, node: int) -> np.ndarray:
    """The floor position (x, z) of a graph node."""
    return np.asarray(graph.nodes[node]["pos"], float)


def _any_within(node_pos: np.ndarray, places: Sequence[np.ndarray], radius: float) -> bool:
    """Whether a floor position of `places` lies within `radius` of `node_pos` (one vectorised pass)."""
    gap = np.asarray(node_pos, float) - np.asarray(places, float).reshape(-1, 2)
    return bool((np.hypot(gap[:, 0], gap[:, 1]) <= radius).any())


def worth_a_visit(info: np.ndarray | float, open_: np.ndarray | bool, threshold: float) -> np.ndarray:
    """Nodes that promise something to see: open (unvisited, not failed) with an information part above
    `threshold` (the local-score threshold of both planning stages). Arrays or one node's scalars."""
    return np.asarray(open_, bool) & (np.asarray(info, float) > threshold)


def goal_candidates(graph: nx.Graph) -> list[int]:
    """View-position candidates: nodes marked `view` and leaves; every node when there are none."""
    nodes = [n for n, d in graph.nodes(data=True) if d.get("view") or graph.degree[n] <= 1]
    return nodes or list(graph.nodes)


@dataclass
class Candidates:
    """The candidate nodes of one replan (sec. III-B1: Voronoi nodes as position candidates) and their state,
    the arrays in the order of `nodes`."""

    nodes: list[int]
    pos: np.ndarray
    """(N, 2) floor positions."""
    unvisited: np.ndarray
    """eq. 12's s_u: no recent position of the agent near the node (`node_state`)."""
    failed: np.ndarray
    """A failed goal near the node (the release's failure penalty)."""
    open_: np.ndarray
    """Unvisited and not failed."""


def candidate_states(graph: nx.Graph, visited: Sequence[np.ndarray], failed: Sequence[np.ndarray],
                     radius: float) -> Candidates | None:
    """Step 1 of `rank_goals` (sec. III-B1): the view-position candidates and their state; None when the
    graph has no node."""
    nodes = goal_candidates(graph)
    if not nodes:
        return None
    pos = np.stack([node_xz(graph, n) for n in nodes])
    state = [node_state(p, visited, failed, radius) for p in pos]
    unvisited = np.array([s[0] for s in state])
    is_failed = np.array([s[1] for s in state])
    return Candidates(nodes, pos, unvisited, is_failed, unvisited & ~is_failed)


__all__ = ["VISIT_MEMORY", "Candidates", "candidate_states", "goal_candidates", "node_state", "node_xz",
           "open_node", "worth_a_visit"]
