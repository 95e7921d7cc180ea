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

The data types (HouseConfig, Room, Door, House) are `sim.rooms`' and the floor-plan families and door
placement `sim.layouts`'; this module names the rooms, draws their kinds and materials (make_layout) and
builds the mesh (house_mesh).
"""

from __future__ import annotations

import numpy as np

from activesplat.sim.furniture import furnish
from activesplat.sim.geometry import MeshBuilder
from activesplat.sim.layouts import (
    KIND_P,
    Plan,
    corridor_plan,
    medium_plan,
    name_all,
    place_doors,
    r2,
    small_plan,
    split,
)
from activesplat.sim.rooms import MEDIUM_FAMILIES, SMALL_FAMILIES, Door, House, HouseConfig, Room
from activesplat.sim.textures import FLOOR_MATERIALS, WALL_MATERIALS, build_atlas
from activesplat.sim.walls import box_along, cut_doors, wall_gaps, wall_lines


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
        plan = small_plan(rng, cfg, family) if small else medium_plan(rng, cfg, family)
        if plan is not None:
            break
    if plan is None:
        if small:
            n = int(rng.integers(cfg.small_rooms[0], cfg.small_rooms[1] + 1))
            rooms = split(rng, [Room(0.0, 0.0, 8.0, 6.0)], n, cfg.min_room_side)
            name_all(rooms)
            plan = Plan("bsp", rooms)
        else:
            plan = corridor_plan(rng, cfg, int(rng.integers(cfg.medium_rooms[0], cfg.medium_rooms[1] + 1)))
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
            kinds[new] = str(rng.choice(list(KIND_P), p=list(KIND_P.values())))
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
    doors = place_doors(rng, rooms, cfg, plan)
    ceiling = r2(rng.uniform(*cfg.ceiling_range))
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


# The house types live in sim.rooms; they stay importable from here (scene.py, tests, benchmarks).
__all__ = ["MEDIUM_FAMILIES", "SMALL_FAMILIES", "Door", "House", "HouseConfig", "Room", "house_mesh",
           "make_layout"]
