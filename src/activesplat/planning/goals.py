"""Goal selection (paper sec. III-B, III-C): the candidate goal nodes of a replan, best first
(`rank_goals`), in the paper's four steps, each in its own module:

1. candidate nodes and their state (sec. III-B1; `planning.candidates`),
2. panoramas at the candidates (sec. III-B2, III-D2) and 3. their eq. 12 scores (`planning.panorama_scores`),
4. the local-then-global order over the UPGMA subregions (sec. III-C; `planning.hierarchical`).

What the explorer does with the goal once chosen (the release's long-path rule, detours) is
`planning.on_the_way`; the on-arrival rotation targets (sec. III-B3) are `planning.viewpoints`'."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from activesplat.planning.candidates import Candidates, candidate_states, worth_a_visit
from activesplat.planning.config import PlanningConfig
from activesplat.planning.explorer_config import GoalRules
from activesplat.planning.hierarchical import in_agent_subregion, local_then_global
from activesplat.planning.panorama import RenderFn
from activesplat.planning.panorama_scores import (
    eq12_scores,
    in_horizon_flags,
    information_part,
    render_panoramas,
)
from activesplat.planning.travel import travel_lengths
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.plan import Plan


def rank_goals(plan: Plan, here: np.ndarray, render: RenderFn, floor_height: float,
               visited: Sequence[np.ndarray], failed: Sequence[np.ndarray], pcfg: PlanningConfig,
               wcfg: WorkspaceConfig, rules: GoalRules, rng: np.random.Generator) -> list[int]:
    """Candidate goal nodes of `plan.graph`, best first (eq. 12 scores; local-then-global, sec. III-C).

    1. Candidates (sec. III-B1): the view nodes and leaves of the Voronoi graph, each unvisited or not
       (eq. 12's s_u) and failed or not (`candidate_states`).
    2. Panoramas (sec. III-B2, III-D2) at the open candidates: each one's invisible share and hull volume,
       eq. 12's s_o and s_c before normalising (`render_panoramas`). The paper renders one at every
       unvisited node; this project at the nearest open node of each subregion plus the `max_panoramas`
       nearest (`panorama_candidates`; docs/protocol.md §5).
    3. Scores: the information part w_o s_o + w_c s_c (`information_part`) and eq. 12 with the in-horizon flag
       s_h (`eq12_scores`); the scores of the global stage leave s_h out (ours, `global_in_horizon`).
    4. Local then global (sec. III-C2, `local_then_global`): the nodes of the agent's own subregion (sec.
       III-C1) first while one of them that is open promises more than `local_score_threshold`; else
       every node by its global score, eq. 12 minus the distance cost. The threshold and the distance
       weight are this project's (the paper gives none), nodes within `local_near_m` of travel count as
       local, and the global stage ranks the open nodes that promise something ahead of the rest
       (`global_information_first`): departures listed in docs/protocol.md §5.

    Records every candidate's score, information part and travel in `plan.scores` / `plan.info` /
    `plan.travel`, the stage ("local", "global" or "flat") in `plan.stage`.

    `random_goals` (the `random` ablation): a random order of the open nodes, then the others (no
    scores)."""
    graph, score_cfg = plan.graph, pcfg.score
    # 1. candidates (sec. III-B1)
    cand = candidate_states(graph, visited, failed, score_cfg.unvisited_radius_m)
    if cand is None:
        return []
    if rules.random_goals:
        return _random_order(cand, rng)
    # 2. panoramas at the open candidates (sec. III-B2)
    views = render_panoramas(plan, cand, here, render, floor_height, pcfg, rules)
    # 3. eq. 12 scores and their information part; the agent's own subregion R_l (sec. III-C1)
    hierarchical = rules.hierarchical and bool(plan.subregions)  # flat: `no-hp`, or no subregions yet
    in_local = in_agent_subregion(plan, cand, here, hierarchical)
    info = information_part(views, score_cfg)
    in_horizon = in_horizon_flags(plan, cand, here, wcfg, hierarchical and not rules.local_in_horizon)
    scores, global_scores = eq12_scores(cand, views, in_horizon, score_cfg, rules)
    travel = travel_lengths(graph, here, cand.nodes, cand.pos)
    if hierarchical and rules.local_near_m is not None:  # nodes this near count as local (ours)
        in_local = in_local | (travel <= rules.local_near_m)
    plan.scores = {n: float(s) for n, s in zip(cand.nodes, scores, strict=True)}
    plan.travel = {n: float(t) for n, t in zip(cand.nodes, travel, strict=True)}
    plan.info = {n: float(v) for n, v in zip(cand.nodes, info, strict=True)}
    # 4. local then global (sec. III-C2)
    local_promising = worth_a_visit(info, cand.open_, rules.local_score_threshold) & in_local
    plan.stage = "flat" if not hierarchical else "local" if local_promising.any() else "global"
    order = local_then_global(scores, info, travel, cand.open_, in_local,
                              dataclasses.replace(rules, hierarchical=hierarchical), global_scores)
    return [cand.nodes[i] for i in order]


def _random_order(cand: Candidates, rng: np.random.Generator) -> list[int]:
    """The `random` ablation (`random_goals`): the open candidates in a random order, then the others."""
    order = rng.permutation(len(cand.nodes))
    return ([cand.nodes[i] for i in order if cand.open_[i]]
            + [cand.nodes[i] for i in order if not cand.open_[i]])


__all__ = ["rank_goals"]
