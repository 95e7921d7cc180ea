"""Draw the workspace topology to a PNG (the episode's topdown.png): grids, workspace outline,
Voronoi graph with nodes coloured by subregion (or, for a frontier-based policy, its frontier cells), a
planned path and the agent's trajectory."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import networkx as nx
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from activesplat.workspace.clean import Workspace
from activesplat.workspace.topdown import TopDownGrids, frontier_cells
from activesplat.workspace.voronoi import node_positions

UNKNOWN_RGB = (0.55, 0.55, 0.58)
FREE_RGB = (1.0, 1.0, 1.0)
OBSTACLE_RGB = (0.12, 0.12, 0.14)
OUTSIDE_FREE_RGB = (0.84, 0.88, 0.93)
WORKSPACE_COLOUR = "#2a9d8f"
EDGE_COLOUR = "#6c757d"
NEUTRAL_NODE_COLOUR = "#adb5bd"
MULTI_COLOUR = "#d62828"
TRAJECTORY_COLOUR = "#1d4ed8"
PATH_COLOUR = "#e63946"
FRONTIER_RGB = (0.97, 0.50, 0.0)


def grid_image(grids: TopDownGrids, workspace: Workspace | None) -> np.ndarray:
    """(H, W, 3) float image: unknown grey, obstacle near-black, workspace white, other free light blue."""
    image = np.empty((*grids.free.shape, 3))
    image[:] = UNKNOWN_RGB
    image[grids.free] = OUTSIDE_FREE_RGB if workspace is not None else FREE_RGB
    if workspace is not None:
        image[workspace.mask] = FREE_RGB
    image[grids.obstacle] = OBSTACLE_RGB
    return image


def _draw_polygons(ax: Axes, workspace: Workspace) -> None:
    for poly in [workspace.outer, *workspace.holes]:
        if len(poly) >= 3:
            closed = np.vstack([poly, poly[:1]])
            ax.plot(closed[:, 0], closed[:, 1], color=WORKSPACE_COLOUR, lw=1.0, zorder=2)


def draw_graph(ax: Axes, graph: nx.Graph) -> None:
    """The Voronoi graph on `ax`: edges grey, nodes coloured by subregion, view nodes ringed black and
    multi-connected nodes ringed red."""
    nodes = sorted(graph.nodes)
    positions = node_positions(graph)
    index = {n: i for i, n in enumerate(nodes)}
    segments = [(positions[index[a]], positions[index[b]]) for a, b in graph.edges]
    ax.add_collection(LineCollection(segments, colors=EDGE_COLOUR, linewidths=0.8, zorder=3))
    labels = np.array([graph.nodes[n].get("subregion", 0) for n in nodes])
    colours = matplotlib.colormaps["tab10"](labels % 10)
    ax.scatter(positions[:, 0], positions[:, 1], s=6, c=colours, zorder=4, linewidths=0)
    view = np.array([bool(graph.nodes[n].get("view")) for n in nodes])
    ax.scatter(positions[view, 0], positions[view, 1], s=40, c=colours[view], edgecolors="k",
               linewidths=0.6, zorder=5)
    multi = np.array([bool(graph.nodes[n].get("multi")) for n in nodes])
    ax.scatter(positions[multi, 0], positions[multi, 1], s=90, facecolors="none", edgecolors=MULTI_COLOUR,
               linewidths=1.0, zorder=5)


FRONTIER_POLICIES = ("fbe",)
"""Policies (by name: this layer knows nothing of planning) that go to frontiers instead of planning on the
Voronoi graph: the frontier-based exploration baseline, planning/frontier.py."""


def uses_frontiers(policy: str | None) -> bool:
    """Whether the named exploration policy goes to frontiers instead of planning on the Voronoi graph."""
    return policy in FRONTIER_POLICIES


def frontier_mask(grids: TopDownGrids, workspace: Workspace | None) -> np.ndarray:
    """(H, W) bool frontier cells as the frontier policy sees them: workspace (else free) cells next to
    unknown ones."""
    free = workspace.mask if workspace is not None else grids.free
    return frontier_cells(free, grids.unknown)


def _draw_frontiers(ax: Axes, mask: np.ndarray, extent: tuple[float, float, float, float]) -> None:
    overlay = np.zeros((*mask.shape, 4))
    overlay[mask] = (*FRONTIER_RGB, 1.0)
    x_min, x_max, z_min, z_max = extent
    ax.imshow(overlay, extent=(x_min, x_max, z_max, z_min), interpolation="nearest", zorder=1)


def _square(colour, label: str) -> Line2D:
    return Line2D([], [], marker="s", ls="", ms=7, mfc=colour, mec="#495057", mew=0.5, label=label)


def legend_handles(workspace: bool = True, graph: bool = True, trajectory: bool = True, path: bool = True,
                   frontiers: bool = False) -> list[Line2D]:
    """Legend entries of the layers :func:`draw_topdown` drew (all the usual ones by default)."""
    handles = [_square(OBSTACLE_RGB, "obstacle"), _square(UNKNOWN_RGB, "unknown")]
    if workspace:
        handles += [_square(FREE_RGB, "free, in workspace"),
                    _square(OUTSIDE_FREE_RGB, "free, outside workspace"),
                    Line2D([], [], color=WORKSPACE_COLOUR, label="workspace outline")]
    else:
        handles.append(_square(FREE_RGB, "free"))
    if graph:
        handles += [
            Line2D([], [], color=EDGE_COLOUR, lw=0.8, marker="o", ms=3, mfc=NEUTRAL_NODE_COLOUR, mec="none",
                   label="Voronoi graph"),
            Line2D([], [], marker="o", ls="", mfc=NEUTRAL_NODE_COLOUR, mec="k",
                   label="view node (colour = subregion)"),
            Line2D([], [], marker="o", ls="", mfc="none", mec=MULTI_COLOUR, label="multi-connected"),
        ]
    if frontiers:
        handles.append(Line2D([], [], marker="s", ls="", ms=6, mfc=FRONTIER_RGB, mec="none",
                              label="frontier cells"))
    if trajectory:
        handles += [Line2D([], [], color=TRAJECTORY_COLOUR, label="trajectory"),
                    Line2D([], [], marker="^", ls="", ms=8, color=TRAJECTORY_COLOUR,
                           label="agent (last position)")]
    if path:
        handles.append(Line2D([], [], color=PATH_COLOUR, lw=2, marker="o", ms=3, label="planned path"))
    return handles


def topdown_title(scene: str | None = None, step: int | None = None, policy: str | None = None,
                  title: str = "") -> str:
    """The figure's title: the scene and step where known, then `title`, or by default what the figure
    shows, honest about the policy (a Voronoi graph, or frontiers), e.g.
    "small-0, step 60 / activesplat: map, Voronoi graph (subregions), trajectory"."""
    head = ", ".join([*([scene] if scene else []), *([f"step {step}"] if step is not None else [])])
    if title:
        return f"{head} | {title}" if head else title
    if policy is None:
        what = "top-down workspace"
    elif uses_frontiers(policy):
        what = f"{policy}: map, workspace, frontiers, trajectory"
    else:
        what = f"{policy}: map, Voronoi graph (subregions), trajectory"
    return f"{head} / {what}" if head else what


def draw_topdown(out_png: str | Path, grids: TopDownGrids, workspace: Workspace | None = None,
                 graph: nx.Graph | None = None, path: np.ndarray | None = None,
                 trajectory: np.ndarray | None = None, title: str = "", *, scene: str | None = None,
                 step: int | None = None, policy: str | None = None, frontiers: bool | None = None) -> Path:
    """Write the top-down map as a PNG (:func:`topdown_figure`, which describes the arguments)."""
    out_png = Path(out_png)
    fig = topdown_figure(grids, workspace, graph, path, trajectory, title, scene=scene, step=step,
                         policy=policy, frontiers=frontiers)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, bbox_inches="tight", pad_inches=0.1)  # never clip the legend outside the axes
    return out_png


def topdown_figure(grids: TopDownGrids, workspace: Workspace | None = None, graph: nx.Graph | None = None,
                   path: np.ndarray | None = None, trajectory: np.ndarray | None = None, title: str = "", *,
                   scene: str | None = None, step: int | None = None, policy: str | None = None,
                   frontiers: bool | None = None) -> Figure:
    """The top-down map (a bare Agg Figure); every layer but the grids is optional. World x runs right and
    world z down, as the grid rows. `path` and `trajectory` are (K, 2) world (x, z).

    `scene`, `step` (steps taken) and `policy` (the exploration policy's name) go into the title; without
    `title` it says what is drawn. A policy that explores by frontiers (`fbe`) never used the Voronoi graph:
    for it the graph is not drawn, and its frontier cells are. `frontiers`: draw the frontier cells (None:
    when the policy uses them). The legend lists the layers drawn."""
    height, width = grids.free.shape
    extent = grids.geometry.extent
    x_min, x_max, z_min, z_max = extent
    frontier_policy = uses_frontiers(policy)
    if frontiers is None:
        frontiers = frontier_policy
    scale = 8.0 / max(height, width)
    # A bare Figure renders with Agg without touching pyplot's global backend.
    fig = Figure(figsize=(max(width * scale, 3.0) + 2.6, max(height * scale, 3.0)), dpi=120)
    ax = fig.subplots()
    ax.imshow(grid_image(grids, workspace), extent=(x_min, x_max, z_max, z_min), interpolation="nearest",
              zorder=0)
    has_workspace = workspace is not None and not workspace.empty
    if has_workspace:
        _draw_polygons(ax, workspace)
    if frontiers:
        _draw_frontiers(ax, frontier_mask(grids, workspace), extent)
    drew_graph = graph is not None and graph.number_of_nodes() > 0 and not frontier_policy
    if drew_graph:
        draw_graph(ax, graph)
    drew_trajectory = trajectory is not None and len(trajectory) > 0
    if drew_trajectory:
        traj = np.asarray(trajectory).reshape(-1, 2)
        ax.plot(traj[:, 0], traj[:, 1], color=TRAJECTORY_COLOUR, lw=1.2, zorder=6)
        ax.plot(*traj[-1], marker="^", color=TRAJECTORY_COLOUR, ms=9, zorder=7)
    drew_path = path is not None and len(path) > 0
    if drew_path:
        waypoints = np.asarray(path).reshape(-1, 2)
        ax.plot(waypoints[:, 0], waypoints[:, 1], color=PATH_COLOUR, lw=2.0, marker="o", ms=3, zorder=8)
    ax.set_xlim(x_min, x_max)
    ax.set_ylim(z_max, z_min)
    ax.set_aspect("equal")
    ax.set_xlabel("world x (m)")
    ax.set_ylabel("world z (m)")
    ax.set_title(topdown_title(scene, step, policy, title), fontsize=10)
    handles = legend_handles(workspace=workspace is not None, graph=drew_graph, trajectory=drew_trajectory,
                             path=drew_path, frontiers=bool(frontiers))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    fig.tight_layout()
    return fig
