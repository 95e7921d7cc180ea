"""Draw the workspace topology to a PNG (the episode's topdown.png): grids, workspace outline,
Voronoi graph with nodes coloured by subregion, a planned path and the agent's trajectory."""

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
from activesplat.workspace.topdown import TopDownGrids
from activesplat.workspace.voronoi import node_positions

UNKNOWN_RGB = (0.55, 0.55, 0.58)
FREE_RGB = (1.0, 1.0, 1.0)
OBSTACLE_RGB = (0.12, 0.12, 0.14)
OUTSIDE_FREE_RGB = (0.84, 0.88, 0.93)


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
            ax.plot(closed[:, 0], closed[:, 1], color="#2a9d8f", lw=1.0, zorder=2)


def draw_graph(ax: Axes, graph: nx.Graph) -> None:
    """The Voronoi graph on `ax`: edges grey, nodes coloured by subregion, view nodes ringed black and
    multi-connected nodes ringed red."""
    nodes = sorted(graph.nodes)
    positions = node_positions(graph)
    index = {n: i for i, n in enumerate(nodes)}
    segments = [(positions[index[a]], positions[index[b]]) for a, b in graph.edges]
    ax.add_collection(LineCollection(segments, colors="#6c757d", linewidths=0.8, zorder=3))
    labels = np.array([graph.nodes[n].get("subregion", 0) for n in nodes])
    colours = matplotlib.colormaps["tab10"](labels % 10)
    ax.scatter(positions[:, 0], positions[:, 1], s=6, c=colours, zorder=4, linewidths=0)
    view = np.array([bool(graph.nodes[n].get("view")) for n in nodes])
    ax.scatter(positions[view, 0], positions[view, 1], s=40, c=colours[view], edgecolors="k",
               linewidths=0.6, zorder=5)
    multi = np.array([bool(graph.nodes[n].get("multi")) for n in nodes])
    ax.scatter(positions[multi, 0], positions[multi, 1], s=90, facecolors="none", edgecolors="#d62828",
               linewidths=1.0, zorder=5)


def legend_handles() -> list[Line2D]:
    return [
        Line2D([], [], marker="s", ls="", color=OBSTACLE_RGB, label="obstacle"),
        Line2D([], [], marker="s", ls="", color=UNKNOWN_RGB, label="unknown"),
        Line2D([], [], color="#2a9d8f", label="workspace"),
        Line2D([], [], marker="o", ls="", mfc="w", mec="k", label="view node"),
        Line2D([], [], marker="o", ls="", mfc="none", mec="#d62828", label="multi-connected"),
        Line2D([], [], color="#1d4ed8", label="trajectory"),
        Line2D([], [], color="#e63946", lw=2, label="path"),
    ]


def draw_topdown(out_png: str | Path, grids: TopDownGrids, workspace: Workspace | None = None,
                 graph: nx.Graph | None = None, path: np.ndarray | None = None,
                 trajectory: np.ndarray | None = None, title: str = "") -> Path:
    """Write the top-down map as a PNG; every layer but the grids is optional. World x runs right and
    world z down, as the grid rows. `path` and `trajectory` are (K, 2) world (x, z)."""
    out_png = Path(out_png)
    height, width = grids.free.shape
    x_min, x_max, z_min, z_max = grids.geometry.extent
    scale = 8.0 / max(height, width)
    # A bare Figure renders with Agg without touching pyplot's global backend.
    fig = Figure(figsize=(max(width * scale, 3.0) + 2.2, max(height * scale, 3.0)), dpi=120)
    ax = fig.subplots()
    ax.imshow(grid_image(grids, workspace), extent=(x_min, x_max, z_max, z_min), interpolation="nearest",
              zorder=0)
    if workspace is not None and not workspace.empty:
        _draw_polygons(ax, workspace)
    if graph is not None and graph.number_of_nodes() > 0:
        draw_graph(ax, graph)
    if trajectory is not None and len(trajectory) > 0:
        traj = np.asarray(trajectory).reshape(-1, 2)
        ax.plot(traj[:, 0], traj[:, 1], color="#1d4ed8", lw=1.2, zorder=6)
        ax.plot(*traj[-1], marker="^", color="#1d4ed8", ms=9, zorder=7)
    if path is not None and len(path) > 0:
        waypoints = np.asarray(path).reshape(-1, 2)
        ax.plot(waypoints[:, 0], waypoints[:, 1], color="#e63946", lw=2.0, marker="o", ms=3, zorder=8)
    ax.set_xlim(x_min, x_max)
    ax.set_ylim(z_max, z_min)
    ax.set_aspect("equal")
    ax.set_xlabel("world x (m)")
    ax.set_ylabel("world z (m)")
    ax.set_title(title or "top-down workspace")
    ax.legend(handles=legend_handles(), loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8,
              frameon=False)
    fig.tight_layout()
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png)
    return out_png
