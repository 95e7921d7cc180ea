"""Hierarchical planning (paper sec. III-C, III-D3), step 4 of goal selection (`planning.goals.rank_goals`):
the candidates in the agent's own subregion R_l (sec. III-C1, UPGMA; `in_agent_subregion`) and the
local-then-global order (sec. III-C2, ties to the shorter travel; `local_then_global`)."""

from __future__ import annotations

import numpy as np

from activesplat.planning.candidates import Candidates, worth_a_visit
from activesplat.planning.explorer_config import GoalRules
from activesplat.workspace.plan import Plan
from activesplat.workspace.subregions import agent_subregion


def in_agent_subregion(plan: Plan, cand: Candidates, here: np.ndarray, hierarchical: bool) -> np.ndarray:
    """Which candidates lie in the agent's own subregion R_l (sec. III-C1: UPGMA, `agent_subregion`); none
    when ranking flat."""
    local = agent_subregion(plan.graph, plan.subregions, here) if hierarchical else None
    return np.array([hierarchical and plan.subregions.get(n) == local for n in cand.nodes])


def local_then_global(scores: np.ndarray, info: np.ndarray, travel: np.ndarray, open_: np.ndarray,
                      in_local: np.ndarray, rules: GoalRules, global_scores: np.ndarray | None = None
                      ) -> list[int]:
    """Indices best first: the local-global goal selection of sec. III-C2, ties to the shorter travel (sec.
    III-D3). Flat (`no-hp`, `rules.hierarchical` off): eq. 12 score order.

    Local stage: while an open node of the agent's own subregion (`in_local`) promises something to see
    (its information part `info` above `local_score_threshold`; the paper gives no value), those nodes come
    first in score order, the others after. Global stage otherwise (`_global_order`), on `global_scores`
    (default `scores`)."""
    order = sorted(range(len(scores)), key=lambda i: (-scores[i], travel[i]))
    if not rules.hierarchical:
        return order
    # stay local while a node of this subregion promises something to see; the unvisited / in-horizon flags
    # alone do not keep the agent in a room it has seen
    worth = worth_a_visit(info, open_, rules.local_score_threshold)
    local_best = [i for i in order if in_local[i] and worth[i]]
    if local_best:
        return local_best + [i for i in order if i not in local_best]
    return _global_order(scores if global_scores is None else global_scores, travel, worth, rules)


def _global_order(scores: np.ndarray, travel: np.ndarray, worth: np.ndarray, rules: GoalRules) -> list[int]:
    """The global stage of sec. III-C2: every node by its score minus the distance cost,
    `global_distance_weight` per metre of travel (the paper gives no weight); ties to the shorter travel. With
    `global_information_first` (ours, on by default; docs/protocol.md §5) the nodes that promise something
    to see (`worth`) come ahead of the others, however near those are: the unvisited / in-horizon flags
    alone kept the agent going from node to node of a room it had seen."""
    global_score = scores - rules.global_distance_weight * travel
    ranked = sorted(range(len(scores)), key=lambda i: (-global_score[i], travel[i]))
    if not rules.global_information_first:
        return ranked
    return [i for i in ranked if worth[i]] + [i for i in ranked if not worth[i]]


__all__ = ["in_agent_subregion", "local_then_global"]
