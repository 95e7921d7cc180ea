"""Furniture of the procedural houses: items by room kind (beds, counters, sofas, desks, tables and chairs
on legs, shelves, cabinets, boxes), each placed with its back to a wall (tables free standing), never in
front of a doorway or an open wall, and never cutting the agent-free space in two (a coarse top-down
check after each item)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from activesplat.sim.walls import box_along, wall_gaps

if TYPE_CHECKING:
    from activesplat.sim.rooms import House, HouseConfig, Room


def _legs(w, d, h, leg=0.05):
    corners = [(x, z) for x in (0.02, w - leg - 0.02) for z in (0.02, d - leg - 0.02)]
    return [((x, 0.0, z), (x + leg, h, z + leg)) for x, z in corners]


def _table(rng, cfg):
    w, d = rng.uniform(1.0, 1.6), rng.uniform(0.7, 0.95)
    return w, d, [*_legs(w, d, 0.72), ((0, 0.72, 0), (w, 0.76, d))], "furniture_wood"


def _desk(rng, cfg):
    w, d = rng.uniform(1.0, 1.4), rng.uniform(0.55, 0.7)
    drawers = ((w - 0.42, 0.0, 0), (w - 0.02, 0.71, d))
    return w, d, [*_legs(w, d, 0.71), ((0, 0.71, 0), (w, 0.75, d)), drawers], "furniture_dark"


def _chair(rng, cfg):
    w = d = 0.45
    seat, back = ((0, 0.44, 0), (w, 0.48, d)), ((0, 0.48, 0), (w, 0.9, 0.05))
    return w, d, [*_legs(w, d, 0.44), seat, back], "furniture_wood"


def _shelf(rng, cfg):
    w, d, h = rng.uniform(0.8, 1.4), 0.35, rng.uniform(1.7, 2.1)
    parts = [((0, 0, 0), (w, h, 0.02)), ((0, 0, 0), (0.03, h, d)), ((w - 0.03, 0, 0), (w, h, d))]
    parts += [((0.03, y, 0.02), (w - 0.03, y + 0.025, d)) for y in np.linspace(0.0, h - 0.025, 5)]
    books = [((x, y + 0.025, 0.05), (x + 0.12, y + 0.025 + rng.uniform(0.15, 0.28), d - 0.04))
             for y in np.linspace(0.0, h - 0.025, 5)[:-1] for x in (0.1, w / 2) if rng.random() < 0.6]
    return w, d, parts + books, "furniture_dark"


def _sofa(rng, cfg):
    w, d = rng.uniform(1.6, 2.2), 0.9
    return w, d, [((0, 0, 0), (w, 0.45, d)), ((0, 0.45, 0), (w, 0.85, 0.2)),
                  ((0, 0.45, 0), (0.18, 0.65, d)), ((w - 0.18, 0.45, 0), (w, 0.65, d))], "fabric_a"


def _bed(rng, cfg):
    w, d = rng.uniform(1.4, 1.8), 2.0
    return w, d, [((0, 0, 0), (w, 0.5, d)), ((0, 0, 0), (w, 1.05, 0.06)),
                  ((0.1, 0.5, 0.1), (w - 0.1, 0.62, 0.5))], "fabric_b"


def _cabinet(rng, cfg):
    w, d, h = rng.uniform(0.8, 1.8), 0.55, rng.uniform(0.85, 0.95)
    return w, d, [((0, 0, 0), (w, h, d))], "white_board"


def _boxes(rng, cfg):
    w, d = rng.uniform(0.4, 0.7), rng.uniform(0.4, 0.6)
    h1 = rng.uniform(0.3, 0.5)
    parts = [((0, 0, 0), (w, h1, d))]
    if rng.random() < 0.6:
        parts.append(((0.05, h1, 0.05), (w - 0.08, h1 + rng.uniform(0.25, 0.4), d - 0.1)))
    return w, d, parts, "cardboard"




def _chair_parts(x, z, flip: bool):
    """A chair at (x, z) in an item's frame; its back at low z, or at high z when flip."""
    w = d = 0.45
    back = ((x, 0.48, z + d - 0.05), (x + w, 0.9, z + d)) if flip else ((x, 0.48, z), (x + w, 0.9, z + 0.05))
    legs = [((x + a[0], a[1], z + a[2]), (x + b[0], b[1], z + b[2])) for a, b in _legs(w, d, 0.44)]
    return [*legs, ((x, 0.44, z), (x + w, 0.48, z + d)), back]


def _dining(rng, cfg):
    """A table on legs with one or two chairs on each long side (free standing)."""
    w, d = rng.uniform(1.1, 1.6), rng.uniform(0.75, 0.9)
    per_side = 2 if w >= 1.3 else 1
    table = [((x0, y0, z0 + 0.5), (x1, y1, z1 + 0.5)) for (x0, y0, z0), (x1, y1, z1) in _legs(w, d, 0.72)]
    table.append(((0, 0.72, 0.5), (w, 0.76, 0.5 + d)))
    xs = [w / 2 - 0.225] if per_side == 1 else [w / 4 - 0.2, 3 * w / 4 - 0.25]
    chairs = [p for x in xs for p in (*_chair_parts(x, 0.0, False), *_chair_parts(x, d + 0.55, True))]
    return w, d + 1.0, table + chairs, "furniture_wood"


def _counter(rng, cfg):
    """A kitchen counter along a wall (0.9 m, a darker top), with wall cabinets above it sometimes."""
    w, d = rng.uniform(1.6, 3.0), 0.6
    parts = [((0, 0, 0), (w, 0.86, d - 0.02)), ((0, 0.86, 0), (w, 0.9, d), "furniture_dark")]
    if rng.random() < cfg.counter_upper_p:
        parts.append(((0, 1.45, 0), (w, 2.15, 0.35)))
    return w, d, parts, "white_board"


_FURNITURE = {
    "bedroom": ((_bed,), (_shelf, _desk, _chair, _boxes, _cabinet)),
    "living": ((_sofa, _dining), (_table, _shelf, _chair, _cabinet, _shelf)),
    "kitchen": ((_counter, _dining), (_counter, _cabinet, _chair, _boxes)),
    "office": ((_desk, _shelf), (_chair, _boxes, _cabinet, _shelf)),
    "corridor": ((), (_cabinet, _boxes, _shelf)),
}
"""Per room kind: items every room of that kind gets first (if they fit), then items drawn at random."""
_FREE_STANDING = (_table, _dining)
_MATERIAL_OVERRIDES = {"fabric_a": ("fabric_a", "fabric_b"), "fabric_b": ("fabric_b", "fabric_a")}


def _furniture_boxes(rng, room: Room, make, cfg: HouseConfig):
    """Place one item with its back to a random wall (lz = 0 at the wall), or free standing for
    tables; returns its world boxes and footprint (x0, z0, x1, z1), or None if it does not fit.
    A part may name its own material as a third element."""
    w, d, parts, material = make(rng, cfg)
    material = rng.choice(_MATERIAL_OVERRIDES.get(material, (material,)))
    inset = cfg.wall_thickness / 2 + 0.02
    x0, z0, x1, z1 = room.x0 + inset, room.z0 + inset, room.x1 - inset, room.z1 - inset
    side = int(rng.integers(0, 4))
    along = (x1 - x0) if side in (0, 1) else (z1 - z0)
    across = (z1 - z0) if side in (0, 1) else (x1 - x0)
    if along < w + 0.05 or across < d + 0.8:
        return None
    s = rng.uniform(0.0, along - w)
    off = 0.0 if make not in _FREE_STANDING else rng.uniform(0.6, max(0.6, across - d - 0.6))
    boxes = []
    for part in parts:
        (lx0, ly0, lz0), (lx1, ly1, lz1) = part[0], part[1]
        lz0, lz1 = lz0 + off, lz1 + off
        if side == 0:  # against the z0 wall, facing +z
            b = ((x0 + s + lx0, ly0, z0 + lz0), (x0 + s + lx1, ly1, z0 + lz1))
        elif side == 1:  # against the z1 wall, facing -z
            b = ((x0 + s + lx0, ly0, z1 - lz1), (x0 + s + lx1, ly1, z1 - lz0))
        elif side == 2:  # against the x0 wall, facing +x
            b = ((x0 + lz0, ly0, z0 + s + lx0), (x0 + lz1, ly1, z0 + s + lx1))
        else:  # against the x1 wall, facing -x
            b = ((x1 - lz1, ly0, z0 + s + lx0), (x1 - lz0, ly1, z0 + s + lx1))
        boxes.append((np.array(b[0]), np.array(b[1]), str(part[2] if len(part) > 2 else material)))
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    return boxes, (lo[0], lo[2], hi[0], hi[2])


class _FreeSpace:
    """Coarse top-down grid of agent-free space used to keep it connected while furnishing."""

    def __init__(self, house: House, cfg: HouseConfig):
        self.cfg = cfg
        xs = [r.x0 for r in house.rooms] + [r.x1 for r in house.rooms]
        zs = [r.z0 for r in house.rooms] + [r.z1 for r in house.rooms]
        self.origin = np.array([min(xs) - 0.5, min(zs) - 0.5])
        shape = np.ceil((np.array([max(xs), max(zs)]) + 0.5 - self.origin) / cfg.check_cell).astype(int)
        self.obstacle = np.ones(shape, dtype=bool)  # indexed [ix, iz]
        t = cfg.wall_thickness
        for r in house.rooms:
            self.set_rect((r.x0 + t / 2, r.z0 + t / 2, r.x1 - t / 2, r.z1 - t / 2), False)
        for axis, coord, a, b in wall_gaps(house):
            lo, hi = box_along(axis, coord, a, b, t + 0.02, 0, 1)
            self.set_rect((lo[0], lo[2], hi[0], hi[2]), False)

    def _slices(self, rect):
        (i0, j0), (i1, j1) = (np.floor((np.array(p) - self.origin) / self.cfg.check_cell).astype(int)
                              for p in ((rect[0], rect[1]), (rect[2], rect[3])))
        return slice(max(i0, 0), i1 + 1), slice(max(j0, 0), j1 + 1)

    def set_rect(self, rect, value: bool) -> None:
        self.obstacle[self._slices(rect)] = value

    def n_components(self) -> int:
        clearance = ndimage.distance_transform_edt(~self.obstacle) * self.cfg.check_cell
        _, n = ndimage.label(clearance > self.cfg.check_clearance)
        return n


def _door_zones(house: House, cfg: HouseConfig) -> list[tuple[float, float, float, float]]:
    """Rectangles kept free of furniture: around every doorway, and along the open walls of L-shaped rooms."""
    zones = []
    for d in house.doors:
        half = d.width / 2 + 0.1
        a, b = d.centre - half, d.centre + half
        c0, c1 = d.coord - cfg.door_clearance, d.coord + cfg.door_clearance
        zones.append((a, c0, b, c1) if d.axis == "x" else (c0, a, c1, b))
    for axis, coord, a, b in house.open_walls:
        c0, c1 = coord - cfg.open_wall_clearance, coord + cfg.open_wall_clearance
        zones.append((a, c0, b, c1) if axis == "x" else (c0, a, c1, b))
    return zones


def _overlaps(a, b, gap: float = 0.0) -> bool:
    return a[0] < b[2] + gap and b[0] < a[2] + gap and a[1] < b[3] + gap and b[1] < a[3] + gap


def furnish(house: House, rng, cfg: HouseConfig) -> None:
    """Furnish every rectangle by its room's kind: the kind's essential items (in the largest rectangle
    of a room; several tries each), then 1-4 random ones (1-2 in corridors), never blocking doorways or
    open walls nor disconnecting the agent-free space (checked on a coarse grid after each item)."""
    free = _FreeSpace(house, cfg)
    blocked = _door_zones(house, cfg)
    largest = {}
    for room in house.rooms:
        if room.name not in largest or room.area > largest[room.name].area:
            largest[room.name] = room

    def place(room, make) -> bool:
        placed = _furniture_boxes(rng, room, make, cfg)
        if placed is None or any(_overlaps(placed[1], z, 0.05) for z in blocked):
            return False
        free.set_rect(placed[1], True)
        if free.n_components() != 1:
            free.set_rect(placed[1], False)
            return False
        house.boxes.extend(placed[0])
        blocked.append(placed[1])
        return True

    for room in house.rooms:
        essential, extra = _FURNITURE[room.kind]
        if largest[room.name] is room:
            for make in essential:
                any(place(room, make) for _ in range(12))
        n_items = int(rng.integers(1, 3)) if room.kind == "corridor" else int(rng.integers(1, 5))
        for _ in range(n_items * 4):
            if n_items == 0:
                break
            n_items -= place(room, extra[int(rng.integers(len(extra)))])


__all__ = ["furnish"]
