"""trajectory.png: the start / end legend outside the axes, and one outline per room (an L-shaped room of
two rectangles has no boundary drawn between them; a wall two rooms share is drawn once)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from activesplat.sim.navmap import NavMap
from activesplat.viz.trajectory import room_outline, trajectory_figure


def _navmap():
    grid = np.ones((180, 100), bool)
    return NavMap(grid, grid, np.ones(grid.shape), grid, np.zeros(2), 0.05, 0.0)


def _cross(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _length(segments: np.ndarray) -> float:
    return float(np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1).sum())


def test_room_outline_of_an_l_shaped_room_drops_the_shared_edge():
    one = room_outline([SimpleNamespace(x0=0, z0=0, x1=4, z1=3)])
    assert one.shape == (4, 2, 2) and _length(one) == pytest.approx(14.0)
    ell = room_outline([SimpleNamespace(x0=0, z0=0, x1=4, z1=3), SimpleNamespace(x0=0, z0=3, x1=2, z1=5)])
    assert _length(ell) == pytest.approx(18.0)  # the L's perimeter: 4 + 3 + 2 + 2 + 2 + 5
    # nothing left on z = 3 between x = 0 and 2 (the boundary between the two rectangles)
    on_shared = [s for s in ell if np.allclose(s[:, 1], 3.0) and s[:, 0].max() <= 2.0 + 1e-9]
    assert not on_shared
    # x = 2..4 along z = 3 is the L's inner corner edge and stays
    assert any(np.allclose(s[:, 1], 3.0) and np.allclose(sorted(s[:, 0]), [2.0, 4.0]) for s in ell)


def test_rooms_are_drawn_as_one_outline_and_one_label_each(house):
    from activesplat.viz.trajectory import room_walls

    ax = trajectory_figure(_navmap(), np.array([[1.0, 1.0], [6.0, 2.0]]), house).axes[0]
    dashed = [c for c in ax.collections if c.get_linestyle() and c.get_linestyle()[0][1] is not None]
    assert len(dashed) == 1  # every room's walls in one collection
    walls = dashed[0].get_segments()
    # no boundary inside the L-shaped living room (z = 3 between x = 0 and 2)
    assert not any(np.allclose(s[:, 1], 3.0) and s[:, 0].max() <= 2.0 + 1e-9 for s in walls)
    # every room's outline is drawn, and a wall two rooms share only once
    outlines = [room_outline(r for r in house.rooms if r.name == n) for n in house.room_names]
    total = sum(_length(o) for o in outlines)
    assert _length(room_walls(house)) < total - 1.0  # the house's rooms share walls
    keys = [tuple(np.round(s.ravel(), 6)) for s in walls]
    assert len(keys) == len(set(keys))
    for outline in outlines:  # each outline's stretches lie on drawn walls
        for seg in outline:
            mid = seg.mean(axis=0)
            assert any(np.isclose(_cross(w[1] - w[0], mid - w[0]), 0)
                       and np.all(mid >= w.min(0) - 1e-9) and np.all(mid <= w.max(0) + 1e-9) for w in walls)
    assert [t.get_text().split("\n")[0] for t in ax.texts] == house.room_names


def test_start_end_legend_sits_outside_the_axes(house):
    fig = trajectory_figure(_navmap(), np.array([[1.0, 1.0], [6.0, 2.0]]), house)
    ax = fig.axes[0]
    assert ax.get_legend() is None and len(fig.legends) == 1
    legend = fig.legends[0]
    assert [t.get_text() for t in legend.get_texts()] == ["start", "end"]
    canvas = FigureCanvasAgg(fig)
    canvas.draw()  # lays the figure out (constrained layout) as savefig does
    renderer = canvas.get_renderer()
    box, axes_box = legend.get_window_extent(renderer), ax.get_window_extent(renderer)
    assert box.y1 <= axes_box.y0 or box.x0 >= axes_box.x1  # below or right of the plan, never over it
    # legend markers only (no line through the start / end marker)
    assert all(h.get_linestyle() in ("None", "", " ") for h in legend.legend_handles)
