"""Procedural house plans over many seeds: room counts, non-overlapping rectangles, consistent names, every
room reachable through doors and openings, the layout families and their features; and, through
build_house for a few seeds, a connected navigable space that reaches every room and every doorway."""

import itertools

import numpy as np
import pytest

from activesplat.sim import HouseConfig, load_scene
from activesplat.sim.house import MEDIUM_FAMILIES, SMALL_FAMILIES, make_layout
from activesplat.sim.rooms import shared_edge

CFG = HouseConfig()
SEEDS = list(range(40))
SHOWCASE = [0, 1, 2, 3, *range(100, 110)]
"""The seeds the docs and benchmarks use; together they must show every feature."""


def _layout(kind: str, seed: int):
    return make_layout(f"{kind}-{seed}", seed, CFG)


def _layouts(seeds):
    return [_layout(kind, seed) for kind in ("small", "medium") for seed in seeds]


def _connected(nodes, graph) -> bool:
    nodes = list(nodes)
    seen, todo = {nodes[0]}, [nodes[0]]
    while todo:
        for m in graph[todo.pop()]:
            if m in nodes and m not in seen:
                seen.add(m)
                todo.append(m)
    return seen == set(nodes)


@pytest.fixture(scope="module")
def layouts():
    return _layouts(SEEDS)


def test_room_counts_names_and_kinds(layouts):
    for house in layouts:
        kind = house.name.split("-")[0]
        low, high = getattr(CFG, f"{kind}_rooms")
        assert low <= house.n_rooms <= high, house.name
        assert all(r.name for r in house.rooms), house.name
        names = house.room_names
        assert len(names) == len(set(names)) and set(names) == {r.name for r in house.rooms}
        assert house.n_rooms == len(set(names) - set(house.corridor_names))
        for name in names:  # one kind, wall and floor per room
            rects = [r for r in house.rooms if r.name == name]
            assert len({(r.kind, r.wall, r.floor) for r in rects}) == 1, (house.name, name)
            assert (rects[0].kind == "corridor") == (name in house.corridor_names)
        if kind == "small":
            assert not house.corridor_names and house.family in SMALL_FAMILIES
        else:
            assert house.corridor_names == ["corridor"] and house.family in MEDIUM_FAMILIES


def test_rectangles_do_not_overlap_and_rooms_are_contiguous(layouts):
    for house in layouts:
        for a, b in itertools.combinations(house.rooms, 2):
            overlap_x = min(a.x1, b.x1) - max(a.x0, b.x0)
            overlap_z = min(a.z1, b.z1) - max(a.z0, b.z0)
            assert overlap_x <= 1e-9 or overlap_z <= 1e-9, (house.name, a, b)
            assert min(a.x1 - a.x0, a.z1 - a.z0) >= 1.2 - 1e-9
        for name in house.room_names:  # the rectangles of one room touch along a wall (no wall there)
            rects = [r for r in house.rooms if r.name == name]
            graph = {i: {j for j in range(len(rects)) if j != i and shared_edge(rects[i], rects[j])}
                     for i in range(len(rects))}
            assert _connected(range(len(rects)), graph), (house.name, name)


def test_every_room_is_reachable_through_doors_and_openings(layouts):
    for house in layouts:
        assert _connected(house.room_names, house.adjacency()), house.name
        for d in house.doors:  # a door lies within the shared wall of exactly two rooms
            a, b = d.centre - d.width / 2, d.centre + d.width / 2
            sides = set()
            for r in house.rooms:
                lo, hi, c0, c1 = (r.x0, r.x1, r.z0, r.z1) if d.axis == "x" else (r.z0, r.z1, r.x0, r.x1)
                if (abs(c0 - d.coord) < 1e-6 or abs(c1 - d.coord) < 1e-6) and lo < b and a < hi:
                    assert lo - 1e-6 <= a and b <= hi + 1e-6, (house.name, d, r)
                    sides.add((r.name, abs(c0 - d.coord) < 1e-6))
            assert len(sides) == 2 and len({n for n, _ in sides}) == 2, (house.name, d, sides)
            assert CFG.narrow_door_width[0] - 1e-9 <= d.width, (house.name, d)


def test_layouts_are_deterministic():
    for kind, seed in (("small", 5), ("medium", 7), ("medium", 11)):
        a, b = _layout(kind, seed), _layout(kind, seed)
        assert a.rooms == b.rooms and a.doors == b.doors and a.family == b.family
        assert len(a.boxes) == len(b.boxes)
        for (lo, hi, m), (lo2, hi2, m2) in zip(a.boxes, b.boxes, strict=True):
            np.testing.assert_array_equal(lo, lo2)
            np.testing.assert_array_equal(hi, hi2)
            assert m == m2


def _features(house) -> set[str]:
    found = {f"family:{house.name.split('-')[0]}:{house.family}"}
    names = {}
    for r in house.rooms:
        names.setdefault(r.name, []).append(r)
    if any(len(rs) > 1 and rs[0].kind != "corridor" for rs in names.values()):
        found.add("non-rectangular room")
    if len(names.get("corridor", [])) > 1:
        found.add("L-shaped corridor")
    graph = house.adjacency()
    corridors = set(house.corridor_names)
    if corridors and any(not graph[n] & corridors for n in house.room_names if n not in corridors):
        found.add("room reached only through rooms")
    if corridors and len(graph["corridor"]) >= 8:
        found.add("corridor with many doors")
    widths = [d.width for d in house.doors]
    found |= {"narrow door"} if min(widths) < 0.8 else set()
    found |= {"wide opening"} if max(widths) >= 1.4 else set()
    found |= {"opening without lintel"} if any(not d.lintel for d in house.doors) else set()
    if any(d.height is not None and d.height > CFG.door_height for d in house.doors):
        found.add("opening under a beam")
    kinds = {r.kind for r in house.rooms}
    if {"living", "kitchen"} <= kinds:
        for d in house.doors:
            if d.width >= CFG.open_plan_min_width:
                found.add("wide opening >= 1.6 m")
    for lo, hi, _ in house.boxes:
        size = hi - lo
        if abs(hi[1] - 0.9) < 1e-6 and lo[1] > 0.8 and max(size[0], size[2]) >= 1.6:
            found.add("counter")
        if lo[1] == 0.0 and hi[1] == 0.5 and max(size[0], size[2]) >= 1.95:
            found.add("bed")
        if hi[1] > 1.6 and min(size[0], size[2]) < 0.05:
            found.add("shelf")
        if abs(lo[1] - 0.72) < 1e-6 and abs(hi[1] - 0.76) < 1e-6:
            found.add("table on legs")
        if abs(lo[1] - 0.44) < 1e-6 and abs(hi[1] - 0.48) < 1e-6:
            found.add("chair on legs")
    return found


def test_showcase_seeds_show_every_feature():
    found = set().union(*(_features(h) for h in _layouts(SHOWCASE)))
    wanted = {f"family:small:{f}" for f in SMALL_FAMILIES} | {f"family:medium:{f}" for f in MEDIUM_FAMILIES}
    wanted |= {"non-rectangular room", "L-shaped corridor", "room reached only through rooms",
               "corridor with many doors", "narrow door", "wide opening", "wide opening >= 1.6 m",
               "opening without lintel", "opening under a beam", "counter", "bed", "shelf", "table on legs",
               "chair on legs"}
    assert wanted <= found, sorted(wanted - found)


@pytest.mark.parametrize("name", ["small-105", "small-101", "medium-102", "medium-0"])
def test_built_house_free_space_reaches_every_room_and_doorway(name):
    """l-room, open-plan, l-corridor, open-plan: one navigable component that holds cells of every room
    (by name) and of every doorway, narrow doors included."""
    scene = load_scene(name)
    navmap, house = scene.navmap, scene.house
    secondary = (navmap.grid & ~navmap.largest).sum() * navmap.resolution**2
    assert secondary <= 0.05
    for room in house.room_names:
        cells = 0
        for r in (r for r in house.rooms if r.name == room):
            ix, iz = navmap.cell_of([r.x0 + 0.1, r.x1 - 0.1], [r.z0 + 0.1, r.z1 - 0.1])
            cells += navmap.largest[ix[0] : ix[1], iz[0] : iz[1]].sum()
        assert cells * navmap.resolution**2 > 1.0, (name, room)
    for d in house.doors:
        a, b = d.centre - d.width / 2, d.centre + d.width / 2
        xs, zs = ([a, b], [d.coord, d.coord]) if d.axis == "x" else ([d.coord, d.coord], [a, b])
        ix, iz = navmap.cell_of(xs, zs)
        assert navmap.largest[ix[0] : ix[1] + 1, iz[0] : iz[1] + 1].any(), (name, d)
