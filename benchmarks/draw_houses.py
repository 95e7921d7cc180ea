"""Built-in houses seen from above: the figure docs/houses.png.

    python benchmarks/draw_houses.py --out docs/houses.png
    python benchmarks/draw_houses.py --out houses.png --houses small-3 medium-139 --columns 2

Each panel is one house's plan as the generator made it: the rooms coloured by kind (living room,
kitchen, bedroom, office, corridor) with their names, the doors and openings by kind (narrow door, door,
wide opening under a beam, wide opening open to the ceiling) and the outline of every furniture part.
Drawn from above, x to the right and z down, like an episode's topdown.png and trajectory.png. The plan is
the scene's own (`activesplat.sim.load_scene(name).house`, furniture as refurnished to keep the floor in
one piece), so the figure shows the houses the benchmarks run in.
"""

from __future__ import annotations

import argparse
import math

from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from activesplat.errors import InvalidInputError, SceneError, check_output_file
from activesplat.sim import load_scene
from activesplat.sim.rooms import HouseConfig
from activesplat.viz.trajectory import largest_part

HOUSES = ("small-105", "small-101", "medium-106", "medium-0", "medium-103", "medium-104")
"""The houses of docs/houses.png: every layout family, small and medium."""

ROOM_COLOURS = {"living": "#fde3b0", "kitchen": "#d4f2c4", "bedroom": "#cfe0fb", "office": "#f2d4ee",
                "corridor": "#e3e3e3"}
FURNITURE = "#8b6d4f"
DOOR_STYLES = {
    "narrow door (< 0.8 m)": {"color": "#e0191b", "linestyle": "-"},
    "door": {"color": "#1f4fd8", "linestyle": "-"},
    "wide opening, beam above": {"color": "#1b8a1b", "linestyle": "-"},
    "wide opening, no lintel": {"color": "#1b8a1b", "linestyle": (0, (1, 1.5))},
}


def door_kind(door, cfg: HouseConfig) -> str:
    """The legend entry of a door: narrow, ordinary, or a wide opening with or without a beam above."""
    if door.width < cfg.normal_door_width[0] - 1e-9:
        return "narrow door (< 0.8 m)"
    if door.width < cfg.wide_opening_width[0] - 1e-9:
        return "door"
    return "wide opening, beam above" if door.lintel else "wide opening, no lintel"


def wall_pieces(lo: float, hi: float, cuts: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """What is left of the interval [lo, hi] once the intervals `cuts` are taken out of it."""
    pieces = [(lo, hi)]
    for a, b in cuts:
        pieces = [p for start, end in pieces for p in ((start, min(end, a)), (max(start, b), end))
                  if p[1] - p[0] > 1e-6]
    return pieces


def draw_house(ax, house, cfg: HouseConfig) -> None:
    """One house's plan on `ax`, from above (z down)."""
    for room in house.rooms:
        ax.add_patch(Rectangle((room.x0, room.z0), room.x1 - room.x0, room.z1 - room.z0,
                               facecolor=ROOM_COLOURS.get(room.kind, "white"), edgecolor="none"))
    for lo, hi, _ in house.boxes:  # furniture parts: their footprint
        ax.add_patch(Rectangle((lo[0], lo[2]), hi[0] - lo[0], hi[2] - lo[2], facecolor="none",
                               edgecolor=FURNITURE, linewidth=0.6, alpha=0.8))
    gaps = [(axis, coord, lo, hi) for axis, coord, lo, hi in house.open_walls]
    gaps += [(d.axis, d.coord, d.centre - d.width / 2, d.centre + d.width / 2) for d in house.doors]
    for room in house.rooms:  # walls: every rectangle side, less the open sides within a room and the doors
        for axis, coord, lo, hi in (("x", room.z0, room.x0, room.x1), ("x", room.z1, room.x0, room.x1),
                                    ("z", room.x0, room.z0, room.z1), ("z", room.x1, room.z0, room.z1)):
            cuts = [(a, b) for ax_, c, a, b in gaps if ax_ == axis and abs(c - coord) < 1e-6]
            for a, b in wall_pieces(lo, hi, cuts):
                xs, zs = ((a, b), (coord, coord)) if axis == "x" else ((coord, coord), (a, b))
                ax.plot(xs, zs, color="black", linewidth=1.2, solid_capstyle="butt")
    for door in house.doors:
        lo, hi = door.centre - door.width / 2, door.centre + door.width / 2
        xs, zs = ((lo, hi), (door.coord, door.coord)) if door.axis == "x" else ((door.coord,) * 2, (lo, hi))
        ax.plot(xs, zs, linewidth=2.6, solid_capstyle="butt", **DOOR_STYLES[door_kind(door, cfg)])
    for name in house.room_names:
        big = largest_part(house, name)
        label = name if big.kind == name else f"{name}\n{big.kind}"
        ax.text(0.5 * (big.x0 + big.x1), 0.5 * (big.z0 + big.z1), label, ha="center",
                va="center", fontsize=6.5, zorder=5,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.6})
    x0, x1 = min(r.x0 for r in house.rooms), max(r.x1 for r in house.rooms)
    z0, z1 = min(r.z0 for r in house.rooms), max(r.z1 for r in house.rooms)
    ax.set_xlim(x0 - 0.3, x1 + 0.3)
    ax.set_ylim(z1 + 0.3, z0 - 0.3)  # z down: the plan seen from above (y up)
    ax.set_aspect("equal")
    ax.set_xlabel("world x (m)", fontsize=7)
    ax.set_ylabel("world z (m)", fontsize=7)
    ax.tick_params(labelsize=6)
    ax.set_title(f"{house.name} ({house.family}, {house.n_rooms} rooms)", fontsize=8)


def houses_figure(names: list[str], columns: int = 3) -> Figure:
    """The figure of the houses `names`, `columns` panels per row, with one legend below."""
    cfg = HouseConfig()
    rows = math.ceil(len(names) / columns)
    fig = Figure(figsize=(5.2 * columns, 4.6 * rows + 0.5), dpi=110)
    for i, name in enumerate(names):
        draw_house(fig.add_subplot(rows, columns, i + 1), load_scene(name).house, cfg)
    handles = [Line2D([], [], linewidth=2.6, label=label, **style) for label, style in DOOR_STYLES.items()]
    handles += [Patch(facecolor=colour, edgecolor="none", label=kind)
                for kind, colour in ROOM_COLOURS.items()]
    handles.append(Patch(facecolor="none", edgecolor=FURNITURE, label="furniture parts (footprint)"))
    fig.legend(handles=handles, loc="lower center", ncol=5, fontsize=7, frameon=False)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    return fig


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True, help="PNG to write (docs/houses.png for the docs' figure)")
    parser.add_argument("--houses", nargs="+", default=list(HOUSES), help="built-in house names")
    parser.add_argument("--columns", type=int, default=3, help="panels per row")
    args = parser.parse_args(argv)
    if args.columns < 1:
        parser.error("--columns must be at least 1")
    try:
        check_output_file(args.out, "--out")  # before the houses are built
    except InvalidInputError as err:
        parser.error(str(err))
    try:
        fig = houses_figure(args.houses, args.columns)
    except SceneError as err:  # an unknown name: the loader's message says what is expected
        parser.error(str(err))
    fig.savefig(args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
