"""Wall lines of a house plan: every wall once, the doorways and open walls cut out of them, and the box
of a wall piece (used by the mesh builder in `sim.house` and the free-space check in `sim.furniture`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from activesplat.sim.rooms import House, Room


def subtract_gaps(lo: float, hi: float, gaps) -> list[tuple[float, float]]:
    """The pieces of the interval [lo, hi] outside every (a, b) of ``gaps``."""
    pieces = [(lo, hi)]
    for a, b in gaps:
        pieces = [q for p0, p1 in pieces for q in ((p0, min(p1, a)), (max(p0, b), p1)) if q[1] - q[0] > 1e-6]
    return pieces


def wall_lines(rooms: list[Room]) -> list[tuple[str, float, float, float]]:
    """Every wall line once: each rectangle's max-x and max-z edges, plus the parts of its min edges that
    no other rectangle's max edge covers (the outside of a footprint of any shape)."""
    lines = []
    for r in rooms:
        lines.append(("x", r.z1, r.x0, r.x1))
        lines.append(("z", r.x1, r.z0, r.z1))
    for r in rooms:
        for axis, coord, lo, hi in (("x", r.z0, r.x0, r.x1), ("z", r.x0, r.z0, r.z1)):
            covered = [(l0, l1) for a, c, l0, l1 in lines[: 2 * len(rooms)]
                       if a == axis and abs(c - coord) < 1e-6 and min(hi, l1) > max(lo, l0)]
            lines += [(axis, coord, a, b) for a, b in subtract_gaps(lo, hi, covered)]
    return lines


def wall_gaps(house: House) -> list[tuple[str, float, float, float]]:
    """(axis, coord, lo, hi) of every cut in the walls: doorways, open walls of non-rectangular rooms."""
    cuts = [(d.axis, d.coord, d.centre - d.width / 2, d.centre + d.width / 2) for d in house.doors]
    return cuts + house.open_walls


def cut_doors(line, gaps) -> list[tuple[float, float]]:
    """Pieces of a wall line left after cutting the doorways and open walls lying on it."""
    axis, coord, lo, hi = line
    return subtract_gaps(lo, hi, [(a, b) for ax, c, a, b in gaps if ax == axis and abs(c - coord) < 1e-6])


def box_along(axis: str, coord: float, lo: float, hi: float, t: float, y0: float, y1: float):
    """(min corner, max corner) of a wall piece ``t`` thick centred on the line ``axis`` = ``coord``,
    from ``lo`` to ``hi`` along it and from height ``y0`` to ``y1``."""
    if axis == "x":
        return np.array([lo, y0, coord - t / 2]), np.array([hi, y1, coord + t / 2])
    return np.array([coord - t / 2, y0, lo]), np.array([coord + t / 2, y1, hi])


__all__ = ["box_along", "cut_doors", "subtract_gaps", "wall_gaps", "wall_lines"]
