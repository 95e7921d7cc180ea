"""The trajectory over the floor plan, coloured by step: dwelling shows as a knot of one colour.

Drawn as seen from above (world y up): x runs right and z down, the same orientation as the episode's
topdown.png, so the two figures of a run can be laid side by side.

Background: the ground-truth navigable floor (light) and the rest of the plan (dark); built-in houses add
their room outlines with each room's name and completion. Agg only; no display needed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure


def draw_trajectory(out_png: str | Path, navmap, positions_xz: np.ndarray, house=None,
                    room_labels: dict[str, str] | None = None, title: str = "") -> Path:
    """Save the top-down trajectory `positions_xz` (one (x, z) per step) over `navmap` (a sim NavMap).

    `house`: a built-in house plan (outlines per room); `room_labels`: text under each room's name (e.g.
    its completion)."""
    out_png = Path(out_png)
    trajectory_figure(navmap, positions_xz, house, room_labels, title).savefig(out_png)
    return out_png


def trajectory_figure(navmap, positions_xz: np.ndarray, house=None, room_labels: dict[str, str] | None = None,
                      title: str = "") -> Figure:
    """The figure :func:`draw_trajectory` saves (a bare Agg Figure)."""
    xz = np.asarray(positions_xz, np.float64).reshape(-1, 2)
    extent = navmap_extent(navmap)
    width, depth = extent[1] - extent[0], extent[3] - extent[2]
    # constrained layout keeps the legend outside the axes (below them), so it never hides the plan
    fig = Figure(figsize=(min(16.0, 2.0 + 0.55 * width), min(14.0, 1.6 + 0.55 * depth)), dpi=110,
                 layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    draw_navigable(ax, navmap)
    if house is not None:
        _draw_rooms(ax, house, room_labels or {})
    if len(xz) > 1:
        segments = np.stack([xz[:-1], xz[1:]], axis=1)
        moved = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1) > 1e-9
        lines = LineCollection(segments[moved], cmap="viridis", linewidths=2.0)
        lines.set_array(np.flatnonzero(moved).astype(float))
        lines.set_clim(0, len(xz) - 1)
        ax.add_collection(lines)
        fig.colorbar(lines, ax=ax, fraction=0.03, pad=0.02, label="step")
        # where the agent turned on the spot: dot size grows with the steps spent there
        stay = _dwell(xz)
        if len(stay):
            ax.scatter(stay[:, 0], stay[:, 1], s=8 + 1.5 * stay[:, 2], c=stay[:, 3], cmap="viridis",
                       vmin=0, vmax=len(xz) - 1, alpha=0.55, edgecolors="none", zorder=3)
    if len(xz):
        ax.plot(*xz[0], marker="o", ms=9, ls="", mfc="none", mec="red", mew=2, zorder=4, label="start")
        ax.plot(*xz[-1], marker="x", ms=9, ls="", color="red", mew=2, zorder=4, label="end")
        fig.legend(loc="outside lower center", ncol=2, fontsize=8, frameon=False)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[3], extent[2])  # z down: the plan seen from above (y up), as topdown.png draws it
    ax.set_aspect("equal")
    ax.set_xlabel("world x (m)")
    ax.set_ylabel("world z (m)")
    if title:
        ax.set_title(title, fontsize=10)
    return fig


def navmap_extent(navmap) -> tuple[float, float, float, float]:
    """(x_min, x_max, z_min, z_max) in world metres of a sim NavMap's grid."""
    res = navmap.resolution
    return (navmap.origin[0], navmap.origin[0] + navmap.grid.shape[0] * res,
            navmap.origin[1], navmap.origin[1] + navmap.grid.shape[1] * res)


def draw_navigable(ax, navmap) -> None:
    """The ground-truth floor plan of a sim NavMap on `ax`: navigable floor light (its largest connected
    part lightest), the rest dark."""
    img = np.where(navmap.largest, 0.93, np.where(navmap.grid, 0.8, 0.45))
    ax.imshow(img.T, origin="lower", extent=navmap_extent(navmap), cmap="gray", vmin=0.0, vmax=1.0,
              interpolation="nearest")


def room_labels(house, rooms: dict, values: dict[str, float | None], unit: str = "%") -> dict[str, str]:
    """Text under each room's name in the figure: its value (e.g. completion %) and "(not entered)" for a
    room the agent never stood in (`rooms`: the episode's ``rooms`` entry; corridors always count as
    entered)."""
    visited = set(rooms.get("entered", ())) | set(house.corridor_names)
    out = {}
    for name, value in values.items():
        text = f"{value:.0f} {unit}" if value is not None else ""
        out[name] = text if name in visited else f"{text} (not entered)"
    return out


def _dwell(xz: np.ndarray) -> np.ndarray:
    """(x, z, steps spent, first step) of every place the agent stayed for more than one step."""
    moved = np.r_[True, np.linalg.norm(np.diff(xz, axis=0), axis=1) > 1e-9]
    starts = np.flatnonzero(moved)
    lengths = np.diff(np.r_[starts, len(xz)])
    keep = lengths > 1
    return np.column_stack([xz[starts[keep]], lengths[keep], starts[keep]]).astype(np.float64)


def largest_part(house, name: str):
    """The largest rectangle of the room `name` (an L-shaped room has two): where its label goes."""
    return max((r for r in house.rooms if r.name == name), key=lambda r: r.area)


def room_outline(rects) -> np.ndarray:
    """(K, 2, 2) segments [(x, z), (x, z)] of the outline of the union of axis-aligned rectangles (objects
    with x0, z0, x1, z1): the rectangles' edges less the parts shared by two of them, so an L-shaped room
    drawn from two rectangles has no boundary between them."""
    rects = list(rects)
    eps = 1e-6
    segments = []
    for i, r in enumerate(rects):
        others = [o for j, o in enumerate(rects) if j != i]
        # each edge: fixed coordinate, span along the edge, outward direction, and whether it runs along x
        for along_x, fixed, lo, hi, out in ((True, r.z0, r.x0, r.x1, -1), (True, r.z1, r.x0, r.x1, 1),
                                            (False, r.x0, r.z0, r.z1, -1), (False, r.x1, r.z0, r.z1, 1)):
            cuts = {lo, hi}
            for o in others:
                cuts.update(v for v in ((o.x0, o.x1) if along_x else (o.z0, o.z1)) if lo < v < hi)
            cuts = sorted(cuts)
            for a, b in zip(cuts[:-1], cuts[1:], strict=False):
                mid, past = 0.5 * (a + b), fixed + out * eps
                x, z = (mid, past) if along_x else (past, mid)
                if any(o.x0 <= x <= o.x1 and o.z0 <= z <= o.z1 for o in others):
                    continue  # the other side is the same room: an internal boundary
                segments.append(((a, fixed), (b, fixed)) if along_x else ((fixed, a), (fixed, b)))
    return np.array(segments, np.float64).reshape(-1, 2, 2)


def room_walls(house) -> np.ndarray:
    """(K, 2, 2) segments of every room's outline (`room_outline`), each stretch drawn once: where two rooms
    share a wall, their outlines cover the same stretch, and two dashed lines over each other read as one
    uneven line."""
    outlines = [room_outline(r for r in house.rooms if r.name == name) for name in house.room_names]
    segments = np.concatenate(outlines) if outlines else np.zeros((0, 2, 2))
    pieces = set()
    for along_x in (True, False):
        axis = 1 if along_x else 0  # the coordinate a wall along x keeps fixed is z
        lines = segments[np.isclose(segments[:, 0, axis], segments[:, 1, axis])]
        for fixed in np.unique(np.round(lines[:, 0, axis], 6)):
            on = lines[np.isclose(lines[:, 0, axis], fixed)]
            spans = np.sort(on[:, :, 1 - axis], axis=1)
            cuts = np.unique(np.round(spans, 6))
            for a, b in zip(cuts[:-1], cuts[1:], strict=False):
                mid = 0.5 * (a + b)
                if np.any((spans[:, 0] <= mid) & (mid <= spans[:, 1])):
                    pieces.add(((a, fixed), (b, fixed)) if along_x else ((fixed, a), (fixed, b)))
    return np.array(sorted(pieces), np.float64).reshape(-1, 2, 2)


def _draw_rooms(ax, house, labels: dict[str, str]) -> None:
    """Each room's outline (one outline for a room of several rectangles, one line for a wall two rooms
    share) and its label in its largest rectangle."""
    ax.add_collection(LineCollection(room_walls(house), colors="#1f4e79", linewidths=0.8, linestyles="--",
                                     zorder=2))
    for name in house.room_names:
        big = largest_part(house, name)
        text = name + (f"\n{labels[name]}" if name in labels else "")
        ax.text(0.5 * (big.x0 + big.x1), 0.5 * (big.z0 + big.z1), text, ha="center", va="center",
                fontsize=7, color="#1f4e79", zorder=5,
                bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.7})


__all__ = ["draw_navigable", "draw_trajectory", "largest_part", "navmap_extent", "room_labels",
           "room_outline", "room_walls", "trajectory_figure"]
