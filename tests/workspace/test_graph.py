"""Voronoi graph, subregions and safe paths on synthetic grids with known answers."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest
from layouts import RES, box, corridor, grids_from_layout, two_rooms, two_rooms_seen_at_a_slant

from activesplat.workspace.clean import extract_workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.paths import line_of_sight, path_length, plan_safe_path
from activesplat.workspace.subregions import agent_subregion, partition_subregions
from activesplat.workspace.voronoi import build_voronoi_graph, node_positions

CFG = WorkspaceConfig(resolution=RES)
DOOR_X, DOOR_Z = 3.6, (1.55, 2.45)


def topology(grids, agent_xz):
    workspace = extract_workspace(grids, np.asarray(agent_xz, dtype=float), CFG)
    graph = build_voronoi_graph(workspace, CFG)
    return workspace, graph


def distance_to_cells(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Exact distance from world points (P, 2) to the nearest square pixel of a boolean grid."""
    rows, cols = np.nonzero(cells)
    centres = np.stack([(cols + 0.5) * RES, (rows + 0.5) * RES], axis=1)
    gap = np.maximum(np.abs(points[:, None, :] - centres[None]) - 0.5 * RES, 0.0)
    return np.linalg.norm(gap, axis=2).min(axis=1)


def door_crossings(waypoints: np.ndarray) -> list[float]:
    """z where the polyline crosses the wall's centre plane x = DOOR_X."""
    out = []
    for a, b in zip(waypoints[:-1], waypoints[1:], strict=True):
        if (a[0] - DOOR_X) * (b[0] - DOOR_X) < 0:
            t = (DOOR_X - a[0]) / (b[0] - a[0])
            out.append(a[1] + t * (b[1] - a[1]))
    return out


def test_two_rooms_connected_graph_with_a_node_in_each_room():
    _, graph = topology(two_rooms(), (2.0, 2.0))
    assert graph.number_of_nodes() > 0
    assert nx.is_connected(graph)
    pos = node_positions(graph)
    assert (pos[:, 0] < 3.5).any() and (pos[:, 0] > 3.7).any()
    # Sites along the mask's real walls put a vertex in the door (between the wall's faces).
    in_door = (np.abs(pos[:, 0] - DOOR_X) <= 0.1) & (pos[:, 1] > DOOR_Z[0]) & (pos[:, 1] < DOOR_Z[1])
    assert in_door.any()
    views = [n for n, d in graph.nodes(data=True) if d["view"]]
    assert views, "junctions of the medial axis are view-position nodes"
    for a, b, w in graph.edges(data="weight"):
        assert w == pytest.approx(np.linalg.norm(graph.nodes[a]["pos"] - graph.nodes[b]["pos"]))


def test_two_rooms_path_goes_through_the_door():
    grids = two_rooms()
    workspace, graph = topology(grids, (1.0, 1.0))
    start, goal = np.array([1.0, 1.0]), np.array([6.0, 3.0])
    path = plan_safe_path(graph, workspace, start, goal, CFG)
    assert path is not None
    np.testing.assert_allclose(path[0], start)
    np.testing.assert_allclose(path[-1], goal)
    crossings = door_crossings(path)
    assert len(crossings) == 1
    assert DOOR_Z[0] + CFG.agent_radius <= crossings[0] <= DOOR_Z[1] - CFG.agent_radius
    # Shortcut keeps the route close to the geodesic (two straight legs through the door centre).
    geodesic = np.linalg.norm([DOOR_X - 1.0, 2.0 - 1.0]) + np.linalg.norm([6.0 - DOOR_X, 3.0 - 2.0])
    assert path_length(path) < 1.15 * geodesic


def test_safe_path_segments_keep_two_agent_radii_from_walls():
    grids = two_rooms()
    workspace, graph = topology(grids, (1.0, 1.0))
    path = plan_safe_path(graph, workspace, np.array([1.0, 1.0]), np.array([6.0, 3.0]), CFG)
    samples = np.concatenate([a + np.linspace(0, 1, 200)[:, None] * (b - a)
                              for a, b in zip(path[:-1], path[1:], strict=True)])
    clearance = distance_to_cells(samples, ~workspace.mask)
    assert clearance.min() >= CFG.path_clearance - 1e-6
    assert clearance.min() >= distance_to_cells(samples, grids.obstacle).min() - 1e-9


def test_no_vertex_closer_than_the_agent_radius_to_an_obstacle():
    for grids, agent in ((two_rooms(), (2.0, 2.0)), (corridor(), (1.0, 1.5))):
        _, graph = topology(grids, agent)
        positions = node_positions(graph)
        assert distance_to_cells(positions, grids.obstacle).min() > CFG.agent_radius
        assert distance_to_cells(positions, ~grids.free).min() > CFG.agent_radius - RES


def test_corridor_graph_runs_along_its_centre_line():
    _, graph = topology(corridor(), (1.0, 1.5))
    positions = node_positions(graph)
    assert nx.is_connected(graph)
    np.testing.assert_allclose(positions[:, 1], 1.5, atol=0.06)
    # Spans the corridor up to the corner spurs' junctions (half a width from each end).
    assert positions[:, 0].min() < 1.1 and positions[:, 0].max() > 4.9
    assert sum(1 for n in graph if graph.degree(n) == 1) == 2


def test_dead_end_branch_is_kept():
    """A 1 m wide, 1.5 m deep alcove off a corridor is a real dead end: its chain survives pruning."""
    shape = (80, 120)
    free = box(shape, 0.5, 5.5, 1.0, 2.0) | box(shape, 2.5, 3.5, 2.0, 3.5)
    grids = grids_from_layout(free, box(shape, 0.3, 5.7, 0.8, 3.7) & ~free)
    _, graph = topology(grids, (1.0, 1.5))
    z = node_positions(graph)[:, 1]
    assert z.max() > 2.8


def test_far_apart_rooms_fall_in_different_subregions():
    """Two 2 x 2 m rooms joined by an 8 m corridor: UPGMA cut at 2 m separates them."""
    shape = (60, 260)
    free = box(shape, 0.5, 2.5, 0.5, 2.5) | box(shape, 10.5, 12.5, 0.5, 2.5) | box(shape, 2.5, 10.5, 1.2, 1.8)
    grids = grids_from_layout(free, box(shape, 0.3, 12.7, 0.3, 2.7) & ~free)
    _, graph = topology(grids, (1.5, 1.5))
    labels = partition_subregions(graph, CFG)
    x = node_positions(graph)[:, 0]
    left = {labels[n] for n in sorted(graph.nodes) if x[n] < 2.5}
    right = {labels[n] for n in sorted(graph.nodes) if x[n] > 10.5}
    assert len(left) == 1 and len(right) == 1 and left != right
    assert len(set(labels.values())) >= 4  # 8 m of corridor cannot be one 2 m subregion either
    assert agent_subregion(graph, labels, np.array([1.5, 1.5])) == left.pop()
    assert all(graph.nodes[n]["subregion"] == labels[n] for n in graph)


def test_upgma_distance_on_a_hand_made_graph():
    """Chain 0-1-2-3 with unit edges bent at node 2: independent UPGMA arithmetic decides the cut."""
    graph = nx.Graph()
    pos = {0: (0.0, 0.0), 1: (1.0, 0.0), 2: (2.0, 0.0), 3: (2.0, 1.0), 4: (9.0, 0.0)}
    for n, p in pos.items():
        graph.add_node(n, pos=np.array(p))
    for a, b in ((0, 1), (1, 2), (2, 3)):
        graph.add_edge(a, b, weight=1.0)
    labels = partition_subregions(graph, CFG)
    # d(0,1)=1, d(1,2)=1, d(2,3)=1, d(0,2)=2, d(1,3)=0.5*2+0.5*sqrt2=1.707, d(0,3)=0.5*3+0.5*sqrt5=2.618.
    # Merges: {0,1}@1 -> {2,3}@1 -> between them avg(2, 2.618, 1, 1.707)=1.831 < 2: one subregion;
    # node 4 is in another component (infinite path length) and stays alone.
    assert labels[0] == labels[1] == labels[2] == labels[3] != labels[4]
    tight = partition_subregions(graph, WorkspaceConfig(resolution=RES, subregion_cut=1.8))
    assert tight[0] == tight[1] != tight[2] == tight[3]


@pytest.mark.parametrize("kind", ["empty", "unknown", "obstacles"])
def test_empty_or_unknown_map_gives_empty_graph_and_no_path(kind):
    shape = (40, 40)
    free = np.zeros(shape, bool)
    obstacle = box(shape, 0.5, 1.5, 0.5, 1.5) if kind == "obstacles" else np.zeros(shape, bool)
    grids = grids_from_layout(free, obstacle)
    workspace, graph = topology(grids, (1.0, 1.0))
    assert workspace.empty and graph.number_of_nodes() == 0
    assert partition_subregions(graph, CFG) == {}
    assert agent_subregion(graph, {}, np.array([1.0, 1.0])) is None
    assert plan_safe_path(graph, workspace, np.array([1.0, 1.0]), np.array([1.5, 1.5]), CFG) is None


def test_tiny_free_patch_gives_no_graph_without_crashing():
    shape = (40, 40)
    free = box(shape, 0.9, 1.05, 0.9, 1.05)
    workspace, graph = topology(grids_from_layout(free, np.zeros(shape, bool)), (1.0, 1.0))
    assert graph.number_of_nodes() == 0
    assert plan_safe_path(graph, workspace, np.array([1.0, 1.0]), np.array([1.8, 1.8]), CFG) is None


def test_endpoint_outside_the_workspace_gives_no_line_of_sight_through_walls():
    grids = two_rooms()
    workspace, graph = topology(grids, (1.0, 1.0))
    inside = np.array([2.0, 1.0])
    in_wall, beyond = np.array([3.6, 1.0]), np.array([7.5, 1.0])  # in the dividing wall / outside the house
    assert workspace.clearance_at(in_wall) == 0 and workspace.clearance_at(beyond) == 0
    assert not line_of_sight(workspace, inside, in_wall, CFG)
    assert not line_of_sight(workspace, beyond, inside, CFG)
    assert plan_safe_path(graph, workspace, beyond, inside, CFG) is None
    # Standing just outside the polished workspace (unobserved floor under the agent) still connects.
    edge = np.array([0.48, 2.0])
    assert workspace.clearance_at(edge) == 0
    assert line_of_sight(workspace, edge, np.array([1.5, 2.0]), CFG)


def test_far_away_and_infinite_voronoi_vertices_are_dropped_without_warnings():
    import warnings

    from activesplat.workspace.voronoi import safe_edges

    workspace = extract_workspace(corridor(), np.array([1.0, 1.5]), CFG)
    vertices = np.array([[1.0, 1.5], [2.0, 1.5], [1e30, 1.5], [np.inf, np.nan]])
    ridges = np.array([[0, 1], [1, 2], [2, 3], [0, 3]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        merged, edges = safe_edges(workspace, vertices, ridges, CFG)
    assert [merged[e].tolist() for e in edges] == [[[1.0, 1.5], [2.0, 1.5]]]


def test_a_door_seen_at_a_slant_gets_an_edge_when_the_free_floor_grows_into_unknown():
    start, goal = np.array([1.0, 1.0]), np.array([6.0, 3.0])
    grids = two_rooms_seen_at_a_slant()
    door = box(grids.free.shape, 3.5, 3.7, 1.55, 2.45)
    observed, graph = topology(grids, start)
    assert plan_safe_path(graph, observed, start, goal, CFG) is None  # the neck is thinner than the agent
    assert observed.clearance[door].max() < CFG.agent_radius
    grown = WorkspaceConfig(resolution=RES, unknown_margin=0.1)
    workspace = extract_workspace(grids, start, grown)
    graph = build_voronoi_graph(workspace, grown)
    path = plan_safe_path(graph, workspace, start, goal, grown)
    assert path is not None and len(door_crossings(path)) == 1
    assert workspace.clearance[door].max() > CFG.agent_radius
    assert not (workspace.mask & grids.obstacle).any()  # obstacles are never grown over
    assert not (observed.mask & ~workspace.mask).any()  # growing only adds to the observed workspace


def test_grown_plan_gives_the_neck_a_path_from_the_same_grids_and_leaves_the_plan_alone():
    """`ExplorerConfig.neck_margin_m`'s fallback: the observed plan has no path through the slanted door,
    the grown plan built from the same grids (no new render) has one; the observed plan is unchanged."""
    from activesplat.planning.explorer_config import ExplorerConfig
    from activesplat.workspace.plan import Plan, grown_plan

    start, goal = np.array([1.0, 1.0]), np.array([6.0, 3.0])
    grids = two_rooms_seen_at_a_slant()
    observed, graph = topology(grids, start)
    plan = Plan(grids=grids, workspace=observed, graph=graph)
    grown = grown_plan(plan, start, CFG, 0.1)
    assert grown.grids is grids and plan.workspace is observed and CFG.unknown_margin == 0
    assert plan_safe_path(plan.graph, plan.workspace, start, goal, CFG) is None
    path = plan_safe_path(grown.graph, grown.workspace, start, goal, CFG)
    assert path is not None and len(door_crossings(path)) == 1
    assert grown.workspace.clearance_at(path).min() >= CFG.agent_radius - RES  # safe on the grown floor
    with pytest.raises(ValueError, match="grids"):
        grown_plan(Plan(), start, CFG, 0.1)
    with pytest.raises(Exception, match="neck_margin_m"):
        ExplorerConfig(neck_margin_m=0.0)


def test_growing_into_unknown_never_covers_obstacles_and_zero_changes_nothing():
    from activesplat.workspace.clean import grow_into_unknown

    free = np.zeros((9, 9), dtype=bool)
    free[4, :4] = True
    unknown = ~free
    unknown[:, 6:] = False  # obstacles from column 6 on
    assert np.array_equal(grow_into_unknown(free, unknown, 0), free)
    grown = grow_into_unknown(free, unknown, 2)
    assert grown[4, 5] and grown[2, 2] and grown[6, 0]  # two pixels around the free row
    assert not grown[4, 6:].any() and not grown[1, 2]  # never an obstacle; not three pixels away
    with pytest.raises(Exception, match="unknown_margin"):
        WorkspaceConfig(unknown_margin=-0.1)
