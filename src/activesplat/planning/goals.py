"""Goal selection (paper sec. III-B, III-C) as functions of the plan and the agent's history: which
Voronoi nodes are candidates, their eq. 12 scores from rendered panoramas, the local-then-global order
over UPGMA subregions, and the release's long-path rule. The explorer calls these at every replan."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import networkx as nx
import numpy as np

from activesplat.geometry import wrap_angle
from activesplat.planning.config import PlanningConfig, ScoreConfig
from activesplat.planning.controller import ControllerConfig, fewest_actions_order
from activesplat.planning.observed import ObservedSurface, poorly_observed_share
from activesplat.planning.panorama import RenderFn, render_panorama
from activesplat.planning.replan_memory import Commitment, Promises, RouteMemory
from activesplat.planning.travel import pairwise_travel, shortest_tour, travel_lengths
from activesplat.planning.viewpoints import (
    RotationTarget,
    hull_volume,
    information_scores,
    invisible_share,
    node_scores,
)
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.paths import line_of_sight, path_length, visible_nodes
from activesplat.workspace.plan import Plan
from activesplat.workspace.subregions import agent_subregion

VISIT_MEMORY = 2000
"""Positions of the agent's most recent steps that count for the unvisited flag (every step of a 1000- or
2000-step episode)."""


@dataclass(frozen=True)
class GoalRules:
    """The explorer's goal-selection knobs (see `ExplorerConfig` for their meaning and origin)."""

    local_score_threshold: float
    global_distance_weight: float
    max_panoramas: int
    panorama_height_m: float
    hierarchical: bool
    random_goals: bool
    long_path_m: float
    on_the_way_m: float
    global_in_horizon: bool = False
    local_in_horizon: bool = True
    global_information_first: bool = True
    panorama_every_subregion: bool = True
    global_halving_m: float | None = None
    global_tour: bool = False
    local_near_m: float | None = None
    route_in_place: bool = False


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


def panorama_candidates(nodes: list[int], dist: np.ndarray, open_: np.ndarray, subregions: dict[int, int],
                        max_panoramas: int, every_subregion: bool = True) -> list[int]:
    """Indices of the nodes scored by panorama: the nearest open node of every subregion first, so that
    rooms farther away are weighed too, then the nearest open nodes, `max_panoramas` in all. With
    `every_subregion` the subregions' nodes do not count against `max_panoramas`: every subregion with an
    open node gets one panorama however many there are, and `max_panoramas` nearest open nodes come on top
    (those already chosen are not scored twice)."""
    order = [int(i) for i in np.argsort(dist, kind="stable") if open_[i]]
    chosen: list[int] = []
    seen: set[int] = set()
    for i in order:
        region = subregions.get(nodes[i])
        if region is not None and region not in seen:
            seen.add(region)
            chosen.append(i)
    if every_subregion:
        taken = set(chosen)
        return chosen + [i for i in order[:max_panoramas] if i not in taken]
    chosen = chosen[:max_panoramas]
    taken = set(chosen)
    chosen += [i for i in order if i not in taken][: max_panoramas - len(chosen)]
    return chosen


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


def sampled_surface_term(poor: np.ndarray, cfg: ScoreConfig) -> np.ndarray:
    """The w_q information term of the candidates from their poorly sampled shares (`ScoreConfig.w_q`):
    relative to the largest share, or on the absolute scale of `ScoreConfig.quality_reference`."""
    poor = np.asarray(poor, float)
    if cfg.quality_reference is not None:
        return cfg.w_q * np.minimum(1.0, poor / cfg.quality_reference)
    return cfg.w_q * poor / poor.max() if poor.size and poor.max() > 0 else np.zeros_like(poor)


@dataclass
class _Candidates:
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


@dataclass
class _PanoramaTerms:
    """What the panoramas rendered at the candidates show (sec. III-B2), 0 where none was rendered."""

    invisible: np.ndarray
    """eq. 12's s_o before normalising: the panorama's invisible share (`invisible_share`)."""
    hull: np.ndarray
    """eq. 12's s_c before normalising: the hull volume of its invisible regions (`hull_volume`)."""
    scored: np.ndarray
    """Whether a panorama was rendered at the node."""
    poor: np.ndarray | None
    """The share of nearby surface the agent's depth sampled poorly (ours); None when that term is off."""


def rank_goals(plan: Plan, here: np.ndarray, render: RenderFn, floor_height: float,
               visited: Sequence[np.ndarray], failed: Sequence[np.ndarray], pcfg: PlanningConfig,
               wcfg: WorkspaceConfig, rules: GoalRules, rng: np.random.Generator,
               observed: ObservedSurface | None = None, promises: Promises | None = None,
               commitment: Commitment | None = None, route_memory: RouteMemory | None = None,
               no_path_travel: Callable[[np.ndarray], np.ndarray] | None = None) -> list[int]:
    """Candidate goal nodes of `plan.graph`, best first (eq. 12 scores; local-then-global, sec. III-C).

    1. Candidates (sec. III-B1): the view nodes and leaves of the Voronoi graph, each unvisited or not
       (eq. 12's s_u) and failed or not (`_candidates`).
    2. Panoramas (sec. III-B2, III-D2) at the open candidates: each one's invisible share and hull volume,
       eq. 12's s_o and s_c before normalising (`_render_panoramas`). The paper renders one at every
       unvisited node; this project at the nearest open node of each subregion plus the `max_panoramas`
       nearest (`panorama_candidates`; docs/protocol.md §5).
    3. Scores: the information part w_o s_o + w_c s_c (`_information`) and eq. 12 with the in-horizon flag
       s_h (`_eq12_scores`); the scores of the global stage leave s_h out (ours, `global_in_horizon`).
    4. Local then global (sec. III-C2, `local_then_global`): the nodes of the agent's own subregion (sec.
       III-C1) first while one of them that is open promises more than `local_score_threshold`; else
       every node by its global score, eq. 12 minus the distance cost. The threshold and the distance
       weight are this project's (the paper gives none), nodes within `local_near_m` of travel count as
       local, and the global stage ranks the open nodes that promise something ahead of the rest
       (`global_information_first`): departures listed in docs/protocol.md §5.

    Records every candidate's score, information part and travel in `plan.scores` / `plan.info` /
    `plan.travel`, the stage ("local", "global" or "flat") in `plan.stage`.

    Options of this project (ours, all off by default; measured in docs/exploration.md and
    docs/benchmark.md, "Tuning log"): `random_goals`: a random order of the open nodes, then the others (no
    scores). With `observed` and a positive `ScoreConfig.w_q`, the information part also counts the surface
    near each node that the agent's depth has not sampled (`planning.observed`, `sampled_surface_term`).
    With `promises` (hierarchical only) a node outside the agent's subregion promises at least what it
    promised at an earlier replan (`Promises`). With `route_memory` (or `global_tour`) the global stage
    follows a route through the subregions whose order is kept across replans (`RouteMemory`,
    `tour_first`). With `commitment` a global stage goes on toward the subregion chosen at an earlier
    global replan while it holds something to see (`Commitment`); whether it did is `plan.committed`.
    `no_path_travel` estimates the travel to nodes the graph gives no path to (`travel_lengths`)."""
    graph, score_cfg = plan.graph, pcfg.score
    # 1. candidates (sec. III-B1)
    cand = _candidates(graph, visited, failed, score_cfg.unvisited_radius_m)
    if cand is None:
        return []
    if rules.random_goals:
        return _random_order(cand, rng)
    # 2. panoramas at the open candidates (sec. III-B2)
    views = _render_panoramas(plan, cand, here, render, floor_height, pcfg, rules, observed)
    extra = _sampled_surface(plan, cand, views, score_cfg)
    # 3. eq. 12 scores and their information part; the agent's own subregion R_l (sec. III-C1)
    hierarchical = rules.hierarchical and bool(plan.subregions)  # flat: `no-hp`, or no subregions yet
    in_local = _in_agent_subregion(plan, cand, here, hierarchical)
    info, kept = _information(cand, views, extra, in_local, hierarchical, score_cfg, promises)
    in_horizon = _in_horizon(plan, cand, here, wcfg, hierarchical and not rules.local_in_horizon)
    scores, global_scores = _eq12_scores(cand, views, in_horizon, extra, kept, score_cfg, rules)
    travel = travel_lengths(graph, here, cand.nodes, cand.pos, no_path_travel)
    if hierarchical and rules.local_near_m is not None:  # nodes this near count as local (ours)
        in_local = in_local | (travel <= rules.local_near_m)
    plan.scores = {n: float(s) for n, s in zip(cand.nodes, scores, strict=True)}
    plan.travel = {n: float(t) for n, t in zip(cand.nodes, travel, strict=True)}
    plan.info = {n: float(v) for n, v in zip(cand.nodes, info, strict=True)}
    # 4. local then global (sec. III-C2). With `quality_in_local` off the sampled-surface term does not keep
    # the agent in its subregion: it only makes poorly sampled rooms worth a trip in the global stage
    local_info = info if score_cfg.quality_in_local else info - extra
    local_promising = worth_a_visit(local_info, cand.open_, rules.local_score_threshold) & in_local
    plan.stage = "flat" if not hierarchical else "local" if local_promising.any() else "global"
    order = local_then_global(scores, local_info, travel, cand.open_, in_local,
                              dataclasses.replace(rules, hierarchical=hierarchical), global_scores, info)
    plan.committed = False
    if plan.stage == "global":
        order = _global_stage_options(plan, cand, order, info, travel, rules, route_memory, commitment)
    return [cand.nodes[i] for i in order]


def _candidates(graph: nx.Graph, visited: Sequence[np.ndarray], failed: Sequence[np.ndarray],
                radius: float) -> _Candidates | None:
    """Step 1 of `rank_goals` (sec. III-B1): the view-position candidates and their state; None when the
    graph has no node."""
    nodes = goal_candidates(graph)
    if not nodes:
        return None
    pos = np.stack([node_xz(graph, n) for n in nodes])
    state = [node_state(p, visited, failed, radius) for p in pos]
    unvisited = np.array([s[0] for s in state])
    is_failed = np.array([s[1] for s in state])
    return _Candidates(nodes, pos, unvisited, is_failed, unvisited & ~is_failed)


def _random_order(cand: _Candidates, rng: np.random.Generator) -> list[int]:
    """The `random` ablation (`random_goals`): the open candidates in a random order, then the others."""
    order = rng.permutation(len(cand.nodes))
    return ([cand.nodes[i] for i in order if cand.open_[i]]
            + [cand.nodes[i] for i in order if not cand.open_[i]])


def _render_panoramas(plan: Plan, cand: _Candidates, here: np.ndarray, render: RenderFn,
                      floor_height: float, pcfg: PlanningConfig, rules: GoalRules,
                      observed: ObservedSurface | None) -> _PanoramaTerms:
    """Step 2 of `rank_goals` (sec. III-B2, III-D2): a panorama `panorama_height_m` above the floor at each
    node `panorama_candidates` picks, and its invisible share and hull volume; with the sampled-surface
    term on (ours: `observed` and a positive `ScoreConfig.w_q`) also its poorly sampled share, recorded in
    `plan.poor`. The largest invisible share is `plan.max_invisible`."""
    n = len(cand.nodes)
    quality = observed is not None and pcfg.score.w_q > 0
    views = _PanoramaTerms(np.zeros(n), np.zeros(n), np.zeros(n, bool), np.zeros(n) if quality else None)
    height = floor_height + rules.panorama_height_m
    dist = np.hypot(*(cand.pos - here).T)
    for i in panorama_candidates(cand.nodes, dist, cand.open_, plan.subregions, rules.max_panoramas,
                                  rules.panorama_every_subregion):
        pano = render_panorama(render, [cand.pos[i][0], height, cand.pos[i][1]], pcfg.panorama,
                               pcfg.panorama.front_faces_scores, pcfg.panorama.scores_back_face_seen)
        views.scored[i] = True
        views.invisible[i] = invisible_share(pano, pcfg.rotation)
        views.hull[i] = hull_volume(pano, pcfg.hull)
        if views.poor is not None:
            views.poor[i] = poorly_observed_share(pano, observed, pcfg.score.quality_radius_m)
    plan.max_invisible = float(views.invisible.max()) if views.scored.any() else 0.0
    if views.poor is not None:
        plan.poor = {n: float(v) for n, v, s in zip(cand.nodes, views.poor, views.scored, strict=True) if s}
    return views


def _sampled_surface(plan: Plan, cand: _Candidates, views: _PanoramaTerms, cfg: ScoreConfig) -> np.ndarray:
    """The sampled-surface term of the candidates (ours, off by default; `sampled_surface_term`): 0 when it
    is off, and, with the gate `ScoreConfig.quality_below_invisible`, until no panorama is that invisible."""
    gate = cfg.quality_below_invisible
    if views.poor is None or not (gate is None or plan.max_invisible < gate):
        return np.zeros(len(cand.nodes))
    return sampled_surface_term(views.poor, cfg)


def _in_agent_subregion(plan: Plan, cand: _Candidates, here: np.ndarray, hierarchical: bool) -> np.ndarray:
    """Which candidates lie in the agent's own subregion R_l (sec. III-C1: UPGMA, `agent_subregion`); none
    when ranking flat."""
    local = agent_subregion(plan.graph, plan.subregions, here) if hierarchical else None
    return np.array([hierarchical and plan.subregions.get(n) == local for n in cand.nodes])


def _information(cand: _Candidates, views: _PanoramaTerms, extra: np.ndarray, in_local: np.ndarray,
                 hierarchical: bool, cfg: ScoreConfig, promises: Promises | None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Step 3 of `rank_goals`: the information part of eq. 12, w_o s_o + w_c s_c with the shares relative to
    the best candidate (`information_scores`), plus the sampled-surface term `extra`: what keeps planning
    local, and what makes a node worth a stop on a long path's way. Returns it with what a kept promise
    (ours, `promises`, hierarchical only) added to it, which adds to the eq. 12 score alike; 0 in the
    agent's own subregion and at visited nodes, so the local stage sees what the panoramas show."""
    info = information_scores(views.invisible, views.hull, cfg) + extra
    kept = np.zeros(len(cand.nodes))
    if promises is not None and hierarchical:
        kept = promises.keep(cand.pos, info, views.scored, in_local | ~cand.unvisited) - info
        info = info + kept
    return info, kept


def _in_horizon(plan: Plan, cand: _Candidates, here: np.ndarray, wcfg: WorkspaceConfig,
                off: bool) -> np.ndarray:
    """eq. 12's s_h: the straight line from the agent to the node is collision-free; none when `off` (a
    hierarchical ranking with `local_in_horizon` off, ours)."""
    if off:
        return np.zeros(len(cand.pos), bool)
    return np.array([line_of_sight(plan.workspace, here, p, wcfg) for p in cand.pos])


def _eq12_scores(cand: _Candidates, views: _PanoramaTerms, in_horizon: np.ndarray, extra: np.ndarray,
                 kept: np.ndarray, cfg: ScoreConfig, rules: GoalRules
                 ) -> tuple[np.ndarray, np.ndarray | None]:
    """Step 3 of `rank_goals`: eq. 12, S = w_o s_o + w_c s_c + w_u s_u + w_h s_h less the release's failure
    penalty (`node_scores`), plus the sampled-surface term and kept promises; and the scores of the global
    stage, None when they are the same (`global_in_horizon`). This project's global stage leaves the
    in-horizon flag out: a node in sight of the agent is a local preference and, counted there too, keeps
    the agent near (ours; docs/protocol.md §5, docs/exploration.md)."""

    def eq12(s_h: np.ndarray) -> np.ndarray:
        return node_scores(views.invisible, views.hull, cand.unvisited, s_h, cand.failed, cfg) + extra + kept

    return eq12(in_horizon), None if rules.global_in_horizon else eq12(np.zeros_like(in_horizon))


def _global_stage_options(plan: Plan, cand: _Candidates, order: list[int], info: np.ndarray,
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


def bridge_toward(plan: Plan, here: np.ndarray, goal: np.ndarray, visited: Sequence[np.ndarray],
                  failed: Sequence[np.ndarray], unvisited_radius: float, wcfg: WorkspaceConfig, gain_m: float,
                  find_path: Callable[[np.ndarray], np.ndarray | None],
                  tries: int = 3) -> tuple[np.ndarray, np.ndarray] | None:
    """A way toward a goal that has no safe path from the agent, typically because the graph is cut where
    the floor was only seen from afar (ours): the open (unvisited, not failed) node of the agent's own
    graph component nearest to `goal`, if it is at least `gain_m` nearer to it than the agent is. Standing
    there, the agent sees the gap from close by and the map joins the two parts. Returns (node position,
    path) or None; the `tries` nearest candidates are planned to."""
    graph = plan.graph
    entries = visible_nodes(graph, plan.workspace, here, wcfg)
    if not entries:
        return None
    component = nx.node_connected_component(graph, entries[0])
    limit = float(np.hypot(*(goal - here))) - gain_m
    candidates = []
    for node in component:
        pos = node_xz(graph, node)
        gap = float(np.hypot(*(pos - goal)))
        if gap <= limit and open_node(pos, visited, failed, unvisited_radius):
            candidates.append((gap, node, pos))
    for _, _, pos in sorted(candidates, key=lambda c: (c[0], c[1]))[:tries]:
        path = find_path(pos)
        if path is not None:
            return pos, path
    return None


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


def select_rotation_targets(targets: Sequence[RotationTarget], yaw: float, pcfg: PlanningConfig,
                            max_views: int, pitch: float = 0.0, ctrl: ControllerConfig | None = None,
                            final_yaw: float | None = None,
                            tilt_within_deg: float | None = None) -> list[RotationTarget]:
    """On-arrival rotation targets (sec. III-B3): the heaviest panorama / high-loss targets, skipping those
    lighter than `RotationCandidateConfig.min_relative_weight` of their source's heaviest, those already in
    view (within their source's minimum offset of the heading, and less than 20 deg off level) and those
    within 20 deg of a chosen one, at most `max_views`. Returned in counter-clockwise order from
    the heading, or, given the controller `ctrl`, in the order that visits them in the fewest turns and
    tilts from (`yaw`, `pitch`), levelling and the turn back to `final_yaw` (if given) included
    (`controller.fewest_actions_order`). Given `tilt_within_deg`, each chosen target's pitch is brought that
    much closer to level (never past it): the tilt that puts the target that far from the image centre."""
    chosen: list[RotationTarget] = []
    heaviest: dict[str, float] = {}
    for t in targets:
        heaviest[t.source] = max(heaviest.get(t.source, 0.0), t.weight)
    for t in sorted(targets, key=lambda t: -t.weight):
        if t.weight < pcfg.rotation.min_relative_weight * heaviest[t.source]:
            continue
        limit = pcfg.high_loss.min_offset_deg if t.source == "high_loss" else pcfg.rotation.min_offset_deg
        if abs(math.degrees(float(wrap_angle(t.yaw - yaw)))) <= limit and abs(math.degrees(t.pitch)) < 20:
            continue
        if any(abs(float(wrap_angle(t.yaw - c.yaw))) < math.radians(20) for c in chosen):
            continue
        chosen.append(t)
        if len(chosen) >= max_views:
            break
    if tilt_within_deg is not None:
        within = math.radians(tilt_within_deg)
        chosen = [dataclasses.replace(t, pitch=math.copysign(max(0.0, abs(t.pitch) - within), t.pitch))
                  for t in chosen]
    chosen.sort(key=lambda t: float(wrap_angle(t.yaw - yaw)) % (2 * math.pi))
    if ctrl is None:
        return chosen
    order = fewest_actions_order(yaw, pitch, [(t.yaw, t.pitch) for t in chosen], ctrl, final_yaw)
    return [chosen[i] for i in order]


__all__ = ["GoalRules", "closer_on_the_way", "distance_to_polyline", "goal_candidates", "last_call_first",
           "local_then_global", "node_state", "node_xz", "open_node", "panorama_candidates", "rank_goals",
           "reachable_first",
           "sampled_surface_term", "select_rotation_targets", "tour_first", "worth_a_detour", "worth_a_visit"]
