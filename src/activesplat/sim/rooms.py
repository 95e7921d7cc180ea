"""Data types of the procedural houses: their sizes (HouseConfig), rooms, doors and the house plan (House),
and the names of the layout families. A room is one or more axis-aligned rectangles sharing a name (see
`sim.house`); `shared_edge` finds the wall two rectangles share. The floor plans are `sim.layouts`'."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

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



def shared_edge(a: Room, b: Room) -> tuple[str, float, float, float] | None:
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
                edge = shared_edge(a, b)
                if edge is not None:
                    out.append(edge)
    return out

