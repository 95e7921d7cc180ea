"""Hierarchical planning (paper sec. III-C, III-D3), step 4 of goal selection (`planning.goals.rank_goals`):
the candidates in the agent's own subregion R_l (sec. III-C1, UPGMA; `in_agent_subregion`), the
local-then-global order (sec. III-C2, ties to the shorter travel; `local_then_global`) and this project's
options of the global stage (a route through the subregions, `tour_first`; a committed global choice;
`global_stage_options`). Also the late-episode reorderings the explorer applies to the ranked order as
the step budget runs out (ours: `last_call_first`, `reachable_first`)."""

from __future__ import annotations

from collections.abc import Sequence

import networkx as nx
import numpy as np

from activesplat.planning.candidates import Candidates, node_xz, open_node, worth_a_visit
from activesplat.planning.explorer_config import GoalRules
from activesplat.planning.replan_memory import Commitment, RouteMemory
from activesplat.planning.travel import pairwise_travel, shortest_tour
from activesplat.workspace.plan import Plan
from activesplat.workspace.subregions import agent_subregion


def in_agent_subregion(plan: Plan, cand: Candidates, here: np.ndarray, hierarchical: bool) -> np.ndarray:
    """Which candidates lie in the agent's own subregion R_l (sec. III-C1: UPGMA, `agent_subregion`); none
    when ranking flat."""
    local = agent_subregion(plan.graph, plan.subregions, here) if hierarchical else None
    return np.array([hierarchical and plan.subregions.get(n) == local for n in cand.nodes])


def local_then_global(scores: np.ndarray, info: np.ndarray, travel: np.ndarray, open_: np.ndarray,
                      in_local: np.ndarray, rules: GoalRules, global_scores: np.ndarray | None = None,
                      global_info: np.ndarray | None = None) -> list[int]:
    """Indices best first: the local-global goal selection of sec. III-C2, ties to the shorter travel (sec.
    III-D3). Flat (`no-hp`, `rules.hierarchical` off): eq. 12 score order.

    Local stage: while an open node of the agent's own subregion (`in_local`) promises something to see
    (its information part `info` above `local_score_threshold`; the paper gives no value), those nodes come
    first in score order, the others after. Global stage otherwise (`_global_order`), on `global_scores`
    (default `scores`) and `global_info` (default `info`)."""
    order = sorted(range(len(scores)), key=lambda i: (-scores[i], travel[i]))
    if not rules.hierarchical:
        return order
    # stay local while a node of this subregion promises something to see; the unvisited / in-horizon flags
    # alone do not keep the agent in a room it has seen
    worth = worth_a_visit(info, open_, rules.local_score_threshold)
    local_best = [i for i in order if in_local[i] and worth[i]]
    if local_best:
        return local_best + [i for i in order if i not in local_best]
    if global_info is not None:
        worth = worth_a_visit(global_info, open_, rules.local_score_threshold)
    return _global_order(scores if global_scores is None else global_scores, travel, worth, rules)


def _global_order(scores: np.ndarray, travel: np.ndarray, worth: np.ndarray, rules: GoalRules) -> list[int]:
    """The global stage of sec. III-C2: every node by its score minus the distance cost,
    `global_distance_weight` per metre of travel (the paper gives no weight), or with `global_halving_m`
    the score per way, halved at that much travel (ours, off); ties to the shorter travel. With
    `global_information_first` (ours, on by default; docs/protocol.md §5) the nodes that promise something
    to see (`worth`) come ahead of the others, however near those are: the unvisited / in-horizon flags
    alone kept the agent going from node to node of a room it had seen."""
    if rules.global_halving_m is None:
        global_score = scores - rules.global_distance_weight * travel
    else:  # score per way: halved at global_halving_m of travel
        global_score = scores / (1.0 + travel / rules.global_halving_m)
    ranked = sorted(range(len(scores)), key=lambda i: (-global_score[i], travel[i]))
    if not rules.global_information_first:
        return ranked
    return [i for i in ranked if worth[i]] + [i for i in ranked if not worth[i]]


def tour_first(ranked: list[int], worth: np.ndarray, travel: np.ndarray, nodes: Sequence[int],
               subregions: dict[int, int], graph: nx.Graph, memory: RouteMemory | None = None,
               in_place: bool = False) -> list[int]:
    """The global stage's order with a route (ours, `global_tour`): of the nodes that promise something to
    see (`worth`), the first in `ranked` of each subregion stands for it; the subregions come in the order
    of the shortest open route from the agent through them all (`shortest_tour`), and the rest of `ranked`
    follows in its own order. Score minus distance alone sends the agent to the best node, then to the best
    from there, and a room left on the way is a long trip back at the end. With `memory` the order of the
    last route is kept for the subregions still on it (`RouteMemory.follow`), and the route is remembered.
    `in_place` (`ExplorerConfig.route_in_place`): the route reorders the subregions' representatives only
    among themselves, each taking the place in `ranked` of the one it replaces, so a node `ranked` puts
    ahead of every representative (a near subregion that promises too little to be a stop) stays ahead."""
    reps: list[int] = []
    seen: set = set()
    for i in ranked:
        if not worth[i]:
            continue
        key = subregions.get(nodes[i], ("node", i))
        if key not in seen:
            seen.add(key)
            reps.append(i)
    rep_pos = np.array([graph.nodes[nodes[i]]["pos"] for i in reps], float).reshape(-1, 2)
    if len(reps) <= 1:
        if memory is not None:
            memory.stops = rep_pos
        return ranked
    pairwise = pairwise_travel(graph, [nodes[i] for i in reps])
    route = None if memory is None else memory.follow(rep_pos, travel[reps], pairwise)
    if route is None:
        route = shortest_tour(travel[reps], pairwise)
    if memory is not None:
        memory.stops = rep_pos[route]
    first = [reps[r] for r in route]
    if in_place:
        slots = iter(first)
        rep_set = set(reps)
        return [next(slots) if i in rep_set else i for i in ranked]
    taken = set(first)
    return first + [i for i in ranked if i not in taken]


def global_stage_options(plan: Plan, cand: Candidates, order: list[int], info: np.ndarray,
                         travel: np.ndarray, rules: GoalRules, route_memory: RouteMemory | None,
                         commitment: Commitment | None) -> list[int]:
    """The global stage's `order` with this project's two options applied (ours, both off by default;
    docs/exploration.md): a route through the subregions worth a visit (`global_tour`, `route_memory`:
    `tour_first`), and a global choice followed while its subregion still holds something to see
    (`commitment`: `Commitment.first`, which sets `plan.committed`)."""
    promising = worth_a_visit(info, cand.open_, rules.local_score_threshold)
    if rules.global_tour or route_memory is not None:
        stops = promising if route_memory is None else promising & (info > route_memory.min_info)
        order = tour_first(order, stops, travel, cand.nodes, plan.subregions, plan.graph, route_memory,
                           rules.route_in_place)
    if commitment is not None:
        order, plan.committed = commitment.first(order, promising, cand.nodes, cand.pos, plan.subregions)
    return order


def last_call_first(order: list[int], plan: Plan, steps_left: int, visited: Sequence[np.ndarray],
                    failed: Sequence[np.ndarray], radius: float, window: int, min_info: float,
                    steps_per_m: float, look_steps: int = 60) -> list[int]:
    """`order` with the node on its last call first (`ExplorerConfig.last_call_steps`): among the open nodes
    that promise at least `min_info`, those whose arrival (their travel times `steps_per_m`) leaves between
    `look_steps` and `window` of the `steps_left`; the one that promises most (ties: the nearer). A node
    left for later would be out of reach before the budget ends. `order` itself when no node is on it."""
    calls = []
    for n in order:
        info, travel = plan.info.get(n, 0.0), plan.travel.get(n, np.inf)
        if info < min_info or not np.isfinite(travel):
            continue
        after = steps_left - travel * steps_per_m
        if not look_steps <= after <= window:
            continue
        if open_node(node_xz(plan.graph, n), visited, failed, radius):
            calls.append(n)
    if not calls:
        return order
    best = max(calls, key=lambda n: (plan.info[n], -plan.travel[n]))
    return [best] + [n for n in order if n != best]


def reachable_first(order: list[int], plan: Plan, steps_left: int, visited: Sequence[np.ndarray],
                    failed: Sequence[np.ndarray], radius: float, steps_per_m: float,
                    threshold: float) -> list[int]:
    """`order` with the open nodes that promise something to see (`worth_a_visit` at `threshold`) and that
    the `steps_left` can reach (travel x `steps_per_m`) first, in their order; then the rest, in theirs
    (`ExplorerConfig.out_of_reach_last`). `order` itself when no such node is out of reach, or none is
    within it."""
    worth = worth_a_visit(np.array([plan.info.get(n, 0.0) for n in order]), True, threshold)
    reachable = np.array([plan.travel.get(n, np.inf) * steps_per_m <= steps_left for n in order], bool)
    if not (worth & ~reachable).any():
        return order
    for k in np.flatnonzero(worth):
        worth[k] = open_node(node_xz(plan.graph, order[k]), visited, failed, radius)
    first = worth & reachable
    if not first.any() or not (worth & ~reachable).any():
        return order
    ahead = [n for n, f in zip(order, first, strict=True) if f]
    return ahead + [n for n, f in zip(order, first, strict=True) if not f]


__all__ = ["global_stage_options", "in_agent_subregion", "last_call_first", "local_then_global",
           "reachable_first", "tour_first"]
