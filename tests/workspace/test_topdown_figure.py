"""The topdown.png figure: legend entries for every layer drawn, a title with scene / step / policy, and
frontier cells (no Voronoi graph) for the frontier-based policy."""

from __future__ import annotations

import numpy as np
from layouts import RES, two_rooms, two_rooms_seen_at_a_slant

from activesplat.workspace.clean import extract_workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.draw import (
    FRONTIER_RGB,
    OUTSIDE_FREE_RGB,
    draw_topdown,
    legend_handles,
    topdown_figure,
    topdown_title,
    uses_frontiers,
)
from activesplat.workspace.subregions import partition_subregions
from activesplat.workspace.voronoi import build_voronoi_graph

TRAJ = np.array([[1.0, 1.0], [1.2, 1.1]])


def _plan(grids=None):
    grids = grids if grids is not None else two_rooms()
    cfg = WorkspaceConfig(resolution=RES)
    workspace = extract_workspace(grids, np.array([1.0, 1.0]), cfg)
    graph = build_voronoi_graph(workspace, cfg)
    partition_subregions(graph, cfg)
    return grids, workspace, graph


def _legend(fig) -> list[str]:
    return [t.get_text() for t in fig.axes[0].get_legend().get_texts()]


def test_legend_names_the_outside_free_cells_the_agent_and_what_node_colours_mean():
    grids, workspace, graph = _plan()
    labels = _legend(topdown_figure(grids, workspace, graph, trajectory=TRAJ))
    assert "free, outside workspace" in labels and "agent (last position)" in labels
    assert "view node (colour = subregion)" in labels
    handles = {h.get_label(): h for h in legend_handles()}
    assert handles["free, outside workspace"].get_markerfacecolor() == OUTSIDE_FREE_RGB
    # the view-node marker is neutral (not white, which no node is drawn in)
    assert handles["view node (colour = subregion)"].get_markerfacecolor() not in ("w", "white")
    assert handles["agent (last position)"].get_marker() == "^"


def test_legend_lists_only_the_layers_drawn():
    grids, workspace, graph = _plan()
    labels = _legend(topdown_figure(grids, workspace, graph))  # no trajectory, no path
    assert "trajectory" not in labels and "planned path" not in labels
    assert "agent (last position)" not in labels
    bare = _legend(topdown_figure(grids))  # no workspace: free cells are just "free"
    assert "free" in bare and "free, outside workspace" not in bare and "Voronoi graph" not in bare


def test_title_carries_scene_step_and_policy():
    assert topdown_title() == "top-down workspace"
    assert topdown_title(title="two rooms") == "two rooms"  # the old calls keep their titles
    assert topdown_title("small-0", 60, "activesplat") == (
        "small-0, step 60 / activesplat: map, Voronoi graph (subregions), trajectory")
    assert topdown_title("small-0", 60, title="mine") == "small-0, step 60 | mine"
    grids, workspace, graph = _plan()
    fig = topdown_figure(grids, workspace, graph, scene="two-rooms", step=7, policy="activesplat")
    assert fig.axes[0].get_title().startswith("two-rooms, step 7 / activesplat")


def test_frontier_policy_draws_frontiers_not_the_voronoi_graph(tmp_path):
    assert uses_frontiers("fbe") and not uses_frontiers("activesplat") and not uses_frontiers(None)
    grids, workspace, graph = _plan(two_rooms_seen_at_a_slant())  # the right room is partly unknown
    fig = topdown_figure(grids, workspace, graph, trajectory=TRAJ, policy="fbe", scene="two-rooms", step=3)
    ax = fig.axes[0]
    assert "Voronoi" not in ax.get_title() and "frontiers" in ax.get_title()
    labels = _legend(fig)
    assert "frontier cells" in labels and "Voronoi graph" not in labels
    assert not ax.collections  # no graph edges nor node scatters
    overlay = ax.get_images()[-1].get_array()  # the frontier cells, opaque orange over a clear image
    assert overlay.shape[-1] == 4 and (overlay[..., 3] > 0).any()
    assert np.allclose(overlay[overlay[..., 3] > 0][:, :3], FRONTIER_RGB)
    # a graph policy keeps its graph and draws no frontiers
    ours = topdown_figure(grids, workspace, graph, policy="activesplat")
    assert ours.axes[0].collections and "frontier cells" not in _legend(ours)
    out = draw_topdown(tmp_path / "fbe.png", grids, workspace, graph, trajectory=TRAJ, policy="fbe")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
