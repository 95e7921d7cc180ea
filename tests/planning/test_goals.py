"""Goal selection (paper sec. III-B, III-C) on a synthetic corridor: the release's long-path rule, node
information with and without hierarchical planning, local-then-global ordering."""

import dataclasses
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "workspace"))
from layouts import RES, corridor  # noqa: E402

from activesplat.errors import InvalidInputError  # noqa: E402
from activesplat.planning.activesplat import goal_rules  # noqa: E402
from activesplat.planning.config import PlanningConfig, ScoreConfig  # noqa: E402
from activesplat.planning.controller import ControllerConfig, tour_actions  # noqa: E402
from activesplat.planning.explorer_config import ExplorerConfig  # noqa: E402
from activesplat.planning.goals import rank_goals  # noqa: E402
from activesplat.planning.hierarchical import (  # noqa: E402
    last_call_first,
    local_then_global,
    reachable_first,
    tour_first,
)
from activesplat.planning.observed import ObservedSurface  # noqa: E402
from activesplat.planning.on_the_way import (  # noqa: E402
    bridge_toward,
    closer_on_the_way,
    distance_to_polyline,
    worth_a_detour,
)
from activesplat.planning.panorama_scores import panorama_candidates, sampled_surface_term  # noqa: E402
from activesplat.planning.replan_memory import Commitment, Promises, RouteMemory  # noqa: E402
from activesplat.planning.viewpoints import RotationTarget, select_rotation_targets  # noqa: E402
from activesplat.workspace.clean import extract_workspace  # noqa: E402
from activesplat.workspace.config import WorkspaceConfig  # noqa: E402
from activesplat.workspace.paths import plan_safe_path  # noqa: E402
from activesplat.workspace.plan import Plan  # noqa: E402
from activesplat.workspace.voronoi import build_voronoi_graph  # noqa: E402

WCFG = WorkspaceConfig(resolution=RES)
HERE = np.array([1.0, 1.5])
RULES = goal_rules(ExplorerConfig(workspace=WCFG, long_path_m=3.0))
RADIUS = PlanningConfig().score.unvisited_radius_m


def _corridor_plan(mid_info: float) -> tuple[Plan, np.ndarray, np.ndarray]:
    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    pos = {n: np.asarray(d["pos"], float) for n, d in graph.nodes(data=True)}
    far = max(pos, key=lambda n: pos[n][0])
    mid = min(pos, key=lambda n: abs(pos[n][0] - 3.0))
    plan = Plan(workspace=ws, graph=graph, scores={far: 40.0, mid: 20.0 + mid_info},
                info={far: 20.0, mid: mid_info})
    goal = pos[far]
    return plan, goal, plan_safe_path(graph, ws, HERE, goal, WCFG)


def _closer(plan, goal, path, visited=()):
    def find_path(node_pos):
        return plan_safe_path(plan.graph, plan.workspace, HERE, node_pos, WCFG)

    return closer_on_the_way(plan, goal, path, list(visited), [], RADIUS, RULES, find_path)


def test_a_long_path_stops_at_a_worthwhile_node_on_the_way():
    plan, goal, path = _corridor_plan(mid_info=10.0)
    new_goal, new_path = _closer(plan, goal, path)
    assert abs(new_goal[0] - 3.0) < 0.2 and new_path[-1] @ [1, 0] < goal[0] - 1.0


def test_a_long_path_is_kept_when_nothing_on_the_way_is_worth_a_stop():
    for mid_info in (5.0, 0.0):  # no information above the local threshold
        plan, goal, path = _corridor_plan(mid_info)
        new_goal, new_path = _closer(plan, goal, path)
        assert new_goal is goal and new_path is path
    plan, goal, path = _corridor_plan(mid_info=10.0)
    # the node on the way was visited already
    assert _closer(plan, goal, path, visited=[np.array([3.0, 1.5])])[0] is goal


def test_a_goal_cut_off_from_the_agent_is_approached_through_the_nearest_open_node_of_its_own_part():
    plan, goal, _ = _corridor_plan(mid_info=10.0)
    graph = plan.graph
    pos = {n: np.asarray(d["pos"], float) for n, d in graph.nodes(data=True)}
    # the floor around x = 4 m was seen only from afar: the graph is cut there
    graph.remove_edges_from([(a, b) for a, b in list(graph.edges) if min(pos[a][0], pos[b][0]) < 4.0
                             < max(pos[a][0], pos[b][0])])
    near_part = [n for n in graph.nodes if pos[n][0] < 4.0]
    asked = []

    def find_path(node_pos):
        asked.append(node_pos)
        return None if node_pos[0] > 4.0 else np.stack([HERE, node_pos])

    bridge = bridge_toward(plan, HERE, goal, [], [], RADIUS, WCFG, 1.0, find_path)
    assert bridge is not None
    best = max(near_part, key=lambda n: pos[n][0])  # the corridor runs along x: nearest to the goal
    np.testing.assert_allclose(bridge[0], pos[best])
    np.testing.assert_allclose(bridge[1][-1], pos[best])
    assert all(p[0] < 4.0 for p in asked)  # only nodes of the agent's own part are candidates
    # once that node is visited the next one nearer to the goal is taken, never one behind the agent
    second = bridge_toward(plan, HERE, goal, [pos[best]], [], RADIUS, WCFG, 1.0, find_path)
    assert second is not None and second[0][0] < pos[best][0] and second[0][0] > HERE[0] + 1.0
    # nothing at least `gain_m` nearer to the goal than the agent: no bridge
    assert bridge_toward(plan, HERE, goal, [], [], RADIUS, WCFG, 10.0, find_path) is None


def _detour_plan(side_info: float) -> tuple[Plan, int, int]:
    """A corridor along x from the agent at 0 to the goal at 10 m, a side branch at x = 3 m up to a node
    2 m off it (a door), and a node 1 m behind the agent."""
    import networkx as nx

    graph = nx.Graph()
    points = {0: (0.0, 0.0), 1: (3.0, 0.0), 2: (10.0, 0.0), 3: (3.0, 2.0), 4: (-1.0, 0.0)}
    for n, p in points.items():
        graph.add_node(n, pos=np.array(p))
    for a, b in [(0, 1), (1, 2), (1, 3), (0, 4)]:
        graph.add_edge(a, b, weight=float(np.hypot(*np.subtract(points[a], points[b]))))
    plan = Plan(graph=graph, scores={2: 40.0, 3: 10.0 + side_info, 4: 16.0},
                info={2: 30.0, 3: side_info, 4: 6.0}, travel={0: 0.0, 1: 3.0, 2: 10.0, 3: 5.0, 4: 1.0})
    return plan, 2, 3


def test_a_node_worth_a_detour_on_the_way_to_a_global_goal_comes_first():
    plan, goal, side = _detour_plan(side_info=12.0)
    # agent -> side -> goal is 5 + 9 m against 10 m straight: a 4 m detour
    assert worth_a_detour(plan, goal, [], [], RADIUS, 5.0, 10.0) == side
    assert worth_a_detour(plan, goal, [], [], RADIUS, 3.0, 10.0) is None  # too far off the way
    # a node that promises too little (the one behind the agent: 6 < 10) is no reason to stop
    assert worth_a_detour(plan, goal, [], [], RADIUS, 5.0, 13.0) is None
    assert worth_a_detour(plan, goal, [np.array([3.0, 2.0])], [], RADIUS, 5.0, 10.0) is None  # visited
    assert worth_a_detour(plan, goal, [], [np.array([3.0, 2.0])], RADIUS, 5.0, 10.0) is None  # failed
    # the nearest qualifying node wins: the one behind the agent, once it promises enough
    plan.info[4] = 11.0
    assert worth_a_detour(plan, goal, [], [], RADIUS, 5.0, 10.0) == 4


def test_distance_to_polyline():
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    assert distance_to_polyline(np.array([1.0, 0.5]), path) == 0.5
    assert distance_to_polyline(np.array([3.0, 1.0]), path) == 1.0
    assert np.isclose(distance_to_polyline(np.array([-1.0, -1.0]), path), np.sqrt(2))


def test_local_nodes_come_first_while_they_promise_something_then_score_minus_distance():
    scores = np.array([50.0, 30.0, 45.0])
    travel = np.array([9.0, 1.0, 2.0])
    open_ = np.ones(3, bool)
    in_local = np.array([False, True, False])
    info = np.array([20.0, 10.0, 20.0])
    assert local_then_global(scores, info, travel, open_, in_local, RULES) == [1, 0, 2]
    info[1] = RULES.local_score_threshold  # nothing left worth seeing here: global, distance counts
    assert local_then_global(scores, info, travel, open_, in_local, RULES) == [2, 0, 1]
    flat = dataclasses.replace(RULES, hierarchical=False)
    assert local_then_global(scores, info, travel, open_, in_local, flat) == [0, 2, 1]
    # the global stage may rank by other scores (without the in-horizon flag): node 0 is far but promises
    # more once the near node 2 loses its in-sight bonus of 10
    assert local_then_global(scores, info, travel, open_, in_local, RULES,
                             global_scores=scores - np.array([0.0, 0.0, 10.0])) == [0, 2, 1]


def test_global_stage_with_information_first_prefers_a_far_node_with_something_to_see():
    # the agent's subregion is seen; node 0 is near with only the unvisited and in-horizon flags (20),
    # node 1 is 23 m away behind a door with unseen space (info 30), node 2 is near but visited
    scores = np.array([20.0, 40.0, 30.0])
    info = np.array([0.0, 30.0, 30.0])
    travel = np.array([1.5, 23.0, 1.0])
    open_ = np.array([True, True, False])
    in_local = np.array([True, False, True])
    plain = dataclasses.replace(RULES, global_information_first=False)
    assert local_then_global(scores, info, travel, open_, in_local, plain) == [2, 0, 1]
    first = dataclasses.replace(RULES, global_information_first=True)
    assert local_then_global(scores, info, travel, open_, in_local, first) == [1, 2, 0]
    info[1] = RULES.local_score_threshold  # nothing promising anywhere: score minus distance as before
    assert local_then_global(scores, info, travel, open_, in_local, first) == [2, 0, 1]


def test_global_halving_ranks_score_per_way_whatever_the_scale_of_the_scores():
    # node 0 promises twice what node 1 does but lies 25 m away against 2 m; nothing local is left
    info = np.array([30.0, 15.0])
    travel = np.array([25.0, 2.0])
    open_ = np.ones(2, bool)
    in_local = np.zeros(2, bool)
    halving = dataclasses.replace(RULES, global_halving_m=5.0)
    for scale in (1.0, 3.0):  # the difference rule flips with the scale of the scores, the ratio does not
        scores = scale * np.array([40.0, 20.0])
        linear = local_then_global(scores, scale * info, travel, open_, in_local, RULES)
        assert linear == ([1, 0] if scale == 1.0 else [0, 1])
        assert local_then_global(scores, scale * info, travel, open_, in_local, halving) == [1, 0]
    # a far node wins once it promises more than its travel costs: 40 / (1 + 5 / 5) = 20 > 20 / 1.4
    assert local_then_global(np.array([40.0, 20.0]), info, np.array([5.0, 2.0]), open_, in_local,
                             halving) == [0, 1]


def _corridor():
    """A corridor graph: nodes every metre at x = -3..4; candidates (indices 0-4) are nodes 0, 4, 5, 6, 7;
    subregion A holds x = -3 (with a promising node), B holds x = 1, 2 (both promising), C holds x = 4;
    x = 3 promises nothing. Ranked by score minus distance from x = 0: node 5 (B) first, node 0 late."""
    import networkx as nx

    graph = nx.Graph()
    for n, x in enumerate([-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0, 4.0]):
        graph.add_node(n, pos=(x, 0.0))
        if n:
            graph.add_edge(n - 1, n, weight=1.0)
    subregions = {0: "A", 1: "A", 2: "A", 3: "A", 4: "B", 5: "B", 6: "C", 7: "C"}
    return graph, [0, 4, 5, 6, 7], subregions, np.array([True, True, True, False, True]), [2, 1, 4, 0, 3]


def test_tour_first_orders_one_node_per_subregion_along_the_route():
    graph, nodes, subregions, worth, ranked = _corridor()  # the agent at x = 0
    travel = np.array([3.0, 1.0, 2.0, 3.0, 4.0])
    order = tour_first(ranked, worth, travel, nodes, subregions, graph)
    # A (x = -3) first, then B (represented by its first-ranked node, index 2), then C; the rest after
    assert order == [0, 2, 4, 1, 3]
    # one subregion with something to see: the ranking stands
    assert tour_first(ranked, np.array([False, True, True, False, False]), travel, nodes, subregions,
                      graph) == ranked


def test_a_route_in_place_reorders_only_the_stops_and_leaves_a_near_node_first():
    graph, nodes, subregions, _, ranked = _corridor()  # the agent at x = 0
    travel = np.array([3.0, 1.0, 2.0, 3.0, 4.0])
    # only A (x = -3) and C (x = 4) are stops; B's node at x = 2 is ranked first but promises too little
    stops = np.array([True, False, False, False, True])
    # the route goes to A first (3 + 7 m against 4 + 7 m); by default both stops go ahead of everything
    assert tour_first(ranked, stops, travel, nodes, subregions, graph) == [0, 4, 2, 1, 3]
    # in place, A and C swap slots in the ranking, and B's near node keeps the lead
    assert tour_first(ranked, stops, travel, nodes, subregions, graph, in_place=True) == [2, 1, 0, 4, 3]
    # every subregion a stop: the route's order fills the slots of the representatives (B at index 2 in
    # the first slot, C at 4 in the third, A at 0 in the fourth) and B's second node stays second
    worth = np.array([True, True, True, False, True])
    assert tour_first(ranked, worth, travel, nodes, subregions, graph, in_place=True) == [0, 1, 2, 4, 3]


def test_a_remembered_route_keeps_its_order_and_inserts_new_stops_where_they_cost_least():
    memory = RouteMemory(radius=1.5)
    assert memory.follow(np.zeros((2, 2)), np.ones(2), np.ones((2, 2))) is None  # nothing remembered
    # the corridor, agent at x = 0: the shortest route goes west (A at x = -3) first
    graph, nodes, subregions, worth, ranked = _corridor()
    order = tour_first(ranked, worth, np.array([3.0, 1.0, 2.0, 3.0, 4.0]), nodes, subregions, graph, memory)
    assert order[:3] == [0, 2, 4]
    np.testing.assert_allclose(memory.stops, [[-3.0, 0.0], [2.0, 0.0], [4.0, 0.0]])
    # the agent moved to x = 2.5: a new route would go east first (C, B, A); the memory keeps A first
    travel = np.abs(np.array([-3.0, 1.0, 2.0, 3.0, 4.0]) - 2.5)
    again = tour_first(ranked, worth, travel, nodes, subregions, graph, memory)
    assert again[:3] == [0, 2, 4]
    assert tour_first(ranked, worth, travel, nodes, subregions, graph)[:3] == [4, 2, 0]
    # the agent back at x = 0, A done (no candidate there), B now stood for by x = 1 (within the radius of
    # its remembered stop), a new subregion D at x = -1: D goes where it lengthens the route least, before
    # B (D, B, C: 1 + 2 + 3 m; B, D, C: 1 + 2 + 5 m), and B, C keep their order
    nodes2 = [2, 4, 5, 7]
    subregions2 = {0: "A", 1: "A", 2: "D", 3: "A", 4: "B", 5: "B", 6: "C", 7: "C"}
    order2 = tour_first([1, 2, 0, 3], np.array([True, True, True, True]), np.array([1.0, 1.0, 2.0, 4.0]),
                        nodes2, subregions2, graph, memory)
    assert order2[:3] == [0, 1, 3]
    np.testing.assert_allclose(memory.stops, [[-1.0, 0.0], [1.0, 0.0], [4.0, 0.0]])


class HalfSeen:
    """A map whose every view has its lower half mapped: an invisible share at every node."""

    def render(self, pose, K=None, width=None, height=None):
        alpha = np.zeros((height, width), np.float32)
        alpha[height // 2:] = 1.0
        return SimpleNamespace(alpha=alpha, median_depth=np.full((height, width), 2.0, np.float32))


def test_every_subregion_gets_a_panorama_however_far_and_the_nearest_nodes_come_on_top():
    # ten nodes on a line, two per subregion, the agent at x = 0; node 3 is visited (not open)
    nodes = list(range(10))
    dist = np.arange(10, dtype=float)
    open_ = np.ones(10, bool)
    open_[3] = False
    subregions = {n: n // 2 for n in nodes}
    both = panorama_candidates(nodes, dist, open_, subregions, max_panoramas=2)
    # one per subregion (the nearest open node of each: 0, 2, 4, 6, 8), then the 2 nearest open nodes
    # not yet chosen among the 2 nearest (0 and 1: only 1 is new)
    assert both == [0, 2, 4, 6, 8, 1]
    capped = panorama_candidates(nodes, dist, open_, subregions, max_panoramas=2, every_subregion=False)
    assert capped == [0, 2]  # the old rule: the far subregions get no panorama
    assert 3 not in panorama_candidates(nodes, dist, open_, subregions, max_panoramas=10)


def test_node_information_is_scored_with_and_without_hierarchical_planning():
    """The long-path rule reads `plan.info`: `no-hp` (hierarchical off) must fill it too."""
    for hierarchical in (True, False):
        cfg = ExplorerConfig(workspace=WCFG, hierarchical=hierarchical)
        ws = extract_workspace(corridor(), HERE, WCFG)
        plan = Plan(workspace=ws, graph=build_voronoi_graph(ws, WCFG))
        ranked = rank_goals(plan, HERE, HalfSeen().render, 0.0, [], [], cfg.planning, WCFG, goal_rules(cfg),
                            np.random.default_rng(0))
        assert ranked and set(plan.info) == set(plan.scores)
        assert max(plan.info.values()) > cfg.local_score_threshold


def test_the_sampled_surface_term_adds_to_the_information_of_the_scored_nodes_only_when_asked():
    base = ExplorerConfig(workspace=WCFG)
    with_q = dataclasses.replace(base, planning=dataclasses.replace(
        base.planning, score=dataclasses.replace(base.planning.score, w_q=20.0)))
    infos = []
    for cfg, observed in ((base, None), (with_q, None), (with_q, ObservedSurface())):
        ws = extract_workspace(corridor(), HERE, WCFG)
        plan = Plan(workspace=ws, graph=build_voronoi_graph(ws, WCFG))
        rank_goals(plan, HERE, HalfSeen().render, 0.0, [], [], cfg.planning, WCFG, goal_rules(cfg),
                   np.random.default_rng(0), observed)
        infos.append(plan.info)
    plain, no_memory, sampled = infos
    assert no_memory == plain  # the weight alone does nothing without the agent's sampled surface
    # nothing sampled yet: every panorama shows the same unsampled surface within reach, so each scored
    # node (information above 0) gains the full weight and the others nothing
    for node, info in plain.items():
        assert sampled[node] == (info + 20.0 if info > 0 else info)


def test_the_sampled_surface_term_waits_until_little_unseen_space_is_left_when_gated():
    base = ExplorerConfig(workspace=WCFG)
    infos, largest = [], []
    for gate in (None, 1e-6, 1.0):
        score = dataclasses.replace(base.planning.score, w_q=20.0, quality_below_invisible=gate)
        cfg = dataclasses.replace(base, planning=dataclasses.replace(base.planning, score=score))
        ws = extract_workspace(corridor(), HERE, WCFG)
        plan = Plan(workspace=ws, graph=build_voronoi_graph(ws, WCFG))
        rank_goals(plan, HERE, HalfSeen().render, 0.0, [], [], cfg.planning, WCFG, goal_rules(cfg),
                   np.random.default_rng(0), ObservedSurface())
        infos.append(plan.info)
        largest.append(plan.max_invisible)
        assert plan.poor  # the shares are recorded whether or not the term counts
    ungated, closed, open_ = infos
    assert 0.0 < largest[0] < 1.0 and largest[0] == largest[1] == largest[2]
    assert open_ == ungated  # the panoramas show less unseen space than the gate: the term counts
    assert closed != ungated and all(closed[n] <= ungated[n] for n in closed)  # eq. 12 alone


def test_the_sampled_surface_term_on_an_absolute_scale_promises_little_where_little_is_unsampled():
    shares = np.array([0.0, 0.02, 0.1, 0.4])
    # relative (the default): the largest share always promises the full weight, however small it is
    relative = sampled_surface_term(shares * 0.1, ScoreConfig(w_q=10.0))
    assert relative.tolist() == pytest.approx([0, 0.5, 2.5, 10])
    absolute = ScoreConfig(w_q=10.0, quality_reference=0.2)
    # capped at w_q
    assert sampled_surface_term(shares, absolute).tolist() == pytest.approx([0, 1.0, 5.0, 10.0])
    assert sampled_surface_term(shares * 0.1, absolute).max() == pytest.approx(2.0)  # a tenth: a fifth
    assert sampled_surface_term(np.zeros(0), ScoreConfig(w_q=10.0)).size == 0
    with pytest.raises(InvalidInputError, match="quality_reference"):
        ScoreConfig(quality_reference=0.0)


def test_a_node_keeps_its_promise_until_its_subregion_is_entered_or_it_is_visited():
    promises = Promises(radius=0.5)
    pos = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    none, all_ = np.zeros(3, bool), np.ones(3, bool)
    first = promises.keep(pos, np.array([12.0, 30.0, 3.0]), all_, none)
    assert first.tolist() == [12.0, 30.0, 3.0]  # nothing remembered yet
    # the graph moved a little; the door view lowered node 0, node 1 got no panorama (information 0)
    moved = pos + [0.3, 0.0]
    scored = np.array([True, False, True])
    again = promises.keep(moved, np.array([6.0, 0.0, 8.0]), scored, none)
    assert again.tolist() == [12.0, 30.0, 8.0]  # the higher of now and then
    # node 0's subregion entered (released): the panorama rules and its memory is gone
    entered = promises.keep(moved, np.array([6.0, 0.0, 4.0]), scored, np.array([True, False, False]))
    assert entered.tolist() == [6.0, 30.0, 8.0]
    assert promises.keep(moved, np.array([2.0, 0.0, 4.0]), all_, none).tolist() == [2.0, 30.0, 8.0]
    far = promises.keep(moved + 1.0, np.zeros(3), none, none)  # beyond the radius nothing is kept
    assert far.tolist() == [0.0, 0.0, 0.0]


def test_a_global_choice_is_followed_until_its_subregion_holds_nothing_to_see():
    nodes = [10, 11, 12, 13]
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [8.0, 0.0], [9.0, 0.0]])
    regions = {10: 0, 11: 0, 12: 1, 13: 1}
    order = [2, 3, 0, 1]  # this replan prefers the other side of the house
    worth = np.array([True, True, True, True])
    commitment = Commitment(radius=0.5)
    assert commitment.first(order, worth, nodes, pos, regions) == (order, False)  # nothing committed yet
    commitment.pos = np.array([0.2, 0.1])  # the last global goal, near node 10 (the graph moved a little)
    assert commitment.first(order, worth, nodes, pos, regions) == ([0, 2, 3, 1], True)
    # node 10 seen: the subregion's other node worth a visit is next
    assert commitment.first(order, np.array([False, True, True, True]), nodes, pos, regions) == (
        [1, 2, 3, 0], True)
    # nothing of the subregion worth a visit any more: the replan's own order, and the commitment is gone
    seen = np.array([False, False, True, True])
    assert commitment.first(order, seen, nodes, pos, regions) == (order, False)
    assert commitment.pos is None
    commitment.pos = np.array([4.5, 0.0])  # no candidate near the remembered goal: dropped as well
    assert commitment.first(order, worth, nodes, pos, regions) == (order, False) and commitment.pos is None
    with pytest.raises(InvalidInputError, match="commit_global_m"):
        ExplorerConfig(commit_global_m=-1.0)


def test_nodes_near_the_agent_join_the_local_stage_whatever_their_subregion_only_when_asked():
    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    pos = {n: np.asarray(graph.nodes[n]["pos"], float) for n in graph.nodes}
    own = min(pos, key=lambda n: np.hypot(*(pos[n] - HERE)))
    stages = []
    for near in (None, 3.0, 5.0):  # the corridor's far end is 4 m along the graph
        cfg = ExplorerConfig(workspace=WCFG, local_near_m=near)
        plan = Plan(workspace=ws, graph=graph)
        # the far end in a subregion of its own; the agent's holds only the node it stands on (visited)
        plan.subregions = {n: 0 if n == own else 1 for n in graph.nodes}
        ranked = rank_goals(plan, HERE, HalfSeen().render, 0.0, [pos[own]], [], cfg.planning, WCFG,
                            goal_rules(cfg), np.random.default_rng(0))
        stages.append(plan.stage)
        assert ranked[0] != own and 3.0 < plan.travel[ranked[0]] < 5.0
    assert stages == ["global", "global", "local"]
    with pytest.raises(InvalidInputError, match="local_near_m"):
        ExplorerConfig(local_near_m=0.0)


def test_the_in_horizon_flag_counts_in_the_local_stage_unless_asked_and_always_without_hierarchy():
    """`local_in_horizon` False: eq. 12's in-horizon flag is left out of the scores the local stage ranks
    by (it is already out of the global stage's); the flat `no-hp` ranking keeps the paper's score. Down a
    straight corridor every node is in sight and none is visited."""
    ws = extract_workspace(corridor(), HERE, WCFG)
    score_cfg = PlanningConfig().score
    cases = ((True, True, 20.0), (True, False, 10.0), (False, False, 20.0))
    for hierarchical, local_in_horizon, flags in cases:
        cfg = ExplorerConfig(workspace=WCFG, hierarchical=hierarchical, local_in_horizon=local_in_horizon)
        plan = Plan(workspace=ws, graph=build_voronoi_graph(ws, WCFG))
        plan.subregions = {n: 0 for n in plan.graph.nodes}  # one subregion: the local stage
        rank_goals(plan, HERE, HalfSeen().render, 0.0, [], [], cfg.planning, WCFG, goal_rules(cfg),
                   np.random.default_rng(0))
        assert (plan.stage == "local") == hierarchical
        assert score_cfg.w_u + score_cfg.w_h == 20.0
        for n, score in plan.scores.items():
            assert score == pytest.approx(plan.info[n] + flags), (hierarchical, local_in_horizon, n)


def test_rank_goals_applies_kept_promises_outside_the_agents_subregion_only():
    cfg = ExplorerConfig(workspace=WCFG, keep_promise_m=0.3)
    ws = extract_workspace(corridor(), HERE, WCFG)
    plan = Plan(workspace=ws, graph=build_voronoi_graph(ws, WCFG))
    plan.subregions = {n: int(plan.graph.nodes[n]["pos"][0] > 3.0) for n in plan.graph.nodes}
    nodes = list(plan.graph.nodes)
    pos = np.stack([np.asarray(plan.graph.nodes[n]["pos"], float) for n in nodes])
    promises = Promises(0.3, pos, np.full(len(nodes), 100.0))
    rank_goals(plan, HERE, HalfSeen().render, 0.0, [], [], cfg.planning, WCFG, goal_rules(cfg),
               np.random.default_rng(0), promises=promises)
    here_region = plan.subregions[min(nodes, key=lambda n: np.hypot(*(pos[nodes.index(n)] - HERE)))]
    outside = {plan.subregions[n] != here_region for n in plan.info}
    assert outside == {True, False}  # candidates on both sides
    for n, info in plan.info.items():
        assert (info == 100.0) == (plan.subregions[n] != here_region), (n, info)
    with pytest.raises(InvalidInputError, match="keep_promise_m"):
        ExplorerConfig(keep_promise_m=0.0)


def test_rotation_targets_tilt_only_until_the_target_is_within_the_given_angle_of_the_centre():
    targets = [RotationTarget(np.radians(90), np.radians(-60), 50.0),   # floor close by: tilt to -30
               RotationTarget(np.radians(-90), np.radians(-25), 40.0),  # in the level view: no tilt
               RotationTarget(np.radians(180), np.radians(50), 30.0, "high_loss")]  # up: to +20
    ctrl, pcfg = ControllerConfig(), PlanningConfig()
    plain = select_rotation_targets(targets, 0.0, pcfg, 5, 0.0, ctrl)
    near = select_rotation_targets(targets, 0.0, pcfg, 5, 0.0, ctrl, tilt_within_deg=30.0)
    assert sorted(np.degrees([t.pitch for t in near]).round(1)) == [-30.0, 0.0, 20.0]
    assert sorted(t.yaw for t in near) == sorted(t.yaw for t in plain)  # the same directions
    cost = [tour_actions(0.0, 0.0, [(t.yaw, t.pitch) for t in ts], ctrl) for ts in (plain, near)]
    assert cost[1] < cost[0]
    with pytest.raises(InvalidInputError, match="tilt_within_deg"):
        ExplorerConfig(tilt_within_deg=120.0)


def test_rotation_targets_lighter_than_a_share_of_their_sources_heaviest_are_skipped():
    targets = [RotationTarget(np.radians(90), 0.0, 4000.0),   # a wall of unseen surface
               RotationTarget(np.radians(-90), 0.0, 30.0),    # a patch beside it: 0.75 % of it
               RotationTarget(np.radians(180), 0.0, 400.0),   # 10 %
               RotationTarget(np.radians(-150), 0.0, 2.0, "high_loss")]  # the only high-loss target stays
    pcfg = PlanningConfig()
    every = select_rotation_targets(targets, 0.0, pcfg, 5)
    assert len(every) == 4  # off by default (paper and release)
    share = dataclasses.replace(pcfg, rotation=dataclasses.replace(pcfg.rotation, min_relative_weight=0.05))
    kept = select_rotation_targets(targets, 0.0, share, 5)
    assert sorted(t.weight for t in kept) == [2.0, 400.0, 4000.0]
    with pytest.raises(InvalidInputError, match="min_relative_weight"):
        dataclasses.replace(pcfg.rotation, min_relative_weight=1.5)


def _plan_on_a_line(nodes: dict[str, tuple[float, float]]) -> tuple[Plan, list[int]]:
    """A plan whose node k sits at (k, 0) with the (information part, travel m) of the k-th entry; and the
    ranking order 0, 1, ..."""
    plan = Plan()
    for k, (info, travel) in enumerate(nodes.values()):
        plan.graph.add_node(k, pos=np.array([float(k), 0.0]))
        plan.info[k], plan.travel[k] = info, travel
    return plan, list(range(len(nodes)))


def test_a_node_on_its_last_call_goes_first_and_only_then():
    # nodes by (information, travel m): with 20 actions per metre, a node is on its last call when walking
    # there leaves between 60 and 300 of the steps left; the one that promises most goes first
    nodes = {"near": (28.0, 2.0), "far": (25.0, 12.0), "farther": (22.0, 21.0), "farthest": (30.0, 24.5),
             "little": (15.0, 12.0), "visited": (29.0, 12.0), "failed": (29.5, 13.0)}
    plan, order = _plan_on_a_line(nodes)
    visited, failed = [np.array([5.0, 0.2])], [np.array([6.0, 0.0])]

    def first(steps_left):
        ranked = last_call_first(order, plan, steps_left, visited, failed, 0.65, window=300, min_info=20.0,
                                 steps_per_m=20.0)
        assert sorted(ranked) == order
        return list(nodes)[ranked[0]]

    assert first(1000) == "near"  # nothing on its last call yet: the order as it was
    assert first(600) == "farthest"  # 24.5 m leaves 110 and it promises most; 12 m would leave 360
    assert first(500) == "far"  # 24.5 m would leave 10; 12 m leaves 260, 21 m 80, and 12 m promises more
    assert first(250) == "near"  # 12 m would leave 10; 2 m leaves 210


def test_a_goal_the_steps_left_cannot_reach_goes_behind_those_they_can():
    # (information, travel m) in ranking order; 20 actions per metre; the local-score threshold 5
    nodes = {"far": (30.0, 20.0), "visited": (29.0, 3.0), "mid": (18.0, 9.0), "near": (8.0, 2.0),
             "nothing": (2.0, 1.0), "failed": (25.0, 4.0)}
    plan, order = _plan_on_a_line(nodes)
    visited, failed = [np.array([1.0, 0.2])], [np.array([5.0, 0.0])]

    def ranked(steps_left):
        out = reachable_first(order, plan, steps_left, visited, failed, 0.65, steps_per_m=20.0, threshold=5.0)
        assert sorted(out) == order
        return [list(nodes)[k] for k in out]

    assert ranked(400) == list(nodes)  # everything within reach: the order as it was
    # 20 m needs 400 actions: behind the open nodes that promise something and are within reach, in order
    assert ranked(399) == ["mid", "near", "far", "visited", "nothing", "failed"]
    assert ranked(100) == ["near", "far", "visited", "mid", "nothing", "failed"]  # 9 m needs 180
    # nothing that promises something is within reach (a visited or failed node does not count, nor one
    # that promises nothing): the order as it was
    assert ranked(30) == list(nodes)
