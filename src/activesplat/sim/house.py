"""Procedural houses: rooms joined by doors and openings (and corridors in medium houses), thick walls,
floor and ceiling, furniture of several heights, textured surfaces. Deterministic per seed.

A room is one or more axis-aligned rectangles sharing a `name`. Two rectangles of one name have no
wall between them at all (their shared wall is removed over its whole length), so a room can be
L-shaped or otherwise non-rectangular. Two rooms with different names are always separated by a wall
line, even when they are joined by a wide opening: an open-plan living room and kitchen are two
rooms (two names) joined by an opening 1.6 m wide up to the full shared wall, with either wall stubs
beside it or a beam above it. Corridors are rooms of kind "corridor" (an L-shaped corridor is two
rectangles named "corridor") and are not counted in `House.n_rooms`.

Layout families, drawn per seed (probabilities in HouseConfig):

- ``small-<seed>`` (2-4 rooms, no corridor, every room reached through another): ``bsp`` (binary space
  partition of a rectangle), ``l-room`` (a partition with one more rectangle, two of them merged into an
  L-shaped room), ``open-plan`` (a partition where two neighbours are a living room and a kitchen joined
  by a wide opening).
- ``medium-<seed>`` (5-10 rooms plus corridors): ``corridor`` (a straight corridor with rooms on both
  sides; often one room is reached only through its neighbour), ``l-corridor`` (a long L-shaped corridor
  with many doors, rooms along both arms, rooms behind rooms), ``open-plan`` (an L-shaped living room
  open to a kitchen reached only through it, a hall corridor with bedrooms, sometimes one bedroom reached
  only through another).

Doors follow a random spanning tree of the room adjacency by name (corridor edges preferred, barred
pairs left out so that some rooms are reached only through other rooms) plus a few extra loops. Door
widths vary: narrow doors, normal doors and wide openings (no lintel, or a beam higher than a door).
Every room gets its own furniture (a bed in a bedroom, counters in a kitchen, a sofa in a living room,
a desk in an office, tables and chairs on legs, shelves), placed with a coarse free-space connectivity
check (`sim.furniture`); the final mesh navigability map is checked again in scene.py. The wall lines,
with the doorways cut out, are `sim.walls`'.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from activesplat.sim.furniture import furnish
from activesplat.sim.geometry import MeshBuilder
from activesplat.sim.textures import FLOOR_MATERIALS, WALL_MATERIALS, build_atlas
from activesplat.sim.walls import box_along, cut_doors, wall_gaps, wall_lines

SMALL_FAMILIES = ("bsp", "l-room", "open-plan")
MEDIUM_FAMILIES = ("corridor", "l-corridor", "open-plan")


@dataclass(frozen=True)
class HouseConfig:
    """Sizes of the procedural houses (our choices; docs/protocol.md §1 fixes only the agent and sensor)."""

    wall_thickness: float = 0.1
    """Interior and exterior wall thickness in metres."""
    ceiling_range: tuple[float, float] = (2.6, 2.8)
    """Ceiling height range in metres (single floor at y = 0)."""
    door_height: float = 2.1
    """Doorway height; a lintel fills the wall above it."""
    narrow_door_width: tuple[float, float] = (0.75, 0.8)
    """Width range of narrow doors (ours). 0.75 m leaves 0.75 - 2 x 0.2 = 0.35 m of agent centres with the
    navigation clearance (0.1 m radius + two 5 cm cells), so narrow doors stay passable."""
    normal_door_width: tuple[float, float] = (0.8, 1.0)
    """Width range of ordinary doors (ours)."""
    wide_opening_width: tuple[float, float] = (1.4, 2.5)
    """Width range of wide openings between two rooms that are neither bedrooms nor corridors (ours)."""
    narrow_door_p: float = 0.2
    """Probability that a door is narrow (ours)."""
    wide_opening_p: float = 0.15
    """Probability that a door between two rooms that may have one (neither a bedroom nor a corridor, and
    a wall long enough) is a wide opening (ours)."""
    wide_no_lintel_p: float = 0.5
    """Probability that a wide opening is open to the ceiling; otherwise a beam tops it (ours)."""
    beam_height: tuple[float, float] = (2.3, 2.45)
    """Height range of the underside of the beam over a wide opening (ours; above door_height)."""
    open_plan_min_width: float = 1.6
    """Narrowest opening between an open-plan living room and kitchen (ours); at most the shared wall."""
    open_plan_full_p: float = 0.4
    """Probability that the open-plan opening spans the whole shared wall (then under a beam; ours)."""
    jamb: float = 0.15
    """Least wall left between a door and the wall across its ends, beyond half a wall thickness (ours)."""
    extra_door_p: float = 0.25
    """Probability of a door between two adjacent rooms beyond the spanning tree (a loop; ours)."""
    min_room_side: float = 2.4
    """Smallest room side in metres."""
    small_rooms: tuple[int, int] = (2, 4)
    """Room count range of small-<seed> (docs/protocol.md §1: small scenes have < 5 rooms)."""
    medium_rooms: tuple[int, int] = (5, 10)
    """Room count range of medium-<seed>, corridors not counted (docs/protocol.md §1: 5-10 rooms)."""
    small_family_p: tuple[float, float, float] = (0.3, 0.35, 0.35)
    """Probabilities of the small families bsp, l-room, open-plan (ours)."""
    medium_family_p: tuple[float, float, float] = (0.35, 0.3, 0.35)
    """Probabilities of the medium families corridor, l-corridor, open-plan (ours)."""
    enfilade_p: float = 0.6
    """Probability that a corridor house bars one room that has another neighbour from the corridor, so it
    is reached only through that neighbour (ours)."""
    corridor_width: tuple[float, float] = (1.2, 1.6)
    """Corridor width range of medium houses."""
    counter_upper_p: float = 0.6
    """Probability that a kitchen counter has wall cabinets above it (ours)."""
    door_clearance: float = 0.9
    """No furniture within this distance of a doorway, on either side."""
    open_wall_clearance: float = 0.35
    """No furniture within this distance of the removed wall inside an L-shaped room (ours)."""
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
    """"corridor", or (set by make_layout) bedroom, living, kitchen or office; one kind per name."""
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
    """A doorway or opening in the wall between two rooms (lo..hi = centre -/+ width/2 along the wall)."""

    axis: str  # "x": the wall runs along x at z = coord; "z": along z at x = coord
    coord: float
    centre: float
    width: float
    height: float | None = None
    """Top of the opening in metres (None: HouseConfig.door_height); a lintel fills the wall above it."""
    lintel: bool = True
    """False: the opening reaches the ceiling (no wall above it)."""


@dataclass
class House:
    """The plan of a procedural house; `mesh` is built by build_house."""

    name: str
    rooms: list[Room]
    doors: list[Door]
    ceiling: float
    boxes: list[tuple[np.ndarray, np.ndarray, str]] = field(default_factory=list)
    family: str = ""
    """Layout family (SMALL_FAMILIES / MEDIUM_FAMILIES)."""

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

    @property
    def open_walls(self) -> list[tuple[str, float, float, float]]:
        """(axis, coord, lo, hi) of every wall segment between two rectangles of one room (no wall there)."""
        return _open_walls(self.rooms)

    def label_points(self, xz: np.ndarray, inset: float = 0.0) -> np.ndarray:
        """Index into `room_names` of the room holding each (x, z) point, -1 outside every room (in a wall
        or outside the house). With `inset` > 0 a point counts only when the square of half-side `inset`
        around it (its corners and edge midpoints) lies in the same room: `inset` metres past the room's
        walls, while the open boundary between two rectangles of one room does not count as a wall."""
        xz = np.asarray(xz, np.float64).reshape(-1, 2)
        out = self._label(xz)
        if inset > 0:
            for dx, dz in ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)):
                out[self._label(xz + inset * np.array([dx, dz], np.float64)) != out] = -1
        return out

    def _label(self, xz: np.ndarray) -> np.ndarray:
        names = self.room_names
        out = np.full(len(xz), -1, np.int64)
        for r in self.rooms:
            inside = ((xz[:, 0] >= r.x0) & (xz[:, 0] <= r.x1) & (xz[:, 1] >= r.z0) & (xz[:, 1] <= r.z1)
                      & (out < 0))
            out[inside] = names.index(r.name)
        return out

    def adjacency(self) -> dict[str, set[str]]:
        """Room names joined by a door or opening (rectangles of one name are joined by definition)."""
        graph: dict[str, set[str]] = {n: set() for n in self.room_names}
        eps = 1e-6
        for d in self.doors:
            a, b = d.centre - d.width / 2, d.centre + d.width / 2
            touching = []
            for r in self.rooms:
                lo, hi, c0, c1 = (r.x0, r.x1, r.z0, r.z1) if d.axis == "x" else (r.z0, r.z1, r.x0, r.x1)
                if (abs(c0 - d.coord) < eps or abs(c1 - d.coord) < eps) and lo < b - eps and a + eps < hi:
                    touching.append(r.name)
            for u in touching:
                graph[u].update(v for v in touching if v != u)
        return graph


# --------------------------------------------------------------------------- layout
_KIND_P = {"bedroom": 0.7, "office": 0.3}
"""Kinds of the rooms left once a house has its living room and kitchen (ours)."""


@dataclass
class _Plan:
    """A layout before naming: rectangles (provisional names: one per room), room kinds the family
    fixes, open-plan pairs (joined by a wide opening) and pairs that must not get a door."""

    family: str
    rooms: list[Room]
    kinds: dict[str, str] = field(default_factory=dict)
    open_pairs: list[tuple[str, str]] = field(default_factory=list)
    barred: set[frozenset] = field(default_factory=set)


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


def _strip(rng, x_total: float, z0: float, z1: float, k: int, min_side: float, x_start: float = 0.0,
           along_z: bool = False) -> list[Room]:
    """k rooms side by side over [x_start, x_start + x_total] along x, spanning z0..z1, each at least
    min_side wide (random split of the rest). along_z: the same along z, (z0, z1) then the x range."""
    spare = x_total - k * min_side
    if spare < 0:
        raise ValueError(f"a strip of {x_total} m cannot hold {k} rooms of {min_side} m")
    widths = min_side + rng.dirichlet(np.full(k, 4.0)) * spare
    edges = np.round(x_start + np.concatenate([[0.0], np.cumsum(widths)]), 2)
    edges[0], edges[-1] = x_start, np.round(x_start + x_total, 2)
    if along_z:
        return [Room(z0, float(a), z1, float(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]
    return [Room(float(a), z0, float(b), z1) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def _r2(x) -> float:
    return float(np.round(x, 2))


def _name_all(rooms: list[Room], prefix: str = "g") -> None:
    for i, r in enumerate(rooms):
        if r.kind != "corridor" and not r.name:
            r.name = f"{prefix}{i}"


def _merge_l(rng, rooms: list[Room]) -> bool:
    """Give two neighbouring rectangles that meet over part of a side one name (an L-shaped room)."""
    pairs = []
    for i, a in enumerate(rooms):
        for b in rooms[i + 1 :]:
            if "corridor" in (a.kind, b.kind) or a.name == b.name:
                continue
            edge = _shared_edge(a, b)
            if edge is None or edge[3] - edge[2] < 1.2:
                continue
            side = (lambda r: r.x1 - r.x0) if edge[0] == "x" else (lambda r: r.z1 - r.z0)
            if edge[3] - edge[2] < max(side(a), side(b)) - 0.5:
                pairs.append((a, b))
    if not pairs:
        return False
    a, b = pairs[int(rng.integers(len(pairs)))]
    old = b.name
    for r in rooms:
        if r.name == old:
            r.name = a.name
    return True


def _pick_open_pair(rng, plan: _Plan, cfg: HouseConfig, need: float) -> bool:
    """Make two neighbouring rooms (shared wall >= need) the open-plan living room and kitchen."""
    pairs = []
    for i, a in enumerate(plan.rooms):
        for b in plan.rooms[i + 1 :]:
            if "corridor" in (a.kind, b.kind) or a.name == b.name:
                continue
            edge = _shared_edge(a, b)
            if edge is not None and edge[3] - edge[2] >= need:
                pairs.append((a.name, b.name))
    if not pairs:
        return False
    a, b = pairs[int(rng.integers(len(pairs)))]
    area = {n: sum(r.area for r in plan.rooms if r.name == n) for n in (a, b)}
    living, kitchen = (a, b) if area[a] >= area[b] else (b, a)
    plan.kinds[living], plan.kinds[kitchen] = "living", "kitchen"
    plan.open_pairs.append((living, kitchen))
    return True


def _open_need(cfg: HouseConfig) -> float:
    return cfg.open_plan_min_width + cfg.wall_thickness + 2 * cfg.jamb


def _small_plan(rng, cfg: HouseConfig, family: str) -> _Plan | None:
    n = int(rng.integers(cfg.small_rooms[0], cfg.small_rooms[1] + 1))
    m = n + (family == "l-room")
    area = m * rng.uniform(11.0, 18.0) * (0.8 if family == "l-room" else 1.0)
    aspect = rng.uniform(1.0, 1.6)
    width = _r2(np.sqrt(area * aspect))
    depth = _r2(area / width)
    depth = max(depth, cfg.min_room_side * (1 if m <= 2 else 2) + 0.2)
    rooms = _split(rng, [Room(0.0, 0.0, width, depth)], m, cfg.min_room_side)
    if len(rooms) != m:
        return None
    _name_all(rooms)
    plan = _Plan(family, rooms)
    if family == "l-room" and not _merge_l(rng, rooms):
        return None
    if family == "open-plan" and not _pick_open_pair(rng, plan, cfg, _open_need(cfg)):
        return None
    if family == "l-room" and n >= 3 and rng.random() < 0.4:
        _pick_open_pair(rng, plan, cfg, _open_need(cfg))
    return plan


def _bar_one_from_corridor(rng, plan: _Plan, candidates: list[str]) -> None:
    """Bar one candidate room that has a non-corridor neighbour from every corridor (enfilade)."""
    corridor = {r.name for r in plan.rooms if r.kind == "corridor"}
    ok = []
    for name in candidates:
        mine = [r for r in plan.rooms if r.name == name]
        neighbours = {o.name for r in mine for o in plan.rooms
                      if o.name != name and _shared_edge(r, o) is not None
                      and _shared_edge(r, o)[3] - _shared_edge(r, o)[2] >= 1.5}
        if neighbours - corridor:
            ok.append(name)
    if ok:
        name = ok[int(rng.integers(len(ok)))]
        plan.barred.update(frozenset((name, c)) for c in corridor)


def _corridor_plan(rng, cfg: HouseConfig, n: int) -> _Plan:
    """A straight corridor with rooms on both sides."""
    k_south = n // 2 + int(rng.integers(0, n % 2 + 1))
    k_north = n - k_south
    width = _r2(max(k_south, k_north) * rng.uniform(3.0, 4.2))
    depth_s = _r2(rng.uniform(3.2, 5.0))
    depth_n = _r2(rng.uniform(3.2, 5.0))
    corridor = _r2(rng.uniform(*cfg.corridor_width))
    rooms = _strip(rng, width, 0.0, depth_s, k_south, cfg.min_room_side)
    rooms.append(Room(0.0, depth_s, width, depth_s + corridor, kind="corridor", name="corridor"))
    rooms += _strip(rng, width, depth_s + corridor, depth_s + corridor + depth_n, k_north, cfg.min_room_side)
    _name_all(rooms)
    plan = _Plan("corridor", rooms)
    if rng.random() < cfg.enfilade_p:
        _bar_one_from_corridor(rng, plan, [r.name for r in rooms if r.kind != "corridor"])
    return plan


def _l_corridor_plan(rng, cfg: HouseConfig, n: int) -> _Plan | None:
    """A long L-shaped corridor: one arm along x with rooms on both sides, the other arm up the east
    end with a column of rooms west of it; the block between holds rooms, some behind others."""
    c = _r2(rng.uniform(*cfg.corridor_width))
    k_e = int(rng.integers(2, 4))
    k_s = int(rng.integers(2, 5))
    k_w = n - k_e - k_s
    if not 1 <= k_w <= 4:
        return None
    col_w = _r2(rng.uniform(3.0, 4.0))
    arm = _r2(k_e * rng.uniform(2.8, 3.6))
    west = _r2(max(k_w * rng.uniform(10.0, 14.0) / arm, cfg.min_room_side + 0.4))
    width = _r2(west + col_w + c)
    if k_s < 2 or width < k_s * (cfg.min_room_side + 0.4):
        return None
    depth_s = _r2(rng.uniform(3.2, 4.8))
    z_arm = _r2(depth_s + c)
    rooms = _strip(rng, width, 0.0, depth_s, k_s, cfg.min_room_side)
    rooms.append(Room(0.0, depth_s, width, z_arm, kind="corridor", name="corridor"))
    rooms.append(Room(_r2(width - c), z_arm, width, _r2(z_arm + arm), kind="corridor", name="corridor"))
    rooms += _strip(rng, arm, _r2(west), _r2(width - c), k_e, cfg.min_room_side, x_start=z_arm, along_z=True)
    block = _split(rng, [Room(0.0, z_arm, west, _r2(z_arm + arm))], k_w, cfg.min_room_side)
    if len(block) != k_w:
        return None
    rooms += block
    _name_all(rooms)
    return _Plan("l-corridor", rooms)


def _open_plan(rng, cfg: HouseConfig, n: tuple[int, int]) -> _Plan | None:
    """An L-shaped living room (a south rectangle and a west column), a kitchen beside it reached only
    through it, a hall corridor east of the column with bedrooms north of it and maybe more rooms
    south of it."""
    c = _r2(rng.uniform(*cfg.corridor_width))
    depth_s = _r2(rng.uniform(3.6, 5.0))
    depth_n = _r2(rng.uniform(3.2, 4.6))
    col = _r2(rng.uniform(2.6, 3.6))
    living_w = _r2(col + rng.uniform(1.8, 3.0))
    kitchen_w = _r2(rng.uniform(2.6, 3.4))
    k_n = int(rng.integers(2, 7))
    north_w = _r2(k_n * rng.uniform(2.8, 3.5))
    width = _r2(max(col + north_w, living_w + kitchen_w))
    spare = width - living_w - kitchen_w
    k_s = int(spare // 3.0)
    if not n[0] <= 2 + k_n + k_s <= n[1]:
        return None
    if k_s == 0:  # no room for another south room: the living room and kitchen share the rest
        living_w = _r2(living_w + spare / 2)
        kitchen_w = _r2(width - living_w)
    z_c, top = _r2(depth_s + c), _r2(depth_s + c + depth_n)
    rooms = [Room(0.0, 0.0, living_w, depth_s, name="living"), Room(0.0, depth_s, col, top, name="living"),
             Room(living_w, 0.0, _r2(living_w + kitchen_w), depth_s, name="kitchen")]
    if k_s:
        rooms += _strip(rng, _r2(width - living_w - kitchen_w), 0.0, depth_s, k_s, cfg.min_room_side,
                        x_start=_r2(living_w + kitchen_w))
    rooms.append(Room(col, depth_s, width, z_c, kind="corridor", name="corridor"))
    rooms += _strip(rng, _r2(width - col), z_c, top, k_n, cfg.min_room_side, x_start=col)
    _name_all(rooms)
    plan = _Plan("open-plan", rooms, kinds={"living": "living", "kitchen": "kitchen"},
                 open_pairs=[("living", "kitchen")], barred={frozenset(("kitchen", "corridor"))})
    if rng.random() < cfg.enfilade_p:
        _bar_one_from_corridor(rng, plan, [r.name for r in rooms if r.z0 == z_c])
    return plan


def _medium_plan(rng, cfg: HouseConfig, family: str) -> _Plan | None:
    lo, hi = cfg.medium_rooms
    if family == "l-corridor":
        lo = max(lo, 7)
    n = int(rng.integers(lo, hi + 1))
    if family == "corridor":
        return _corridor_plan(rng, cfg, n)
    return _l_corridor_plan(rng, cfg, n) if family == "l-corridor" else _open_plan(rng, cfg, cfg.medium_rooms)


def _shared_edge(a: Room, b: Room) -> tuple[str, float, float, float] | None:
    """(axis, coord, lo, hi) of the wall segment two rooms share, if any."""
    for p, q in ((a, b), (b, a)):
        if abs(p.x1 - q.x0) < 1e-6:
            lo, hi = max(p.z0, q.z0), min(p.z1, q.z1)
            if hi > lo + 1e-6:
                return "z", p.x1, lo, hi
        if abs(p.z1 - q.z0) < 1e-6:
            lo, hi = max(p.x0, q.x0), min(p.x1, q.x1)
            if hi > lo + 1e-6:
                return "x", p.z1, lo, hi
    return None


def _open_walls(rooms: list[Room]) -> list[tuple[str, float, float, float]]:
    out = []
    for i, a in enumerate(rooms):
        for b in rooms[i + 1 :]:
            if a.name == b.name:
                edge = _shared_edge(a, b)
                if edge is not None:
                    out.append(edge)
    return out


def _door(rng, edge, cfg: HouseConfig, wide_ok: bool) -> Door | None:
    """A door on a shared wall: narrow, normal or (wide_ok) a wide opening, as the wall allows."""
    axis, coord, lo, hi = edge
    room = hi - lo - cfg.wall_thickness - 2 * cfg.jamb  # widest opening that keeps both jambs
    u = rng.random()
    if u < cfg.narrow_door_p:
        width = rng.uniform(*cfg.narrow_door_width)
    elif wide_ok and u < cfg.narrow_door_p + cfg.wide_opening_p and room >= cfg.wide_opening_width[0]:
        width = rng.uniform(cfg.wide_opening_width[0], min(cfg.wide_opening_width[1], room))
    else:
        width = rng.uniform(*cfg.normal_door_width)
    width = float(np.floor(min(width, room) * 100 + 1e-6) / 100)
    if width < cfg.narrow_door_width[0] - 1e-9:
        return None
    margin = width / 2 + cfg.wall_thickness / 2 + cfg.jamb
    centre = _r2(rng.uniform(lo + margin, max(lo + margin, hi - margin)))
    centre = min(max(centre, lo + margin), hi - margin)
    if width >= cfg.wide_opening_width[0]:
        return _wide(rng, axis, coord, centre, width, cfg)
    return Door(axis, coord, centre, width)


def _wide(rng, axis, coord, centre, width, cfg: HouseConfig, beam: bool = False) -> Door:
    if not beam and rng.random() < cfg.wide_no_lintel_p:
        return Door(axis, coord, centre, width, lintel=False)
    return Door(axis, coord, centre, width, height=_r2(rng.uniform(*cfg.beam_height)))


def _open_plan_door(rng, edge, cfg: HouseConfig) -> Door:
    """The opening between an open-plan living room and kitchen: the whole shared wall under a beam, or
    open_plan_min_width up to the wall less its jambs."""
    axis, coord, lo, hi = edge
    if rng.random() < cfg.open_plan_full_p:
        return _wide(rng, axis, coord, (lo + hi) / 2, hi - lo, cfg, beam=True)
    room = hi - lo - cfg.wall_thickness - 2 * cfg.jamb
    width = float(np.floor(rng.uniform(cfg.open_plan_min_width, max(cfg.open_plan_min_width, min(room, 3.2)))
                           * 100) / 100)
    margin = width / 2 + cfg.wall_thickness / 2 + cfg.jamb
    centre = min(max(_r2(rng.uniform(lo + margin, max(lo + margin, hi - margin))), lo + margin), hi - margin)
    return _wide(rng, axis, coord, centre, width, cfg)


def _place_doors(rng, rooms: list[Room], cfg: HouseConfig, plan: _Plan) -> list[Door]:
    """Open-plan openings, then a random spanning tree of the adjacency between room names (corridor
    edges first, barred pairs only if the house cannot be connected without them) plus extra loops."""
    names = list(dict.fromkeys(r.name for r in rooms))
    kind = {r.name: r.kind for r in rooms}
    shortest = cfg.narrow_door_width[0] + cfg.wall_thickness + 2 * cfg.jamb
    edges: dict[frozenset, list] = {}
    for i, a in enumerate(rooms):
        for b in rooms[i + 1 :]:
            edge = _shared_edge(a, b) if a.name != b.name else None
            if edge is not None and edge[3] - edge[2] >= shortest:
                edges.setdefault(frozenset((a.name, b.name)), []).append(edge)
    parent = {n: n for n in names}

    def find(n):
        while parent[n] != n:
            n = parent[n]
        return n

    doors = []
    for a, b in plan.open_pairs:
        options = sorted(edges[frozenset((a, b))], key=lambda e: -(e[3] - e[2]))
        doors.append(_open_plan_door(rng, options[0], cfg))
        parent[find(a)] = find(b)
    done = {frozenset(p) for p in plan.open_pairs}
    order = []
    for key in sorted(edges, key=lambda k: sorted(k)):
        corridor = any(kind[n] == "corridor" for n in key)
        order.append(((0.0 if corridor else 1.0) + rng.random(), key))
    order.sort(key=lambda p: p[0])
    for allow_barred in (False, True):
        for _, key in order:
            if key in done or ((key in plan.barred) != allow_barred):
                continue
            a, b = sorted(key)
            joined = find(a) != find(b)
            if not joined and (allow_barred or rng.random() >= cfg.extra_door_p):
                continue
            options = edges[key]
            edge = options[int(rng.integers(len(options)))]
            wide_ok = "bedroom" not in (kind[a], kind[b]) and "corridor" not in (kind[a], kind[b])
            door = _door(rng, edge, cfg, wide_ok)
            if door is None:
                continue
            doors.append(door)
            done.add(key)
            parent[find(a)] = find(b)
        if len({find(n) for n in names}) == 1:
            break
    assert len({find(n) for n in names}) == 1, "room adjacency is not connected"
    return doors


# --------------------------------------------------------------------------- walls
# --------------------------------------------------------------------------- mesh
def make_layout(name: str, seed: int, cfg: HouseConfig, furniture_seed: int = 0) -> House:
    """The plan of `small-<seed>` / `medium-<seed>`: layout family, rooms (named), doors, materials,
    furniture. A family that cannot realise its draw retries with the same generator (deterministic);
    after 50 failures the house falls back to the plain partition (small) or straight corridor (medium)."""
    small = name.startswith("small")
    rng = np.random.default_rng([seed, 0 if small else 1])
    families, p = (SMALL_FAMILIES, cfg.small_family_p) if small else (MEDIUM_FAMILIES, cfg.medium_family_p)
    family = families[int(rng.choice(len(families), p=p))]
    plan = None
    for _ in range(50):
        plan = _small_plan(rng, cfg, family) if small else _medium_plan(rng, cfg, family)
        if plan is not None:
            break
    if plan is None:
        if small:
            n = int(rng.integers(cfg.small_rooms[0], cfg.small_rooms[1] + 1))
            rooms = _split(rng, [Room(0.0, 0.0, 8.0, 6.0)], n, cfg.min_room_side)
            _name_all(rooms)
            plan = _Plan("bsp", rooms)
        else:
            plan = _corridor_plan(rng, cfg, int(rng.integers(cfg.medium_rooms[0], cfg.medium_rooms[1] + 1)))
    rooms = sorted(plan.rooms, key=lambda r: (r.z0, r.x0))
    rename, n = {}, 0
    for r in rooms:
        if r.name not in rename:
            if r.kind == "corridor":
                rename[r.name] = "corridor"
            else:
                n += 1
                rename[r.name] = f"room {n}"
    kinds = {rename[k]: v for k, v in plan.kinds.items()}
    area = {}
    for r in rooms:
        if r.kind != "corridor":
            area[rename[r.name]] = area.get(rename[r.name], 0.0) + r.area
    for new in sorted(area, key=lambda k: -area[k]):  # the largest free rooms: living room, then kitchen
        if new in kinds:
            continue
        missing = [k for k in ("living", "kitchen") if k not in kinds.values()]
        if missing and (missing[0] == "living" or len(area) > 3 or rng.random() < 0.5):
            kinds[new] = missing[0]
        else:
            kinds[new] = str(rng.choice(list(_KIND_P), p=list(_KIND_P.values())))
    materials = {}
    for new in rename.values():
        materials[new] = (str(rng.choice(WALL_MATERIALS)),
                          "floor_tiles" if new == "corridor" else str(rng.choice(FLOOR_MATERIALS)))
    for r in rooms:
        r.name = rename[r.name]
        if r.kind != "corridor":
            r.kind = kinds[r.name]
        r.wall, r.floor = materials[r.name]
    plan.open_pairs = [(rename[a], rename[b]) for a, b in plan.open_pairs]
    plan.barred = {frozenset(rename[n] for n in key) for key in plan.barred}
    doors = _place_doors(rng, rooms, cfg, plan)
    ceiling = _r2(rng.uniform(*cfg.ceiling_range))
    house = House(name=name, rooms=rooms, doors=doors, ceiling=ceiling, family=plan.family)
    furnish(house, np.random.default_rng([seed, 2, furniture_seed]), cfg)
    return house


def house_mesh(house: House, atlas_seed: int, cfg: HouseConfig, plain: bool = False):
    """Triangle mesh of a plan: floors, ceilings, walls (interior faces only), lintels and beams,
    furniture; plain=True gives every surface its material's flat colour instead of the textured atlas."""
    builder = MeshBuilder(build_atlas(atlas_seed))
    t, h = cfg.wall_thickness, house.ceiling
    for r in house.rooms:
        builder.add_box((r.x0, -0.05, r.z0), (r.x1, 0.0, r.z1), r.floor, faces=("+y",))
        builder.add_box((r.x0, h, r.z0), (r.x1, h + 0.05, r.z1), "ceiling", faces=("-y",))

    def wall_material(centre, normal):
        room = house.room_at(centre[0] + 0.06 * normal[0], centre[2] + 0.06 * normal[2])
        return None if room is None else room.wall

    side_faces = ("+x", "-x", "+z", "-z")
    gaps = wall_gaps(house)
    for line in wall_lines(house.rooms):
        axis, coord, lo, hi = line
        for a, b in cut_doors(line, gaps):
            a = a - t / 2 if a == lo else a
            b = b + t / 2 if b == hi else b
            builder.add_box(*box_along(axis, coord, a, b, t, 0.0, h), wall_material, faces=side_faces)
    for d in house.doors:
        top = cfg.door_height if d.height is None else d.height
        if not d.lintel or top >= h - 1e-6:
            continue
        half = d.width / 2
        lo, hi = box_along(d.axis, d.coord, d.centre - half, d.centre + half, t, top, h)
        broad = ("+z", "-z") if d.axis == "x" else ("+x", "-x")
        builder.add_box(lo, hi, wall_material, faces=("-y", *broad))
    for lo, hi, material in house.boxes:
        builder.add_box(lo, hi, material)
    return builder.build(plain=plain)
