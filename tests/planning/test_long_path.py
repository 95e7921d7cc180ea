"""The release's long-path rule (REFERENCE.md section 5) on a synthetic corridor."""

import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "workspace"))
from layouts import RES, corridor  # noqa: E402

from activesplat.planning.explorer import ActiveSplatExplorer, ExplorerConfig, _distance_to_polyline  # noqa: E402
from activesplat.workspace.clean import extract_workspace  # noqa: E402
from activesplat.workspace.config import WorkspaceConfig  # noqa: E402
from activesplat.workspace.paths import plan_safe_path  # noqa: E402
from activesplat.workspace.voronoi import build_voronoi_graph  # noqa: E402

WCFG = WorkspaceConfig(resolution=RES)
HERE = np.array([1.0, 1.5])


def _explorer(mid_info: float) -> tuple[ActiveSplatExplorer, np.ndarray, np.ndarray]:
    cfg = ExplorerConfig(workspace=WCFG, long_path_m=3.0)
    ex = ActiveSplatExplorer(world=None, floor_height=0.0, cfg=cfg)
    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    ex.plan.workspace, ex.plan.graph = ws, graph
    pos = {n: np.asarray(d["pos"], float) for n, d in graph.nodes(data=True)}
    far = max(pos, key=lambda n: pos[n][0])
    mid = min(pos, key=lambda n: abs(pos[n][0] - 3.0))
    ex.plan.scores = {far: 40.0, mid: 20.0 + mid_info}
    ex.plan.info = {far: 20.0, mid: mid_info}
    goal = pos[far]
    return ex, goal, plan_safe_path(graph, ws, HERE, goal, WCFG)


def test_a_long_path_stops_at_a_worthwhile_node_on_the_way():
    ex, goal, path = _explorer(mid_info=10.0)
    new_goal, new_path = ex._closer_on_the_way(HERE, goal, path)
    assert abs(new_goal[0] - 3.0) < 0.2 and new_path[-1] @ [1, 0] < goal[0] - 1.0


def test_a_long_path_is_kept_when_nothing_on_the_way_is_worth_a_stop():
    for mid_info in (5.0, 0.0):  # no information above the local threshold
        ex, goal, path = _explorer(mid_info)
        new_goal, new_path = ex._closer_on_the_way(HERE, goal, path)
        assert new_goal is goal and new_path is path
    ex, goal, path = _explorer(mid_info=10.0)
    ex.visited.append(np.array([3.0, 1.5]))  # the node on the way was visited already
    assert ex._closer_on_the_way(HERE, goal, path)[0] is goal


def test_distance_to_polyline():
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    assert _distance_to_polyline(np.array([1.0, 0.5]), path) == 0.5
    assert _distance_to_polyline(np.array([3.0, 1.0]), path) == 1.0
    assert np.isclose(_distance_to_polyline(np.array([-1.0, -1.0]), path), np.sqrt(2))


def _follower_to(ex: ActiveSplatExplorer, here: np.ndarray, target: np.ndarray) -> np.ndarray:
    from activesplat.planning.controller import PathFollower

    ex.plan.workspace = extract_workspace(corridor(), HERE, WCFG)
    ex.follower = PathFollower(np.array([target]), ex.cfg.controller)
    pose = np.eye(4)
    pose[0, 3], pose[2, 3] = here
    return pose


def test_path_ahead_is_blocked_only_where_it_gets_narrower_than_the_agent_and_than_here():
    ex = ActiveSplatExplorer(world=None, floor_height=0.0, cfg=ExplorerConfig(workspace=WCFG))
    # from the corridor's middle toward its wall: blocked
    assert not ex._path_ahead_clear(_follower_to(ex, np.array([2.0, 1.5]), np.array([2.0, 1.02])))
    # along the middle: clear
    assert ex._path_ahead_clear(_follower_to(ex, np.array([2.0, 1.5]), np.array([3.5, 1.5])))
    # standing closer to the wall than the agent radius (thin polished workspace), a way out is clear
    pose = _follower_to(ex, np.array([2.0, 1.06]), np.array([2.6, 1.5]))
    assert ex.plan.workspace.clearance_at(np.array([2.0, 1.06])) < WCFG.agent_radius
    assert ex._path_ahead_clear(pose)


def test_path_ahead_forgives_one_cell_but_not_a_wall():
    """Beside a wall the checked segment starts off the planned one and clearance is quantised to cells:
    a dip of less than `ahead_tolerance_m` below the agent radius passes, a heading into the wall does not."""
    ex = ActiveSplatExplorer(world=None, floor_height=0.0, cfg=ExplorerConfig(workspace=WCFG))
    here = np.array([2.0, 1.5])
    graze = np.array([2.3, 1.06])  # ends just closer to the wall than the agent radius
    pose = _follower_to(ex, here, graze)
    ws = ex.plan.workspace
    dip = float(ws.segments_clearance(here[None], graze[None])[0])
    assert WCFG.agent_radius - ex.cfg.ahead_tolerance_m <= dip < WCFG.agent_radius
    assert ex._path_ahead_clear(pose)
    ex.cfg = dataclasses.replace(ex.cfg, ahead_tolerance_m=0.0)  # the config is frozen
    assert not ex._path_ahead_clear(pose)
    ex.cfg = dataclasses.replace(ex.cfg, ahead_tolerance_m=0.05)
    assert not ex._path_ahead_clear(_follower_to(ex, here, np.array([2.3, 1.0])))


def test_an_agent_whose_goals_all_failed_escapes_before_looking_around():
    ex = ActiveSplatExplorer(world=None, floor_height=0.0, cfg=ExplorerConfig(workspace=WCFG))
    pose = _follower_to(ex, np.array([2.0, 1.2]), np.array([3.0, 1.5]))
    ex.queue.clear()
    ex._idle(pose, stuck=False)
    assert ex.queue == ["turn_left"] * 6
    ex.queue.clear()
    ex._idle(pose, stuck=True)
    assert ex.queue[-6:] == ["turn_left"] * 6 and "move_forward" in ex.queue


def test_node_information_is_scored_with_and_without_hierarchical_planning():
    """The long-path rule reads `plan.info`: `no-hp` (hierarchical off) must fill it too."""
    from types import SimpleNamespace

    class HalfSeen:  # the lower half of every view mapped: an invisible share at every node
        gaussians = None
        high_loss_mask = None

        def render(self, pose, K=None, width=None, height=None):
            alpha = np.zeros((height, width), np.float32)
            alpha[height // 2:] = 1.0
            return SimpleNamespace(alpha=alpha, median_depth=np.full((height, width), 2.0, np.float32))

    for hierarchical in (True, False):
        ex = ActiveSplatExplorer(world=HalfSeen(), floor_height=0.0,
                                 cfg=ExplorerConfig(workspace=WCFG, hierarchical=hierarchical))
        ws = extract_workspace(corridor(), HERE, WCFG)
        ex.plan.workspace, ex.plan.graph = ws, build_voronoi_graph(ws, WCFG)
        ranked = ex._rank_goals(HERE)
        assert ranked and set(ex.plan.info) == set(ex.plan.scores)
        assert max(ex.plan.info.values()) > ex.cfg.local_score_threshold


def test_a_goal_the_agent_stands_on_is_skipped(monkeypatch):
    """Arriving at once would replan at once: the explorer must go to the next goal instead of spinning."""
    import activesplat.planning.explorer as explorer_module

    ws = extract_workspace(corridor(), HERE, WCFG)
    graph = build_voronoi_graph(ws, WCFG)
    pos = {n: np.asarray(d["pos"], float) for n, d in graph.nodes(data=True)}
    near = min(pos, key=lambda n: np.hypot(*(pos[n] - HERE)))
    far = max(pos, key=lambda n: pos[n][0])
    ex = ActiveSplatExplorer(world=type("W", (), {"gaussians": None})(), floor_height=0.0,
                             cfg=ExplorerConfig(workspace=WCFG))
    ex.queue.clear()
    plan = explorer_module.Plan(workspace=ws, graph=graph)
    monkeypatch.setattr(explorer_module, "build_plan", lambda *a, **k: plan)
    monkeypatch.setattr(ActiveSplatExplorer, "_rank_goals", lambda self, here: [near, far])
    pose = np.eye(4)
    pose[0, 3], pose[2, 3] = pos[near]  # standing on the best-ranked node
    ex._replan(pose)
    assert np.allclose(ex.plan.goal, pos[far]) and ex.follower is not None
