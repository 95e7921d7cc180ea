"""Procedural houses: rooms joined by doorways (and a corridor in medium houses), thick walls, floor
and ceiling, furniture of several heights, textured surfaces. Deterministic per seed.

Layout: ``small-<seed>`` is a binary space partition of a rectangle into 2-4 rooms; ``medium-<seed>``
is a corridor with 5-10 rooms on its two sides. Doors follow a random spanning tree of the room
adjacency (so every room is reachable) plus a few extra loops. Furniture is placed with a coarse
free-space connectivity check; the final mesh navigability map is checked again in scene.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from activesplat.sim.geometry import MeshBuilder
from activesplat.sim.textures import FLOOR_MATERIALS, WALL_MATERIALS, build_atlas


@dataclass(frozen=True)
class HouseConfig:
    """Sizes of the procedural houses (our choices; docs/protocol.md §1 fixes only the agent and sensor)."""

    wall_thickness: float = 0.1
    """Interior and exterior wall thickness in metres."""
    ceiling_range: tuple[float, float] = (2.6, 2.8)
    """Ceiling height range in metres (single floor at y = 0)."""
    door_width: float = 0.9
    """Doorway width in metres."""
    door_height: float = 2.1
    """Doorway height; a lintel fills the wall above it."""
    min_room_side: float = 2.4
    """Smallest room side in metres."""
    small_rooms: tuple[int, int] = (2, 4)
    """Room count range of small-<seed> (docs/protocol.md §1: small scenes have < 5 rooms)."""
    medium_rooms: tuple[int, int] = (5, 10)
    """Room count range of medium-<seed>, the corridor not counted (docs/protocol.md §1: 5-10 rooms)."""
    corridor_width: tuple[float, float] = (1.2, 1.6)
    """Corridor width range of medium houses."""
    door_clearance: float = 0.9
    """No furniture within this distance of a doorway, on either side."""
    check_cell: float = 0.05
    """Cell of the coarse free-space connectivity check during furniture placement."""
    check_clearance: float = 0.22
    """Clearance used by that check: larger than the simulator's effective radius (0.1 m + one
    navigation cell diagonal), so the fine navigability map stays connected."""


@dataclass
class Room:
    x0: float
    z0: float
    x1: float
    z1: float
    kind: str = "room"
    wall: str = "wall_a"
    floor: str = "floor_wood"
    name: str = ""
    """The room this rectangle belongs to (set by make_layout): rectangles of one room share a name, so a
    room need not be a rectangle. Per-room coverage and "rooms entered" are counted by name."""

    @property
    def area(self) -> float:
        return (self.x1 - self.x0) * (self.z1 - self.z0)

    def contains(self, x: float, z: float) -> bool:
        return self.x0 <= x <= self.x1 and self.z0 <= z <= self.z1


@dataclass(frozen=True)
class Door:
    axis: str  # "x": the wall runs along x at z = coord; "z": along z at x = coord
    coord: float
    centre: float
    width: float


@dataclass
class House:
    """The plan of a procedural house; `mesh` is built by build_house."""

    name: str
    rooms: list[Room]
    doors: list[Door]
    ceiling: float
    boxes: list[tuple[np.ndarray, np.ndarray, str]] = field(default_factory=list)

    @property
    def n_rooms(self) -> int:
        """Rooms by name (a room may span several rectangles), corridors not counted."""
        return len({r.name or id(r) for r in self.rooms if r.kind != "corridor"})

    def room_at(self, x: float, z: float) -> Room | None:
        for room in self.rooms:
            if room.contains(x, z):
                return room
        return None

    @property
    def room_names(self) -> list[str]:
        """Distinct room names in layout order, corridors included."""
        return list(dict.fromkeys(r.name for r in self.rooms))

    @property
    def corridor_names(self) -> list[str]:
        return list(dict.fromkeys(r.name for r in self.rooms if r.kind == "corridor"))

    def label_points(self, xz: np.ndarray, inset: float = 0.0) -> np.ndarray:
        """Index into `room_names` of the room holding each (x, z) point, -1 outside every room (in a wall
        or outside the house). `inset` shrinks every rectangle first (a point counts as inside a room only
        `inset` metres past its walls)."""
        xz = np.asarray(xz, np.float64).reshape(-1, 2)
        names = self.room_names
        out = np.full(len(xz), -1, np.int64)
        for r in self.rooms:
            inside = ((xz[:, 0] >= r.x0 + inset) & (xz[:, 0] <= r.x1 - inset)
                      & (xz[:, 1] >= r.z0 + inset) & (xz[:, 1] <= r.z1 - inset) & (out < 0))
            out[inside] = names.index(r.name)
        return out


# --------------------------------------------------------------------------- layout
def _split(rng, rooms: list[Room], n: int, min_side: float) -> list[Room]:
    """Binary space partition: split the largest room across its longer side until n rooms."""
    for _ in range(100):
        if len(rooms) >= n:
            break
        rooms.sort(key=lambda r: -r.area)
        r = rooms[0]
        along_x = (r.x1 - r.x0) >= (r.z1 - r.z0)
        lo, hi = (r.x0, r.x1) if along_x else (r.z0, r.z1)
        if hi - lo < 2 * min_side:
            break
        cut = float(np.round(rng.uniform(max(lo + min_side, lo + 0.35 * (hi - lo)),
                                         min(hi - min_side, lo + 0.65 * (hi - lo))), 2))
        a, b = (Room(r.x0, r.z0, cut, r.z1), Room(cut, r.z0, r.x1, r.z1)) if along_x else (
            Room(r.x0, r.z0, r.x1, cut), Room(r.x0, cut, r.x1, r.z1))
        rooms[0:1] = [a, b]
    return rooms


def _small_layout(rng, cfg: HouseConfig) -> list[Room]:
    n = int(rng.integers(cfg.small_rooms[0], cfg.small_rooms[1] + 1))
    area = n * rng.uniform(11.0, 18.0)
    aspect = rng.uniform(1.0, 1.6)
    width = float(np.round(np.sqrt(area * aspect), 2))
    depth = float(np.round(area / width, 2))
    depth = max(depth, cfg.min_room_side * (1 if n <= 2 else 2) + 0.2)
    return _split(rng, [Room(0.0, 0.0, width, depth)], n, cfg.min_room_side)


def _strip(rng, x_total: float, z0: float, z1: float, k: int, min_side: float) -> list[Room]:
    """k rooms side by side along x, each at least min_side wide (random split of the rest)."""
    spare = x_total - k * min_side
    if spare < 0:
        raise ValueError(f"a strip of {x_total} m cannot hold {k} rooms of {min_side} m")
    widths = min_side + rng.dirichlet(np.full(k, 4.0)) * spare
    edges = np.round(np.concatenate([[0.0], np.cumsum(widths)]), 2)
    edges[-1] = x_total
    return [Room(float(a), z0, float(b), z1) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def _medium_layout(rng, cfg: HouseConfig) -> list[Room]:
    n = int(rng.integers(cfg.medium_rooms[0], cfg.medium_rooms[1] + 1))
    k_south = n // 2 + int(rng.integers(0, n % 2 + 1))
    k_north = n - k_south
    width = float(np.round(max(k_south, k_north) * rng.uniform(3.0, 4.2), 2))
    depth_s = float(np.round(rng.uniform(3.2, 5.0), 2))
    depth_n = float(np.round(rng.uniform(3.2, 5.0), 2))
    corridor = float(np.round(rng.uniform(*cfg.corridor_width), 2))
    rooms = _strip(rng, width, 0.0, depth_s, k_south, cfg.min_room_side)
    rooms.append(Room(0.0, depth_s, width, depth_s + corridor, kind="corridor"))
    rooms += _strip(rng, width, depth_s + corridor, depth_s + corridor + depth_n, k_north,
                    cfg.min_room_side)
    return rooms


def _shared_edge(a: Room, b: Room) -> tuple[str, float, float, float] | None:
    """(axis, coord, lo, hi) of the wall segment two rooms share, if any."""
    for p, q in ((a, b), (b, a)):
        if abs(p.x1 - q.x0) < 1e-6:
            lo, hi = max(p.z0, q.z0), min(p.z1, q.z1)
            if hi > lo:
                return "z", p.x1, lo, hi
        if abs(p.z1 - q.z0) < 1e-6:
            lo, hi = max(p.x0, q.x0), min(p.x1, q.x1)
            if hi > lo:
                return "x", p.z1, lo, hi
    return None


def _place_doors(rng, rooms: list[Room], cfg: HouseConfig) -> list[Door]:
    """Random spanning tree of the room adjacency (corridor edges first) plus ~25 % extra doors."""
    margin = cfg.door_width / 2 + cfg.wall_thickness + 0.2
    pairs = []
    for i in range(len(rooms)):
        for j in range(i + 1, len(rooms)):
            edge = _shared_edge(rooms[i], rooms[j])
            if edge is not None and edge[3] - edge[2] >= 2 * margin:
                corridor = "corridor" in (rooms[i].kind, rooms[j].kind)
                pairs.append((0.0 if corridor else 1.0 + rng.random(), i, j, edge))
    pairs.sort(key=lambda p: p[0])
    parent = list(range(len(rooms)))

    def find(i):
        while parent[i] != i:
            i = parent[i]
        return i

    doors = []
    for _, i, j, (axis, coord, lo, hi) in pairs:
        joined = find(i) != find(j)
        if joined or rng.random() < 0.25:
            parent[find(i)] = find(j)
            centre = float(np.round(rng.uniform(lo + margin, hi - margin), 2))
            doors.append(Door(axis, coord, centre, cfg.door_width))
    assert len({find(i) for i in range(len(rooms))}) == 1, "room adjacency is not connected"
    return doors


# --------------------------------------------------------------------------- walls
def _wall_lines(rooms: list[Room]) -> list[tuple[str, float, float, float]]:
    """Every wall line once: each room's max-x and max-z edges plus the footprint's min edges."""
    x_min = min(r.x0 for r in rooms)
    z_min = min(r.z0 for r in rooms)
    lines = []
    for r in rooms:
        lines.append(("x", r.z1, r.x0, r.x1))
        lines.append(("z", r.x1, r.z0, r.z1))
        if r.z0 == z_min:
            lines.append(("x", r.z0, r.x0, r.x1))
        if r.x0 == x_min:
            lines.append(("z", r.x0, r.z0, r.z1))
    return lines


def _cut_doors(line, doors: list[Door]) -> list[tuple[float, float]]:
    """Pieces of a wall line left after cutting the doorways lying on it."""
    axis, coord, lo, hi = line
    pieces = [(lo, hi)]
    for d in doors:
        if d.axis != axis or abs(d.coord - coord) > 1e-6:
            continue
        a, b = d.centre - d.width / 2, d.centre + d.width / 2
        pieces = [q for p0, p1 in pieces for q in ((p0, min(p1, a)), (max(p0, b), p1)) if q[1] - q[0] > 1e-6]
    return pieces


def _box_along(axis: str, coord: float, lo: float, hi: float, t: float, y0: float, y1: float):
    if axis == "x":
        return np.array([lo, y0, coord - t / 2]), np.array([hi, y1, coord + t / 2])
    return np.array([coord - t / 2, y0, lo]), np.array([coord + t / 2, y1, hi])


# --------------------------------------------------------------------------- furniture
def _legs(w, d, h, leg=0.05):
    corners = [(x, z) for x in (0.02, w - leg - 0.02) for z in (0.02, d - leg - 0.02)]
    return [((x, 0.0, z), (x + leg, h, z + leg)) for x, z in corners]


def _table(rng):
    w, d = rng.uniform(1.0, 1.6), rng.uniform(0.7, 0.95)
    return w, d, [*_legs(w, d, 0.72), ((0, 0.72, 0), (w, 0.76, d))], "furniture_wood"


def _desk(rng):
    w, d = rng.uniform(1.0, 1.4), rng.uniform(0.55, 0.7)
    drawers = ((w - 0.42, 0.0, 0), (w - 0.02, 0.71, d))
    return w, d, [*_legs(w, d, 0.71), ((0, 0.71, 0), (w, 0.75, d)), drawers], "furniture_dark"


def _chair(rng):
    w = d = 0.45
    seat, back = ((0, 0.44, 0), (w, 0.48, d)), ((0, 0.48, 0), (w, 0.9, 0.05))
    return w, d, [*_legs(w, d, 0.44), seat, back], "furniture_wood"


def _shelf(rng):
    w, d, h = rng.uniform(0.8, 1.4), 0.35, rng.uniform(1.7, 2.1)
    parts = [((0, 0, 0), (w, h, 0.02)), ((0, 0, 0), (0.03, h, d)), ((w - 0.03, 0, 0), (w, h, d))]
    parts += [((0.03, y, 0.02), (w - 0.03, y + 0.025, d)) for y in np.linspace(0.0, h - 0.025, 5)]
    books = [((x, y + 0.025, 0.05), (x + 0.12, y + 0.025 + rng.uniform(0.15, 0.28), d - 0.04))
             for y in np.linspace(0.0, h - 0.025, 5)[:-1] for x in (0.1, w / 2) if rng.random() < 0.6]
    return w, d, parts + books, "furniture_dark"


def _sofa(rng):
    w, d = rng.uniform(1.6, 2.2), 0.9
    return w, d, [((0, 0, 0), (w, 0.45, d)), ((0, 0.45, 0), (w, 0.85, 0.2)),
                  ((0, 0.45, 0), (0.18, 0.65, d)), ((w - 0.18, 0.45, 0), (w, 0.65, d))], "fabric_a"


def _bed(rng):
    w, d = rng.uniform(1.4, 1.8), 2.0
    return w, d, [((0, 0, 0), (w, 0.5, d)), ((0, 0, 0), (w, 1.05, 0.06)),
                  ((0.1, 0.5, 0.1), (w - 0.1, 0.62, 0.5))], "fabric_b"


def _cabinet(rng):
    w, d, h = rng.uniform(0.8, 1.8), 0.55, rng.uniform(0.85, 0.95)
    return w, d, [((0, 0, 0), (w, h, d))], "white_board"


def _boxes(rng):
    w, d = rng.uniform(0.4, 0.7), rng.uniform(0.4, 0.6)
    h1 = rng.uniform(0.3, 0.5)
    parts = [((0, 0, 0), (w, h1, d))]
    if rng.random() < 0.6:
        parts.append(((0.05, h1, 0.05), (w - 0.08, h1 + rng.uniform(0.25, 0.4), d - 0.1)))
    return w, d, parts, "cardboard"


_FURNITURE = {
    "bedroom": (_bed, _shelf, _desk, _chair, _boxes),
    "living": (_sofa, _table, _shelf, _chair, _cabinet),
    "kitchen": (_cabinet, _table, _chair, _chair, _boxes),
    "office": (_desk, _chair, _shelf, _boxes, _cabinet),
    "corridor": (_cabinet, _boxes),
}
_MATERIAL_OVERRIDES = {"fabric_a": ("fabric_a", "fabric_b"), "fabric_b": ("fabric_b", "fabric_a")}


def _furniture_boxes(rng, room: Room, make, t: float):
    """Place one item with its back to a random wall (lz = 0 at the wall), or free standing for
    tables; returns its world boxes and footprint (x0, z0, x1, z1), or None if it does not fit."""
    w, d, parts, material = make(rng)
    material = rng.choice(_MATERIAL_OVERRIDES.get(material, (material,)))
    inset = t / 2 + 0.02
    x0, z0, x1, z1 = room.x0 + inset, room.z0 + inset, room.x1 - inset, room.z1 - inset
    side = int(rng.integers(0, 4))
    along = (x1 - x0) if side in (0, 1) else (z1 - z0)
    across = (z1 - z0) if side in (0, 1) else (x1 - x0)
    if along < w + 0.05 or across < d + 0.8:
        return None
    s = rng.uniform(0.0, along - w)
    off = 0.0 if make not in (_table,) else rng.uniform(0.6, max(0.6, across - d - 0.6))
    boxes = []
    for lo, hi in parts:
        (lx0, ly0, lz0), (lx1, ly1, lz1) = lo, hi
        lz0, lz1 = lz0 + off, lz1 + off
        if side == 0:  # against the z0 wall, facing +z
            b = ((x0 + s + lx0, ly0, z0 + lz0), (x0 + s + lx1, ly1, z0 + lz1))
        elif side == 1:  # against the z1 wall, facing -z
            b = ((x0 + s + lx0, ly0, z1 - lz1), (x0 + s + lx1, ly1, z1 - lz0))
        elif side == 2:  # against the x0 wall, facing +x
            b = ((x0 + lz0, ly0, z0 + s + lx0), (x0 + lz1, ly1, z0 + s + lx1))
        else:  # against the x1 wall, facing -x
            b = ((x1 - lz1, ly0, z0 + s + lx0), (x1 - lz0, ly1, z0 + s + lx1))
        boxes.append((np.array(b[0]), np.array(b[1]), str(material)))
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
        for d in house.doors:
            lo, hi = _box_along(d.axis, d.coord, d.centre - d.width / 2, d.centre + d.width / 2,
                                t + 0.02, 0, 1)
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
    zones = []
    for d in house.doors:
        half = d.width / 2 + 0.1
        a, b = d.centre - half, d.centre + half
        c0, c1 = d.coord - cfg.door_clearance, d.coord + cfg.door_clearance
        zones.append((a, c0, b, c1) if d.axis == "x" else (c0, a, c1, b))
    return zones


def _overlaps(a, b, gap: float = 0.0) -> bool:
    return a[0] < b[2] + gap and b[0] < a[2] + gap and a[1] < b[3] + gap and b[1] < a[3] + gap


def furnish(house: House, rng, cfg: HouseConfig) -> None:
    """Add 1-5 furniture items per room (by room kind), never blocking doorways or disconnecting
    the agent-free space (checked on a coarse grid after each item)."""
    free = _FreeSpace(house, cfg)
    blocked = _door_zones(house, cfg)
    kinds = ("bedroom", "living", "kitchen", "office")
    for room in house.rooms:
        if room.kind != "corridor":
            room.kind = str(rng.choice(kinds))
        makers = _FURNITURE[room.kind]
        n_items = int(rng.integers(1, 3)) if room.kind == "corridor" else int(rng.integers(2, 6))
        for _ in range(n_items * 4):
            if n_items == 0:
                break
            placed = _furniture_boxes(rng, room, makers[int(rng.integers(len(makers)))], cfg.wall_thickness)
            if placed is None or any(_overlaps(placed[1], z, 0.05) for z in blocked):
                continue
            free.set_rect(placed[1], True)
            if free.n_components() != 1:
                free.set_rect(placed[1], False)
                continue
            house.boxes += placed[0]
            blocked.append(placed[1])
            n_items -= 1


# --------------------------------------------------------------------------- mesh
def make_layout(name: str, seed: int, cfg: HouseConfig, furniture_seed: int = 0) -> House:
    """The plan of `small-<seed>` / `medium-<seed>`: rooms, doors, materials, furniture."""
    rng = np.random.default_rng([seed, 0 if name.startswith("small") else 1])
    rooms = _small_layout(rng, cfg) if name.startswith("small") else _medium_layout(rng, cfg)
    rooms.sort(key=lambda r: (r.z0, r.x0))
    n = 0
    for r in rooms:
        if r.kind == "corridor":
            r.name = "corridor"
        else:
            n += 1
            r.name = f"room {n}"
        r.wall = str(rng.choice(WALL_MATERIALS))
        r.floor = "floor_tiles" if r.kind == "corridor" else str(rng.choice(FLOOR_MATERIALS))
    doors = _place_doors(rng, rooms, cfg)
    ceiling = float(np.round(rng.uniform(*cfg.ceiling_range), 2))
    house = House(name=name, rooms=rooms, doors=doors, ceiling=ceiling)
    furnish(house, np.random.default_rng([seed, 2, furniture_seed]), cfg)
    return house


def house_mesh(house: House, atlas_seed: int, cfg: HouseConfig, plain: bool = False):
    """Triangle mesh of a plan: floors, ceilings, walls (interior faces only), lintels, furniture;
    plain=True gives every surface its material's flat colour instead of the textured atlas."""
    builder = MeshBuilder(build_atlas(atlas_seed))
    t, h = cfg.wall_thickness, house.ceiling
    for r in house.rooms:
        builder.add_box((r.x0, -0.05, r.z0), (r.x1, 0.0, r.z1), r.floor, faces=("+y",))
        builder.add_box((r.x0, h, r.z0), (r.x1, h + 0.05, r.z1), "ceiling", faces=("-y",))

    def wall_material(centre, normal):
        room = house.room_at(centre[0] + 0.06 * normal[0], centre[2] + 0.06 * normal[2])
        return None if room is None else room.wall

    side_faces = ("+x", "-x", "+z", "-z")
    for line in _wall_lines(house.rooms):
        axis, coord, lo, hi = line
        for a, b in _cut_doors(line, house.doors):
            a = a - t / 2 if a == lo else a
            b = b + t / 2 if b == hi else b
            builder.add_box(*_box_along(axis, coord, a, b, t, 0.0, h), wall_material, faces=side_faces)
    for d in house.doors:
        half = d.width / 2
        lo, hi = _box_along(d.axis, d.coord, d.centre - half, d.centre + half, t, cfg.door_height, h)
        broad = ("+z", "-z") if d.axis == "x" else ("+x", "-x")
        builder.add_box(lo, hi, wall_material, faces=("-y", *broad))
    for lo, hi, material in house.boxes:
        builder.add_box(lo, hi, material)
    return builder.build(plain=plain)
