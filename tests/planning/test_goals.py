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
from activesplat.planning.config import PlanningConfig  # noqa: E402
from activesplat.planning.explorer_config import ExplorerConfig  # noqa: E402
from activesplat.planning.goals import rank_goals  # noqa: E402
from activesplat.planning.hierarchical import (  # noqa: E402
    local_then_global,
)
from activesplat.planning.on_the_way import (  # noqa: E402
    closer_on_the_way,
    distance_to_polyline,
    worth_a_detour,
)
from activesplat.planning.panorama_scores import panorama_candidates  # noqa: E402
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
