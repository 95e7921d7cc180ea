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
    """Indices best first (sec. III-C). Ties go to the shorter travel. Hierarchical: while an open node of
    the agent's own subregion (`in_local`) promises something to see (information above the local
    threshold), those nodes come first in score order; otherwise every node is ranked by its global score
    (`global_scores`, default `scores`) minus the distance cost, with `global_information_first` the open
    nodes that promise something to see (information above the same threshold; `global_info`, default
    `info`) ahead of the others. Flat (`no-hp`): score order."""
    n = len(scores)
    order = sorted(range(n), key=lambda i: (-scores[i], travel[i]))
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
    base = scores if global_scores is None else global_scores
    if rules.global_halving_m is None:
        global_score = base - rules.global_distance_weight * travel
    else:  # score per way: halved at global_halving_m of travel
        global_score = base / (1.0 + travel / rules.global_halving_m)
    ranked = sorted(range(n), key=lambda i: (-global_score[i], travel[i]))
    if not rules.global_information_first:
        return ranked
    # a node that promises something to see beats one that only has the unvisited / in-horizon flags,
    # however near: the flags alone kept the agent going from node to node of a room it had seen (ours)
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
        pos = np.asarray(plan.graph.nodes[n]["pos"], float)
        unvisited, is_failed = node_state(pos, visited, failed, radius)
        if unvisited and not is_failed:
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
        unvisited, is_failed = node_state(np.asarray(plan.graph.nodes[order[k]]["pos"], float), visited,
                                          failed, radius)
        worth[k] = unvisited and not is_failed
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


def rank_goals(plan: Plan, here: np.ndarray, render: RenderFn, floor_height: float,
               visited: Sequence[np.ndarray], failed: Sequence[np.ndarray], pcfg: PlanningConfig,
               wcfg: WorkspaceConfig, rules: GoalRules, rng: np.random.Generator,
               observed: ObservedSurface | None = None, promises: Promises | None = None,
               commitment: Commitment | None = None, route_memory: RouteMemory | None = None,
               no_path_travel: Callable[[np.ndarray], np.ndarray] | None = None) -> list[int]:
    """Candidate goal nodes of `plan.graph`, best first (eq. 12 scores; local-then-global, sec. III-C).
    Renders a panorama at up to `max_panoramas` open candidates and records every candidate's score and
    information part in `plan.scores` / `plan.info`. `random_goals`: a random order of the open nodes,
    then the others (no scores). With `observed` and a positive `ScoreConfig.w_q`, the information part
    also counts the surface near each node that the agent's depth has not sampled (`planning.observed`).
    With `promises` (hierarchical only) a node outside the agent's subregion promises at least what it
    promised at an earlier replan (`Promises`). With `commitment` a global stage goes on toward the
    subregion chosen at an earlier global replan while it holds something to see (`Commitment`); whether
    it did is `plan.committed`. With `route_memory` the global stage follows a route whose order is kept
    across replans (`RouteMemory`, implies the route of `global_tour`). `no_path_travel` estimates the
    travel to nodes the graph gives no path to (`travel_lengths`)."""
    graph, ws = plan.graph, plan.workspace
    nodes = goal_candidates(graph)
    if not nodes:
        return []
    pos = np.stack([np.asarray(graph.nodes[n]["pos"], float) for n in nodes])
    state = [node_state(p, visited, failed, pcfg.score.unvisited_radius_m) for p in pos]
    unvisited = np.array([s[0] for s in state])
    is_failed = np.array([s[1] for s in state])
    open_ = unvisited & ~is_failed
    dist = np.hypot(*(pos - here).T)
    if rules.random_goals:
        order = rng.permutation(len(nodes))
        return [nodes[i] for i in order if open_[i]] + [nodes[i] for i in order if not open_[i]]
    inv = np.zeros(len(nodes))
    vol = np.zeros(len(nodes))
    poor = np.zeros(len(nodes))
    scored = np.zeros(len(nodes), bool)
    height = floor_height + rules.panorama_height_m
    score_cfg = pcfg.score
    quality = observed is not None and score_cfg.w_q > 0
    for i in panorama_candidates(nodes, dist, open_, plan.subregions, rules.max_panoramas,
                                  rules.panorama_every_subregion):
        pano = render_panorama(render, [pos[i][0], height, pos[i][1]], pcfg.panorama,
                               pcfg.panorama.front_faces_scores, pcfg.panorama.scores_back_face_seen)
        scored[i] = True
        inv[i] = invisible_share(pano, pcfg.rotation)
        vol[i] = hull_volume(pano, pcfg.hull)
        if quality:
            poor[i] = poorly_observed_share(pano, observed, score_cfg.quality_radius_m)
    # the sampled-surface term (ours, off by default; `sampled_surface_term`), with its optional gate
    plan.max_invisible = float(inv.max()) if scored.any() else 0.0
    if quality:
        plan.poor = {n: float(v) for n, v, s in zip(nodes, poor, scored, strict=True) if s}
        gate = score_cfg.quality_below_invisible
        quality = gate is None or plan.max_invisible < gate
    extra = sampled_surface_term(poor, score_cfg) if quality else np.zeros(len(nodes))
    hierarchical = rules.hierarchical and bool(plan.subregions)
    local = agent_subregion(graph, plan.subregions, here) if hierarchical else None
    in_local = np.array([hierarchical and plan.subregions.get(n) == local for n in nodes])
    # the information terms (w_o s_o + w_c s_c, shares relative to the best node anywhere): what keeps
    # planning local, and what makes a node worth a stop on a long path's way
    info = information_scores(inv, vol, score_cfg) + extra
    # a promise kept from an earlier replan adds to the information part and the score alike (0 in the
    # agent's own subregion, so the local stage sees what the panoramas show)
    kept = np.zeros(len(nodes))
    if promises is not None and hierarchical:
        kept = promises.keep(pos, info, scored, in_local | ~unvisited) - info
        info = info + kept
    if hierarchical and not rules.local_in_horizon:  # ranked without the flag in the local stage too (ours)
        in_horizon = np.zeros(len(pos), bool)
    else:
        in_horizon = np.array([line_of_sight(ws, here, p, wcfg) for p in pos])
    scores = node_scores(inv, vol, unvisited, in_horizon, is_failed, score_cfg) + extra + kept
    # the global stage weighs what a node promises against the way there; the in-horizon flag (a node in
    # sight of the agent) is a local preference and, counted there too, keeps the agent near (ours)
    global_scores = None if rules.global_in_horizon else node_scores(
        inv, vol, unvisited, np.zeros_like(in_horizon), is_failed, score_cfg) + extra + kept
    plan.scores = {n: float(s) for n, s in zip(nodes, scores, strict=True)}
    travel = travel_lengths(graph, here, nodes, pos, no_path_travel)
    plan.travel = {n: float(t) for n, t in zip(nodes, travel, strict=True)}
    if hierarchical and rules.local_near_m is not None:  # nodes this near count as local (ours)
        in_local = in_local | (travel <= rules.local_near_m)
    plan.info = {n: float(v) for n, v in zip(nodes, info, strict=True)}
    # with `quality_in_local` off the sampled-surface term does not keep the agent in its subregion: it
    # only makes poorly sampled rooms worth a trip in the global stage
    local_info = info if score_cfg.quality_in_local else info - extra
    rules = dataclasses.replace(rules, hierarchical=hierarchical)
    promising = worth_a_visit(info, open_, rules.local_score_threshold)
    local_promising = worth_a_visit(local_info, open_, rules.local_score_threshold)
    plan.stage = "flat" if not hierarchical else "local" if (local_promising & in_local).any() else "global"
    order = local_then_global(scores, local_info, travel, open_, in_local, rules, global_scores, info)
    if (rules.global_tour or route_memory is not None) and plan.stage == "global":
        stops = promising if route_memory is None else promising & (info > route_memory.min_info)
        order = tour_first(order, stops, travel, nodes, plan.subregions, graph, route_memory,
                           rules.route_in_place)
    plan.committed = False
    if commitment is not None and plan.stage == "global":
        order, plan.committed = commitment.first(order, promising, nodes, pos, plan.subregions)
    return [nodes[i] for i in order]


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
        pos = np.asarray(graph.nodes[node]["pos"], float)
        gap = float(np.hypot(*(pos - goal)))
        unvisited, is_failed = node_state(pos, visited, failed, unvisited_radius)
        if gap <= limit and unvisited and not is_failed:
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
        pos = np.asarray(plan.graph.nodes[node]["pos"], float)
        unvisited, is_failed = node_state(pos, visited, failed, unvisited_radius)
        if not unvisited or is_failed or np.hypot(*(pos - goal)) < 1e-6:
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
        pos = np.asarray(graph.nodes[node]["pos"], float)
        unvisited, is_failed = node_state(pos, visited, failed, unvisited_radius)
        if not unvisited or is_failed:
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
           "local_then_global", "node_state", "panorama_candidates", "rank_goals", "reachable_first",
           "sampled_surface_term", "select_rotation_targets", "tour_first", "worth_a_detour", "worth_a_visit"]
