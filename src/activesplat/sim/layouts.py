"""Floor plans of the procedural houses: the layout families (small: bsp, l-room, open-plan; medium:
corridor, l-corridor, open-plan) as rectangles with provisional room names, and the doors between rooms
(open-plan openings, a random spanning tree of the room adjacency plus extra loops). `make_layout` in
`sim.house` names the rooms and furnishes them."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from activesplat.sim.rooms import Door, HouseConfig, Room, shared_edge

KIND_P = {"bedroom": 0.7, "office": 0.3}
"""Kinds of the rooms left once a house has its living room and kitchen (ours)."""


@dataclass
class Plan:
    """A layout before naming: rectangles (provisional names: one per room), room kinds the family
    fixes, open-plan pairs (joined by a wide opening) and pairs that must not get a door."""

    family: str
    rooms: list[Room]
    kinds: dict[str, str] = field(default_factory=dict)
    open_pairs: list[tuple[str, str]] = field(default_factory=list)
    barred: set[frozenset] = field(default_factory=set)


def split(rng, rooms: list[Room], n: int, min_side: float) -> list[Room]:
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


def r2(x) -> float:
    return float(np.round(x, 2))


def name_all(rooms: list[Room], prefix: str = "g") -> None:
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
            edge = shared_edge(a, b)
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


def _pick_open_pair(rng, plan: Plan, cfg: HouseConfig, need: float) -> bool:
    """Make two neighbouring rooms (shared wall >= need) the open-plan living room and kitchen."""
    pairs = []
    for i, a in enumerate(plan.rooms):
        for b in plan.rooms[i + 1 :]:
            if "corridor" in (a.kind, b.kind) or a.name == b.name:
                continue
            edge = shared_edge(a, b)
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


def small_plan(rng, cfg: HouseConfig, family: str) -> Plan | None:
    n = int(rng.integers(cfg.small_rooms[0], cfg.small_rooms[1] + 1))
    m = n + (family == "l-room")
    area = m * rng.uniform(11.0, 18.0) * (0.8 if family == "l-room" else 1.0)
    aspect = rng.uniform(1.0, 1.6)
    width = r2(np.sqrt(area * aspect))
    depth = r2(area / width)
    depth = max(depth, cfg.min_room_side * (1 if m <= 2 else 2) + 0.2)
    rooms = split(rng, [Room(0.0, 0.0, width, depth)], m, cfg.min_room_side)
    if len(rooms) != m:
        return None
    name_all(rooms)
    plan = Plan(family, rooms)
    if family == "l-room" and not _merge_l(rng, rooms):
        return None
    if family == "open-plan" and not _pick_open_pair(rng, plan, cfg, _open_need(cfg)):
        return None
    if family == "l-room" and n >= 3 and rng.random() < 0.4:
        _pick_open_pair(rng, plan, cfg, _open_need(cfg))
    return plan


def _bar_one_from_corridor(rng, plan: Plan, candidates: list[str]) -> None:
    """Bar one candidate room that has a non-corridor neighbour from every corridor (enfilade)."""
    corridor = {r.name for r in plan.rooms if r.kind == "corridor"}
    ok = []
    for name in candidates:
        mine = [r for r in plan.rooms if r.name == name]
        neighbours = {o.name for r in mine for o in plan.rooms
                      if o.name != name and shared_edge(r, o) is not None
                      and shared_edge(r, o)[3] - shared_edge(r, o)[2] >= 1.5}
        if neighbours - corridor:
            ok.append(name)
    if ok:
        name = ok[int(rng.integers(len(ok)))]
        plan.barred.update(frozenset((name, c)) for c in corridor)


def corridor_plan(rng, cfg: HouseConfig, n: int) -> Plan:
    """A straight corridor with rooms on both sides."""
    k_south = n // 2 + int(rng.integers(0, n % 2 + 1))
    k_north = n - k_south
    width = r2(max(k_south, k_north) * rng.uniform(3.0, 4.2))
    depth_s = r2(rng.uniform(3.2, 5.0))
    depth_n = r2(rng.uniform(3.2, 5.0))
    corridor = r2(rng.uniform(*cfg.corridor_width))
    rooms = _strip(rng, width, 0.0, depth_s, k_south, cfg.min_room_side)
    rooms.append(Room(0.0, depth_s, width, depth_s + corridor, kind="corridor", name="corridor"))
    rooms += _strip(rng, width, depth_s + corridor, depth_s + corridor + depth_n, k_north, cfg.min_room_side)
    name_all(rooms)
    plan = Plan("corridor", rooms)
    if rng.random() < cfg.enfilade_p:
        _bar_one_from_corridor(rng, plan, [r.name for r in rooms if r.kind != "corridor"])
    return plan


def _l_corridor_plan(rng, cfg: HouseConfig, n: int) -> Plan | None:
    """A long L-shaped corridor: one arm along x with rooms on both sides, the other arm up the east
    end with a column of rooms west of it; the block between holds rooms, some behind others."""
    c = r2(rng.uniform(*cfg.corridor_width))
    k_e = int(rng.integers(2, 4))
    k_s = int(rng.integers(2, 5))
    k_w = n - k_e - k_s
    if not 1 <= k_w <= 4:
        return None
    col_w = r2(rng.uniform(3.0, 4.0))
    arm = r2(k_e * rng.uniform(2.8, 3.6))
    west = r2(max(k_w * rng.uniform(10.0, 14.0) / arm, cfg.min_room_side + 0.4))
    width = r2(west + col_w + c)
    if k_s < 2 or width < k_s * (cfg.min_room_side + 0.4):
        return None
    depth_s = r2(rng.uniform(3.2, 4.8))
    z_arm = r2(depth_s + c)
    rooms = _strip(rng, width, 0.0, depth_s, k_s, cfg.min_room_side)
    rooms.append(Room(0.0, depth_s, width, z_arm, kind="corridor", name="corridor"))
    rooms.append(Room(r2(width - c), z_arm, width, r2(z_arm + arm), kind="corridor", name="corridor"))
    rooms += _strip(rng, arm, r2(west), r2(width - c), k_e, cfg.min_room_side, x_start=z_arm, along_z=True)
    block = split(rng, [Room(0.0, z_arm, west, r2(z_arm + arm))], k_w, cfg.min_room_side)
    if len(block) != k_w:
        return None
    rooms += block
    name_all(rooms)
    return Plan("l-corridor", rooms)


def _open_plan(rng, cfg: HouseConfig, n: tuple[int, int]) -> Plan | None:
    """An L-shaped living room (a south rectangle and a west column), a kitchen beside it reached only
    through it, a hall corridor east of the column with bedrooms north of it and maybe more rooms
    south of it."""
    c = r2(rng.uniform(*cfg.corridor_width))
    depth_s = r2(rng.uniform(3.6, 5.0))
    depth_n = r2(rng.uniform(3.2, 4.6))
    col = r2(rng.uniform(2.6, 3.6))
    living_w = r2(col + rng.uniform(1.8, 3.0))
    kitchen_w = r2(rng.uniform(2.6, 3.4))
    k_n = int(rng.integers(2, 7))
    north_w = r2(k_n * rng.uniform(2.8, 3.5))
    width = r2(max(col + north_w, living_w + kitchen_w))
    spare = width - living_w - kitchen_w
    k_s = int(spare // 3.0)
    if not n[0] <= 2 + k_n + k_s <= n[1]:
        return None
    if k_s == 0:  # no room for another south room: the living room and kitchen share the rest
        living_w = r2(living_w + spare / 2)
        kitchen_w = r2(width - living_w)
    z_c, top = r2(depth_s + c), r2(depth_s + c + depth_n)
    rooms = [Room(0.0, 0.0, living_w, depth_s, name="living"), Room(0.0, depth_s, col, top, name="living"),
             Room(living_w, 0.0, r2(living_w + kitchen_w), depth_s, name="kitchen")]
    if k_s:
        rooms += _strip(rng, r2(width - living_w - kitchen_w), 0.0, depth_s, k_s, cfg.min_room_side,
                        x_start=r2(living_w + kitchen_w))
    rooms.append(Room(col, depth_s, width, z_c, kind="corridor", name="corridor"))
    rooms += _strip(rng, r2(width - col), z_c, top, k_n, cfg.min_room_side, x_start=col)
    name_all(rooms)
    plan = Plan("open-plan", rooms, kinds={"living": "living", "kitchen": "kitchen"},
                open_pairs=[("living", "kitchen")], barred={frozenset(("kitchen", "corridor"))})
    if rng.random() < cfg.enfilade_p:
        _bar_one_from_corridor(rng, plan, [r.name for r in rooms if r.z0 == z_c])
    return plan


def medium_plan(rng, cfg: HouseConfig, family: str) -> Plan | None:
    lo, hi = cfg.medium_rooms
    if family == "l-corridor":
        lo = max(lo, 7)
    n = int(rng.integers(lo, hi + 1))
    if family == "corridor":
        return corridor_plan(rng, cfg, n)
    return _l_corridor_plan(rng, cfg, n) if family == "l-corridor" else _open_plan(rng, cfg, cfg.medium_rooms)



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
    centre = r2(rng.uniform(lo + margin, max(lo + margin, hi - margin)))
    centre = min(max(centre, lo + margin), hi - margin)
    if width >= cfg.wide_opening_width[0]:
        return _wide(rng, axis, coord, centre, width, cfg)
    return Door(axis, coord, centre, width)


def _wide(rng, axis, coord, centre, width, cfg: HouseConfig, beam: bool = False) -> Door:
    if not beam and rng.random() < cfg.wide_no_lintel_p:
        return Door(axis, coord, centre, width, lintel=False)
    return Door(axis, coord, centre, width, height=r2(rng.uniform(*cfg.beam_height)))


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
    centre = min(max(r2(rng.uniform(lo + margin, max(lo + margin, hi - margin))), lo + margin), hi - margin)
    return _wide(rng, axis, coord, centre, width, cfg)


def place_doors(rng, rooms: list[Room], cfg: HouseConfig, plan: Plan) -> list[Door]:
    """Open-plan openings, then a random spanning tree of the adjacency between room names (corridor
    edges first, barred pairs only if the house cannot be connected without them) plus extra loops."""
    names = list(dict.fromkeys(r.name for r in rooms))
    kind = {r.name: r.kind for r in rooms}
    shortest = cfg.narrow_door_width[0] + cfg.wall_thickness + 2 * cfg.jamb
    edges: dict[frozenset, list] = {}
    for i, a in enumerate(rooms):
        for b in rooms[i + 1 :]:
            edge = shared_edge(a, b) if a.name != b.name else None
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

