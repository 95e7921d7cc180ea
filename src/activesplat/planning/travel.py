"""Travel on the Voronoi graph (paper sec. III-C's distances): how far each candidate is from the agent
along the graph (`travel_lengths`; goal selection, `planning.goals`, ranks with it), and the shortest open
route through a set of stops (`shortest_tour`: exact Held-Karp for a few, local search beyond; the
benchmarks' room tours)."""

from __future__ import annotations

import networkx as nx
import numpy as np

NO_PATH_FACTOR = 3.0
"""Travel to a node the graph gives no path to: this times the straight distance (a stand-in, ours)."""


def travel_lengths(graph: nx.Graph, here: np.ndarray, nodes: list[int], pos: np.ndarray) -> np.ndarray:
    """Approximate travel length to each node: from the graph node nearest the agent along the graph (plus
    the straight hop to it); three times the Euclidean distance where the graph gives no path."""
    if graph.number_of_nodes() == 0:
        return np.hypot(*(pos - here).T)
    keys = list(graph.nodes)
    all_pos = np.stack([np.asarray(graph.nodes[n]["pos"], float) for n in keys])
    start = int(np.argmin(np.hypot(*(all_pos - here).T)))
    hop = float(np.hypot(*(all_pos[start] - here)))
    lengths = nx.single_source_dijkstra_path_length(graph, keys[start], weight="weight")
    out = np.array([hop + lengths.get(n, np.inf) for n in nodes])
    eu = np.hypot(*(pos - here).T)
    return np.where(np.isfinite(out), out, eu * NO_PATH_FACTOR)


def shortest_tour(start: np.ndarray, pairwise: np.ndarray, exact_up_to: int = 10,
                  max_rounds: int = 100) -> list[int]:
    """An open route from the agent through every stop, short first: the order of the K stops (indices)
    that visits them all, starting where the agent is (`start[i]`: travel from the agent to stop i;
    `pairwise`: between stops, symmetric) and ending anywhere. Up to `exact_up_to` stops the shortest
    (Held-Karp dynamic programme over subsets); beyond, nearest neighbour and then local search until no
    move shortens the route: 2-opt (walk a stretch backwards) and or-opt (move a stretch of up to three
    stops elsewhere, either way round)."""
    k = len(start)
    if k <= 1:
        return list(range(k))
    start, pairwise = np.asarray(start, float), np.asarray(pairwise, float)
    if k <= exact_up_to:
        return _held_karp(start, pairwise)
    left, route, at = set(range(k)), [], None
    while left:
        row = start if at is None else pairwise[at]
        at = min(left, key=lambda j: (row[j], j))
        route.append(at)
        left.remove(at)

    def length(r: list[int]) -> float:
        a = np.asarray(r)
        return float(start[a[0]] + pairwise[a[:-1], a[1:]].sum())

    def moves(r: list[int]):
        for i in range(k - 1):
            for j in range(i + 1, k):
                yield r[:i] + r[i:j + 1][::-1] + r[j + 1:]
        for size in range(1, min(3, k - 1) + 1):
            for i in range(k - size + 1):
                stretch, rest = r[i:i + size], r[:i] + r[i + size:]
                for at in range(len(rest) + 1):
                    if at != i:
                        yield rest[:at] + stretch + rest[at:]
                    if size > 1:
                        yield rest[:at] + stretch[::-1] + rest[at:]

    best = length(route)
    for _ in range(max_rounds):
        for candidate in moves(route):
            cost = length(candidate)
            if cost < best - 1e-9:
                route, best = candidate, cost
                break
        else:
            break
    return route


def _held_karp(start: np.ndarray, pairwise: np.ndarray) -> list[int]:
    """The shortest open route from the agent through every stop (see `shortest_tour`): cost[S, j] is the
    shortest route that visits the set S (a bit mask) and ends at j."""
    k = len(start)
    full = 1 << k
    cost = np.full((full, k), np.inf)
    back = np.full((full, k), -1, dtype=np.int64)
    for j in range(k):
        cost[1 << j, j] = start[j]
    bits = 1 << np.arange(k)
    for mask in range(1, full):
        ends = np.flatnonzero(mask & bits)
        if len(ends) < 2:
            continue
        # arriving at j from i: the route over mask without j, ending at i, then the leg i -> j
        via = cost[mask ^ bits[ends]] + pairwise[:, ends].T
        best = np.argmin(via, axis=1)
        cost[mask, ends] = via[np.arange(len(ends)), best]
        back[mask, ends] = best
    route, mask, at = [], full - 1, int(np.argmin(cost[full - 1]))
    while at >= 0:
        route.append(at)
        mask, at = mask ^ (1 << at), int(back[mask, at])
    return route[::-1]


__all__ = ["NO_PATH_FACTOR", "shortest_tour", "travel_lengths"]
