"""The explorer through its public behaviour: the actions `act` returns (bootstrap, goals, escapes), the
path-ahead check, and turn counts that follow the action sizes."""

import dataclasses
import sys
from pathlib import Path
from types import SimpleNamespace

import networkx as nx
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "workspace"))
from layouts import RES, corridor, corridor_with_a_slot, two_rooms_seen_at_a_slant  # noqa: E402

import activesplat.planning.activesplat as explorer_module  # noqa: E402
from activesplat.errors import InvalidInputError  # noqa: E402
from activesplat.geometry import camera_pose, pose_yaw_pitch, wrap_angle  # noqa: E402
from activesplat.planning.activesplat import ActiveSplatExplorer  # noqa: E402
from activesplat.planning.controller import ControllerConfig, PathFollower  # noqa: E402
from activesplat.planning.explorer import retrace_actions  # noqa: E402
from activesplat.planning.explorer_config import ExplorerConfig  # noqa: E402
from activesplat.workspace.clean import empty_workspace, extract_workspace  # noqa: E402
from activesplat.workspace.config import WorkspaceConfig  # noqa: E402
from activesplat.workspace.paths import line_of_sight, path_ahead_clear  # noqa: E402
from activesplat.workspace.plan import Plan  # noqa: E402
from activesplat.workspace.voronoi import build_voronoi_graph  # noqa: E402

WCFG = WorkspaceConfig(resolution=RES)
HERE = np.array([1.0, 1.5])
OBSERVED_ONLY = {"neck_margin_m": None}  # paths on observed floor only (the release)
WORLD = SimpleNamespace(gaussians=None, high_loss_mask=None, render=None)


def _obs(xz, yaw=0.0, collided=False):
    return SimpleNamespace(pose=camera_pose([xz[0], 1.25, xz[1]], yaw), collided=collided, step=0)


def _after_bootstrap(ex, obs) -> None:
    n = 0
    while ex.queue:
        ex.act(obs)
        n += 1
    assert n == 72


def test_the_bootstrap_and_the_escape_turn_by_the_action_sizes():
    for turn_deg, look_deg, turns, tilts in ((10.0, 15.0, 36, 3), (30.0, 15.0, 12, 3), (10.0, 45.0, 36, 1)):
        ctrl = ControllerConfig(turn_deg=turn_deg, look_deg=look_deg)
        cfg = ExplorerConfig(workspace=WCFG, controller=ctrl)
        ex = ActiveSplatExplorer(WORLD, 0.0, cfg)
        actions = [ex.act(_obs(HERE)) for _ in range(2 * turns)]
        assert actions[0::2] == ["turn_left"] * turns
        assert actions[1::2][: 2 * tilts] == ["look_down"] * tilts + ["look_up"] * tilts
        assert ex.dense_mapping
        # a refused forward move: turns toward the clearest heading (at most half a circle), then 3 steps
        ex.plan = Plan(workspace=extract_workspace(corridor(), HERE, WCFG))
        escape = [ex.act(_obs(HERE, collided=True))]
        while ex.queue:
            escape.append(ex.act(_obs(HERE)))
        turn = escape[: escape.index("move_forward")]
        assert turn and len(set(turn)) == 1 and len(turn) <= turns // 2
        assert escape[len(turn):] == ["move_forward"] * 3


def test_an_escape_does_not_retry_a_heading_the_scene_refused_from_the_same_spot():
    # the map shows a free corridor, the scene refuses every forward move but one heading (a thing the map
    # does not have): each escape tries a new heading until the free one, instead of cycling
    cfg = ExplorerConfig(workspace=WCFG)
    ex = ActiveSplatExplorer(WORLD, 0.0, cfg)
    ex.queue, ex.queue_causes = [], []
    ex.plan = Plan(workspace=extract_workspace(corridor(), HERE, WCFG))
    free_yaw = np.radians(-170.0)
    yaw, collided, tried = 0.0, True, []
    for _ in range(400):
        action = ex.act(_obs(HERE, yaw, collided=collided))
        collided = False
        if action in ("turn_left", "turn_right"):
            yaw += np.radians(10.0) * (1 if action == "turn_left" else -1)
        elif action == "move_forward":
            heading = pose_yaw_pitch(_obs(HERE, yaw).pose)[0]
            tried.append(round(float(np.degrees(heading))) % 360)
            if abs(np.degrees(wrap_angle(heading - free_yaw))) < 5:
                break  # the free heading: the agent gets out
            collided = True
    assert tried and abs((tried[-1] - 190) % 360) < 5, tried
    assert len(tried) == len(set(tried))  # no refused heading tried twice
    assert len(tried) <= 36


def test_the_path_ahead_is_blocked_only_where_it_gets_narrower_than_the_agent_and_than_here():
    ws = extract_workspace(corridor(), HERE, WCFG)

    def clear(here, target, tolerance=0.05):
        return path_ahead_clear(ws, np.array(here), np.array(target), 0.65, tolerance, WCFG)

    assert not clear([2.0, 1.5], [2.0, 1.02])  # from the corridor's middle toward its wall
    assert clear([2.0, 1.5], [3.5, 1.5])  # along the middle
    # standing closer to the wall than the agent radius (thin polished workspace), a way out is clear
    assert ws.clearance_at(np.array([2.0, 1.06])) < WCFG.agent_radius
    assert clear([2.0, 1.06], [2.6, 1.5])
    # beside a wall the checked segment starts off the planned one and clearance is quantised to cells: a
    # dip of less than the tolerance below the agent radius passes, a heading into the wall does not
    here, graze = np.array([2.0, 1.5]), np.array([2.3, 1.06])
    dip = float(ws.segments_clearance(here[None], graze[None])[0])
    assert WCFG.agent_radius - 0.05 <= dip < WCFG.agent_radius
    assert clear(here, graze) and not clear(here, graze, tolerance=0.0)
    assert not clear(here, [2.3, 1.0])
    assert path_ahead_clear(None, here, graze, 0.65, 0.0, WCFG)


def test_the_path_ahead_keeps_to_the_planned_segment_from_within_the_arrival_radius_of_a_waypoint():
    # a planned segment along the wall (its ends closer to the wall than the agent radius: the planner
    # relaxes its bound to their clearance); the agent reached its start 8 cm off it, toward the middle.
    # From there the line to the segment's end is as narrow as the segment, below the bound from here:
    # without the segment's start the check refused the path at its first step (FBE from tight corners);
    # with it, the planned segment is checked with the planner's bound
    ws = extract_workspace(corridor(), HERE, WCFG)
    start, end, here = np.array([2.0, 1.02]), np.array([3.0, 1.02]), np.array([2.0, 1.1])
    assert line_of_sight(ws, start, end, WCFG)
    assert np.hypot(*(here - start)) <= ControllerConfig().arrive_radius
    assert not path_ahead_clear(ws, here, end, 0.65, 0.05, WCFG)
    assert path_ahead_clear(ws, here, end, 0.65, 0.05, WCFG, segment_start=start)
    # the relaxation never lets a segment leave the workspace
    assert not path_ahead_clear(ws, here, np.array([3.0, 0.9]), 0.65, 0.05, WCFG, segment_start=start)


def test_the_follower_remembers_the_waypoint_it_reached_last():
    follower = PathFollower(np.array([[0.0, 0.0], [0.0, 1.0]]))
    assert follower.passed is None
    assert follower.next_action(_obs([0.0, 0.0]).pose) is not None
    np.testing.assert_allclose(follower.passed, [0.0, 0.0])


def test_an_agent_whose_goals_all_failed_escapes_before_looking_around():
    ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG))
    ex.plan = Plan(workspace=extract_workspace(corridor(), HERE, WCFG))
    pose = _obs([2.0, 1.2]).pose
    ex.queue.clear()
    ex.idle(pose, stuck=False)
    assert ex.queue == ["turn_left"] * 6
    ex.queue.clear()
    ex.idle(pose, stuck=True)
    assert ex.queue[-6:] == ["turn_left"] * 6 and "move_forward" in ex.queue


def test_a_goal_the_agent_stands_on_is_skipped(monkeypatch):
    """Arriving at once would replan at once: the explorer must go to the next goal instead of spinning."""
    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    pos = {n: np.asarray(d["pos"], float) for n, d in graph.nodes(data=True)}
    near = min(pos, key=lambda n: np.hypot(*(pos[n] - HERE)))
    far = max(pos, key=lambda n: pos[n][0])
    monkeypatch.setattr(explorer_module, "build_plan", lambda *a, **k: Plan(workspace=ws, graph=graph))
    monkeypatch.setattr(explorer_module, "rank_goals", lambda *a, **k: [near, far])
    ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG))
    obs = _obs(pos[near])  # standing on the best-ranked node
    _after_bootstrap(ex, obs)
    action = ex.act(obs)
    assert np.allclose(ex.plan.goal, pos[far]) and action in ("turn_left", "turn_right", "move_forward")
    assert not ex.dense_mapping  # travelling


def test_a_multi_connected_stop_takes_its_own_view_budget_and_is_counted_as_such(monkeypatch):
    import networkx as nx

    from activesplat.planning.viewpoints import RotationTarget

    graph = nx.Graph()
    graph.add_node(0, pos=(2.0, 1.2), multi=True)
    budgets = []

    def targets(pose, max_views):
        budgets.append(max_views)
        return [RotationTarget(yaw=1.5, pitch=0.0, weight=1.0, source="panorama")][:max_views]

    ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, multi_stop_views=1,
                                                        max_rotation_views=4))
    ex.plan = Plan(graph=graph)
    monkeypatch.setattr(ex, "_rotation_targets", targets)
    assert ex.stop_on_the_way(_obs([2.1, 1.2]).pose) and budgets == [1]
    assert ex.rotation_cause == "multi_stop"
    assert not ex.stop_on_the_way(_obs([2.1, 1.2]).pose)  # one stop per node
    ex.arrive(_obs([5.0, 1.2]).pose)
    assert budgets == [1, 4] and ex.rotation_cause == "arrival"
    ex.queue.clear(), ex.queue_causes.clear()
    ex.act(_obs([5.0, 1.2]))
    assert ex.last_cause == "arrival"  # a turn toward the arrival target


def test_high_loss_samples_come_only_from_a_mask_of_the_frame_itself(monkeypatch):
    """The mapper maps every n-th frame; an older frame's mask must not be paired with a newer pose."""
    calls = []
    ex = ActiveSplatExplorer(SimpleNamespace(gaussians=None, high_loss_mask=None, render=None), 0.0,
                             ExplorerConfig(workspace=WCFG))
    monkeypatch.setattr(ex.high_loss, "update", lambda *a: calls.append("update"))
    monkeypatch.setattr(ex.high_loss, "observe", lambda pose: calls.append("observe"))
    obs = SimpleNamespace(**vars(_obs(HERE)), depth=np.ones((4, 4)))
    ex.observe_mapping(obs, np.eye(3))
    ex.world.high_loss_mask = np.zeros((4, 4), bool)
    ex.observe_mapping(obs, np.eye(3))
    assert calls == ["observe", "update"]


def test_multi_connected_stops_keep_their_spacing_from_every_rotation_spot_and_the_start(monkeypatch):
    import networkx as nx

    from activesplat.planning.viewpoints import RotationTarget

    graph = nx.Graph()
    for i, x in enumerate((1.3, 2.1, 2.9)):
        graph.add_node(i, pos=(x, 1.5), multi=True)
    target = [RotationTarget(yaw=1.5, pitch=0.0, weight=1.0, source="panorama")]
    for spacing, stops in ((0.0, [True, True, True]), (1.0, [False, True, False])):
        ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, multi_stop_spacing_m=spacing))
        ex.plan = Plan(graph=graph)
        monkeypatch.setattr(ex, "_rotation_targets", lambda pose, n: list(target))
        ex.visited.append(HERE)  # the start (1.0, 1.5): the bootstrap looked around there
        got = []
        for x in (1.3, 2.1, 2.9):  # 0.3 m from the start, 1.1 m from it, 0.8 m past the stop at 2.1
            got.append(ex.stop_on_the_way(_obs([x, 1.5]).pose))
            ex.rotation_targets = []
        assert got == stops, spacing


def test_a_goal_with_no_path_is_skipped_for_the_replan_or_marked_failed_and_logged(monkeypatch):
    """stops.json's "failures" say which goals were skipped or closed and why (a closed goal stays closed
    until no goal is left, so these marks explain an agent that ignores part of the house)."""
    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    pos = {n: np.asarray(d["pos"], float) for n, d in graph.nodes(data=True)}
    far = max(pos, key=lambda n: pos[n][0])
    mid = sorted(pos, key=lambda n: pos[n][0])[len(pos) // 2]
    monkeypatch.setattr(explorer_module, "build_plan", lambda *a, **k: Plan(workspace=ws, graph=graph))
    monkeypatch.setattr(explorer_module, "rank_goals", lambda *a, **k: [far, mid])
    real = explorer_module.plan_safe_path
    monkeypatch.setattr(explorer_module, "plan_safe_path",
                        lambda g, w, a, b, c: None if np.allclose(b, pos[far]) else real(g, w, a, b, c))
    cfg = ExplorerConfig(workspace=WCFG, retry_unreachable=False, **OBSERVED_ONLY)
    ex = ActiveSplatExplorer(WORLD, 0.0, cfg)
    obs = _obs(HERE)
    _after_bootstrap(ex, obs)
    ex.act(obs)
    assert np.allclose(ex.plan.goal, pos[mid])
    assert len(ex.failed) == 1 and np.allclose(ex.failed[0], pos[far])
    assert ex.failures == [{"step": len(ex.visited) - 1, "goal": [round(float(v), 3) for v in pos[far]],
                            "why": "no path", "failed_now": 1, "refused": False}]
    # with retry_unreachable (the default) the goal is only skipped: not closed, logged as such
    ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, **OBSERVED_ONLY))
    _after_bootstrap(ex, obs)
    ex.act(obs)
    assert np.allclose(ex.plan.goal, pos[mid]) and ex.failed == []
    assert [f["why"] for f in ex.failures] == ["no path, skipped"]


def test_a_goal_behind_a_neck_of_observed_floor_gets_a_path_on_grown_floor(monkeypatch):
    """`neck_margin_m`: a room seen through its door at a slant has no path on the observed floor; the
    fallback finds one on the same grids grown into unknown, follows it, checks it ahead on the grown floor
    and says so in the replan's record. Off (the default, the release), the goal is skipped."""
    start = np.array([1.0, 1.0])
    grids = two_rooms_seen_at_a_slant()
    ws = extract_workspace(grids, start, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    room, goal = max(graph.nodes) + 1, np.array([6.0, 3.0])  # a node of the right room, cut off at the door
    graph.add_node(room, pos=tuple(goal))
    monkeypatch.setattr(explorer_module, "build_plan",
                        lambda *a, **k: Plan(grids=grids, workspace=ws, graph=graph))
    monkeypatch.setattr(explorer_module, "rank_goals", lambda *a, **k: [room])
    obs = _obs(start)
    ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, **OBSERVED_ONLY))
    _after_bootstrap(ex, obs)
    ex.act(obs)
    assert ex.plan.goal is None and [f["why"] for f in ex.failures] == ["no path, skipped"]
    ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, neck_margin_m=0.1))
    _after_bootstrap(ex, obs)
    assert ex.act(obs) in ("turn_left", "turn_right", "move_forward")
    assert np.allclose(ex.plan.goal, goal) and ex.failures == []
    assert ex.replans[-1]["grown"] and ex.plan.workspace is not ws
    assert ex.plan.workspace.mask.sum() > ws.mask.sum()
    assert path_ahead_clear(ex.plan.workspace, start, ex.follower.waypoints[0], 10.0, 0.0, WCFG)


def test_an_agent_with_no_path_to_any_goal_escapes_instead_of_turning_on_the_spot(monkeypatch):
    """`retry_unreachable` closes nothing, so with every goal cut off the same graph comes back at every
    replan: the agent must move (an escape), as when every goal was marked failed (small-101 turned on
    one spot for 376 of its 1000 steps)."""
    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    pos = {n: np.asarray(d["pos"], float) for n, d in graph.nodes(data=True)}
    far = max(pos, key=lambda n: pos[n][0])
    monkeypatch.setattr(explorer_module, "build_plan", lambda *a, **k: Plan(workspace=ws, graph=graph))
    monkeypatch.setattr(explorer_module, "rank_goals", lambda *a, **k: [far])
    monkeypatch.setattr(explorer_module, "plan_safe_path", lambda *a: None)
    for retry in (True, False):
        ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, retry_unreachable=retry,
                                                            **OBSERVED_ONLY))
        obs = _obs(HERE)
        _after_bootstrap(ex, obs)
        ex.act(obs)
        assert ex.plan.goal is None and ex.failed == []
        assert ex.last_cause == "escape" and "move_forward" in ex.queue, retry


def _walk(start, moves, ctrl):
    """Floor positions after each action of `moves` from `start` heading +z (yaw 0), as the simulator
    moves: turns in whole steps, forward along the heading."""
    yaw, at, visited = 0.0, np.asarray(start, float), [np.asarray(start, float)]
    for action in moves:
        if action == "move_forward":
            at = at + ctrl.forward_m * np.array([np.sin(yaw), np.cos(yaw)])
        elif action in ("turn_left", "turn_right"):
            yaw += np.radians(ctrl.turn_deg) * (1 if action == "turn_left" else -1)
        visited.append(at.copy())
    return visited, yaw


def test_retracing_walks_the_agents_own_steps_back_to_open_workspace():
    """`retrace_actions` replays the forward moves the other way round, turning in whole steps, so the
    walk ends exactly where the agent last stood with the path clearance; nothing when it stands there
    already or when that lies farther back than `max_m`."""
    grids = corridor_with_a_slot()
    ctrl = ControllerConfig()
    # in the corridor heading +x, along the slot, then up its second leg
    moves = ["turn_left"] * 9 + ["move_forward"] * 12 + ["move_forward"] * 12 + ["turn_right"] * 9
    moves += ["turn_left"] * 18 + ["move_forward"] * 12  # heading +z: up the leg
    visited, yaw = _walk([3.0, 1.5], moves, ctrl)
    ws = extract_workspace(grids, visited[-1], WCFG)
    assert ws.clearance_at(visited[-1]) < WCFG.path_clearance
    actions = retrace_actions(visited, yaw, ws, WCFG.path_clearance, 3.0, ctrl)
    assert actions and set(actions) <= {"turn_left", "turn_right", "move_forward"}
    yaw_now, at = yaw, visited[-1].copy()
    for action in actions:  # replay: every move retraces an earlier one exactly
        if action == "move_forward":
            at = at + ctrl.forward_m * np.array([np.sin(yaw_now), np.cos(yaw_now)])
            assert min(float(np.hypot(*(at - v))) for v in visited) < 1e-9
        else:
            yaw_now += np.radians(ctrl.turn_deg) * (1 if action == "turn_left" else -1)
    assert ws.clearance_at(at) >= WCFG.path_clearance
    earlier = [v for v in visited if ws.clearance_at(v) >= WCFG.path_clearance]
    assert np.allclose(at, earlier[-1])  # the latest such spot, not the start
    assert retrace_actions(visited, yaw, ws, WCFG.path_clearance, 0.5, ctrl) == []
    assert retrace_actions(visited[:10], 0.0, ws, WCFG.path_clearance, 3.0, ctrl) == []  # open already


def test_an_agent_stuck_in_a_dead_end_slot_walks_back_before_it_escapes(monkeypatch):
    """`way_back_m`: with no path to any goal from a slot thinner than the path clearance, the agent
    queues its own steps back to open workspace before anything else; off, it escapes as before."""
    grids = corridor_with_a_slot()
    ctrl = ControllerConfig()
    moves = ["turn_left"] * 9 + ["move_forward"] * 24 + ["turn_left"] * 9 + ["move_forward"] * 12
    visited, yaw = _walk([3.0, 1.5], moves, ctrl)
    here = visited[-1]
    ws = extract_workspace(grids, here, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    far = min(graph.nodes, key=lambda n: graph.nodes[n]["pos"][0])
    monkeypatch.setattr(explorer_module, "build_plan", lambda *a, **k: Plan(grids=grids, workspace=ws,
                                                                            graph=graph))
    monkeypatch.setattr(explorer_module, "rank_goals", lambda *a, **k: [far])
    monkeypatch.setattr(explorer_module, "plan_safe_path", lambda *a: None)
    for way_back_m, cause in ((3.0, "way_back"), (None, "escape")):
        ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, way_back_m=way_back_m,
                                                            **OBSERVED_ONLY))
        _after_bootstrap(ex, _obs(here, yaw))
        ex.visited = list(visited[:-1])  # its walk into the slot (act appends the spot it stands on)
        ex.act(_obs(here, yaw))
        assert ex.plan.goal is None and ex.last_cause == cause, way_back_m
        if cause == "way_back":
            assert set(ex.queue_causes) <= {"way_back", "idle"} and "move_forward" in ex.queue
    # No workspace left around the agent (its region polished away): the observed free floor stands in.
    monkeypatch.setattr(explorer_module, "build_plan", lambda *a, **k: Plan(
        grids=grids, workspace=empty_workspace(grids.geometry), graph=nx.Graph()))
    monkeypatch.setattr(explorer_module, "rank_goals", lambda *a, **k: [])
    ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, **OBSERVED_ONLY))
    _after_bootstrap(ex, _obs(here, yaw))
    ex.visited = list(visited[:-1])
    ex.act(_obs(here, yaw))
    assert ex.last_cause == "way_back" and "move_forward" in ex.queue


def test_paths_refused_at_their_first_step_from_one_spot_make_the_agent_leave_it(monkeypatch):
    """`start_blocks`: where the path-ahead check refuses the first forward move of every path, the agent
    turns toward one goal after another, the failed ones again once the open ones have failed, and never
    moves (a replan that finds any goal with a path does not escape). After 3 such paths in a row it
    escapes (here the workspace has the path clearance, so there is no way back to walk); off, it never
    moves in 150 steps."""
    import activesplat.planning.explorer as base_module

    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    nodes = sorted(graph.nodes, key=lambda n: -graph.nodes[n]["pos"][0])  # farthest first
    monkeypatch.setattr(explorer_module, "build_plan", lambda *a, **k: Plan(workspace=ws, graph=graph))
    monkeypatch.setattr(explorer_module, "rank_goals", lambda *a, **k: list(nodes))
    monkeypatch.setattr(base_module, "path_ahead_clear", lambda *a, **k: False)
    turn = np.radians(ControllerConfig().turn_deg)
    for start_blocks in (3, None):
        ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, start_blocks=start_blocks,
                                                            **OBSERVED_ONLY))
        yaw = np.pi  # facing away from every goal: each path begins with turns
        _after_bootstrap(ex, _obs(HERE, yaw))
        causes = []
        for _ in range(150):
            action = ex.act(_obs(HERE, yaw))
            causes.append(ex.last_cause)
            yaw += {"turn_left": turn, "turn_right": -turn}.get(action, 0.0)
            if action == "move_forward":
                break
        if start_blocks is None:
            assert action != "move_forward" and set(causes) <= {"path", "fallback"}
            assert len(ex.failures) > len(nodes)  # the failed goals tried again
        else:
            assert action == "move_forward" and causes[-1] == "escape"
            assert [f["why"] for f in ex.failures] == ["blocked"] * 3
            assert not any(f["refused"] for f in ex.failures)  # refused ahead on the map, not by the scene


def test_a_global_replan_stops_first_at_a_node_worth_a_detour(monkeypatch):
    """`detour_m`: the far goal ranked first is reached by way of a nearer node that promises enough (the
    door of a room passed on the way); with the rule off, or in the local stage, straight to the goal."""
    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    pos = {n: np.asarray(d["pos"], float) for n, d in graph.nodes(data=True)}
    far = max(pos, key=lambda n: pos[n][0])
    mid = sorted(pos, key=lambda n: pos[n][0])[len(pos) // 2]

    def plan_for(stage):
        def build(*a, **k):
            return Plan(workspace=ws, graph=graph)

        def rank(plan, here, *a, **k):
            plan.stage = stage
            plan.scores, plan.info = {far: 40.0, mid: 25.0}, {far: 30.0, mid: 12.0}
            plan.travel = {n: float(abs(pos[n][0] - here[0])) for n in (far, mid)}
            return [far, mid]

        monkeypatch.setattr(explorer_module, "build_plan", build)
        monkeypatch.setattr(explorer_module, "rank_goals", rank)

    obs = _obs(HERE)
    for stage, detour_m, expected in (("global", 5.0, mid), ("global", None, far), ("local", 5.0, far)):
        plan_for(stage)
        ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, detour_m=detour_m))
        _after_bootstrap(ex, obs)
        ex.act(obs)
        assert np.allclose(ex.plan.goal, pos[expected]), (stage, detour_m)
        assert ex.replans[-1]["on_the_way"] == (expected == mid)


def test_a_rotation_stop_on_the_way_keeps_the_travelling_schedule(monkeypatch):
    """docs/protocol.md §2: the dense schedule while the agent turns on the spot with no path (bootstrap,
    arrival, escapes); a stop at a multi-connected node turns with its path still waiting and keeps the
    travelling schedule (the dense one measured within noise on the tuning houses)."""
    import networkx as nx

    from activesplat.planning.controller import PathFollower
    from activesplat.planning.viewpoints import RotationTarget

    graph = nx.Graph()
    graph.add_node(0, pos=(2.0, 1.2), multi=True)
    ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, multi_stop_spacing_m=0.0))
    ex.queue.clear(), ex.queue_causes.clear()  # the bootstrap
    ex.plan = Plan(graph=graph)
    ex.follower = PathFollower(np.array([[5.0, 1.2]]), ex.cfg.controller)
    monkeypatch.setattr(ex, "_rotation_targets", lambda pose, n: [RotationTarget(yaw=np.radians(-60.0),
                                                                                 pitch=0.0, weight=1.0,
                                                                                 source="panorama")])
    yaw, seen = 0.0, []
    for _ in range(12):  # turns applied as the simulator does
        action = ex.act(SimpleNamespace(pose=camera_pose([2.1, 1.25, 1.2], yaw), collided=False, step=0))
        seen.append((ex.last_cause, ex.dense_mapping))
        if ex.last_cause == "path":
            break
        yaw += np.radians(10.0) * {"turn_left": 1, "turn_right": -1}[action]
    assert seen[:6] == [("multi_stop", False)] * 6  # six right turns to -60 deg, with a path waiting
    assert seen[-1] == ("path", False) and ex.follower is not None


def test_the_camera_travels_at_the_travel_pitch_and_returns_to_it_after_a_stop():
    import math

    from activesplat.planning.viewpoints import RotationTarget

    def pose(pitch_deg):
        return SimpleNamespace(pose=camera_pose([1.0, 1.25, 1.5], 0.0, math.radians(pitch_deg)),
                               collided=False, step=0)

    path = np.array([[1.0, 1.5], [1.0, 3.0]])  # straight ahead (+z, yaw 0)
    for travel, level_first, down_first in ((0.0, "move_forward", "move_forward"),
                                            (-15.0, "look_down", "move_forward")):
        ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, travel_pitch_deg=travel))
        ex.queue.clear(), ex.queue_causes.clear()
        ex.go_to(path[-1], path)
        assert ex.act(pose(0.0)) == level_first and ex.last_cause == "path"
        assert ex.act(pose(-15.0)) == down_first
        # the last rotation target reached (looking 45 deg up): the camera goes back to the travel pitch
        ex.rotation_targets = [RotationTarget(yaw=0.0, pitch=math.radians(45.0), weight=1.0)]
        assert [ex.act(pose(45.0)), *ex.queue] == ["look_down"] * (3 if travel == 0 else 4)
        assert ex.last_cause == "level"
    with pytest.raises(InvalidInputError, match="travel_pitch_deg"):
        ExplorerConfig(travel_pitch_deg=-90.0)


def test_a_stop_turns_to_a_wall_it_has_only_seen_from_the_other_side_unless_told_not_to():
    """`PanoramaConfig.front_faces_targets`: the stop's panorama asks the world for front-facing opacity.
    This world is opaque all round, but behind the agent (yaw 180) it has only the far face of a wall."""
    def render(pose, K, width, height, front_alpha=False, behind_margin_deg=0.0):
        u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
        cam = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
        d = cam @ pose[:3, :3].T
        behind = d[..., 2] < -0.5 * np.linalg.norm(d, axis=-1)  # looking toward -z
        alpha = np.where(behind & front_alpha, 0.0, 1.0)
        return SimpleNamespace(alpha=alpha, median_depth=np.full(alpha.shape, 2.0))

    world = SimpleNamespace(gaussians=None, high_loss_mask=None, render=render)
    yaws = {}
    for front in (True, False):
        cfg = ExplorerConfig(workspace=WCFG)
        assert cfg.planning.panorama.front_faces_targets  # the default
        pano = dataclasses.replace(cfg.planning.panorama, front_faces_targets=front)
        cfg = dataclasses.replace(cfg, planning=dataclasses.replace(cfg.planning, panorama=pano))
        ex = ActiveSplatExplorer(world, 0.0, cfg)
        targets = ex._rotation_targets(camera_pose([1.0, 1.25, 1.5], 0.0), 5)
        yaws[front] = [abs(np.degrees(wrap_angle(t.yaw))) for t in targets]
    assert yaws[True] and max(yaws[True]) > 150  # it turns round to the wall's near face
    assert yaws[False] == []  # with every Gaussian's opacity the wall looks seen: nothing to turn to


def test_an_agent_cut_off_from_every_goal_worth_a_visit_leaves_instead_of_shuttling(monkeypatch):
    """`leave_when_cut_off`: the goal worth a visit has no path, the only goal with one promises nothing.
    On, the replan leaves the spot (its own steps back or the escape) instead of walking to it; off, it
    walks there, and from there back again: fresh medium-102 seed 0 shuttled so for its last 325 steps."""
    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    pos = {n: np.asarray(d["pos"], float) for n, d in graph.nodes(data=True)}
    far = max(pos, key=lambda n: pos[n][0])
    near = min((n for n in pos if np.hypot(*(pos[n] - HERE)) > 0.3), key=lambda n: np.hypot(*(pos[n] - HERE)))
    real_path = explorer_module.plan_safe_path

    def rank(plan, here, *a, **k):
        plan.stage = "global"
        plan.scores, plan.info = {far: 40.0, near: 10.0}, {far: 30.0, near: 0.0}
        plan.travel = {n: float(abs(pos[n][0] - here[0])) for n in (far, near)}
        return [far, near]

    def cut_off(graph_, workspace, start, goal, cfg):
        return None if np.allclose(goal, pos[far]) else real_path(graph_, workspace, start, goal, cfg)

    monkeypatch.setattr(explorer_module, "build_plan", lambda *a, **k: Plan(workspace=ws, graph=graph))
    monkeypatch.setattr(explorer_module, "rank_goals", rank)
    monkeypatch.setattr(explorer_module, "plan_safe_path", cut_off)
    obs = _obs(HERE)
    for leave in (True, False):
        ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG, leave_when_cut_off=leave,
                                                            **OBSERVED_ONLY))
        _after_bootstrap(ex, obs)
        ex.act(obs)
        assert [f["why"] for f in ex.failures] == ["no path, skipped"]
        if leave:
            assert ex.replans[-1]["goal"] is None and ex.last_cause in ("escape", "way_back")
        else:
            assert np.allclose(ex.plan.goal, pos[near]) and ex.last_cause == "path"


def test_a_refusal_on_the_way_fails_the_goal_and_escapes():
    # following a path down the corridor, the scene refuses a forward move 3 m short of the goal: the
    # paper's rule fails the goal at once, and the agent escapes
    ex = ActiveSplatExplorer(WORLD, 0.0, ExplorerConfig(workspace=WCFG))
    ex.queue, ex.queue_causes = [], []
    ex.plan = Plan(workspace=extract_workspace(corridor(), HERE, WCFG))
    goal = np.array([5.0, 1.5])
    ex.go_to(goal, np.stack([HERE, goal]))
    ex.act(_obs(HERE, np.pi / 2, collided=True))  # facing +x, toward the goal
    assert ex.follower is None and ex.last_cause == "escape"
    assert len(ex.failed) == 1 and np.allclose(ex.failed[0], goal)
    assert ex.failures[-1]["why"] == "blocked" and ex.failures[-1]["refused"]
    ex.forget_failures()
    assert not ex.failed
