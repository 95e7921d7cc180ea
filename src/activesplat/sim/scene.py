"""Scenes: built-in procedural houses, user meshes (.glb/.gltf/.ply/.obj) and a box room for tests."""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
import trimesh

from activesplat.errors import InvalidInputError, SceneError, SceneNotFoundError
from activesplat.sim.config import SimConfig
from activesplat.sim.gltf import read_gltf, warn_material, write_glb
from activesplat.sim.house import MEDIUM_FAMILIES, SMALL_FAMILIES, HouseConfig, house_mesh, make_layout
from activesplat.sim.materials import Surface, surface_from_trimesh
from activesplat.sim.navmap import MAX_NAV_CELLS, GridTooLargeError, NavMap, build_navmap
from activesplat.sim.sensor import RGBDSensor, hit_distance
from activesplat.sim.textures import build_atlas

MESH_SUFFIXES = (".glb", ".gltf", ".ply", ".obj")
BUILTIN_PATTERN = re.compile(r"^(small|medium)-(\d+)(-plain)?$")
"""Built-in names: kind, seed, and an optional `-plain` suffix (flat colour per material, no texture)."""
BUILTIN_NAMES = "small-<seed>, medium-<seed> (optionally with -plain)"
DEFAULT_STEPS = {"small": 1000, "medium": 2000, "file": 1000}
"""Step budgets (docs/protocol.md §1: 1000 actions for small scenes, 2000 for medium; 1000 for user
meshes)."""
STOREY_MIN_GAP = 1.8
"""Two levels closer than this (m) are one storey (the agent is 1.5 m tall; tables, sofas, steps)."""
STOREY_MIN_AREA_FRACTION = 0.25
"""A level needs this fraction of the largest level's upward area (furniture tops stay below it)."""
STOREY_SNAP = 0.5
"""--floor HEIGHT picks the storey within this distance (m)."""
STOREY_BAND_BELOW = 0.1
"""In a multi-storey mesh the ground-truth surface of storey k is y in [floor_k, floor_k+1) shifted
down by this (m): its floor and everything up to the underside of the next storey."""
HEADROOM = 1.5
"""A floor has a ceiling at least this high (m, the agent's height) straight above it, or none."""
_MAX_FURNITURE_TRIES = 6
_MAX_SECONDARY_AREA = 0.05
"""Largest navigable area (m^2) allowed outside the main component of a built-in house."""


class Scene:
    """A triangle mesh in the world frame (y up, metres) with its floor height, navigability map
    and Embree sensor. `rooms` is the room count of built-in houses (None for user meshes); `house` their
    plan (rooms by name, doors), None for user meshes."""

    def __init__(self, name: str, mesh: trimesh.Trimesh, floor_height: float, default_steps: int,
                 rooms: int | None = None, surface: Surface | None = None, house=None):
        self.name = name
        self.mesh = mesh
        self.surface = surface if surface is not None else surface_from_trimesh(mesh)
        self.floor_height = float(floor_height)
        self.default_steps = int(default_steps)
        self.rooms = rooms
        self.house = house
        self.storeys: list[Storey] = [Storey(self.floor_height, 0.0)]
        self.surface_band: tuple[float, float] | None = None
        """(low, high) y of the faces that belong to this storey (None: all faces)."""
        self._navmaps: dict[tuple, NavMap] = {}
        self._sensors: dict[SimConfig, RGBDSensor] = {}

    def __repr__(self) -> str:
        size = self.bounds[1] - self.bounds[0]
        return f"Scene({self.name!r}, {len(self.mesh.faces)} faces, {size[0]:.1f} x {size[2]:.1f} m)"

    @cached_property
    def bounds(self) -> np.ndarray:
        """(2, 3) min and max corner of the mesh."""
        return np.asarray(self.mesh.bounds, dtype=np.float64)

    @property
    def navmap(self) -> NavMap:
        """Navigability map for the default agent (SimConfig())."""
        return self.navmap_for(SimConfig())

    def navmap_for(self, config: SimConfig) -> NavMap:
        """Navigability map for an agent's radius, height, step margin and grid cell (cached)."""
        key = (config.agent_radius, config.agent_height, config.step_margin, config.nav_cell,
               config.floor_hole_cells)
        if key not in self._navmaps:
            try:
                navmap = build_navmap(self.mesh.vertices, self.mesh.faces, self.floor_height, config)
            except GridTooLargeError as exc:
                raise SceneError(_too_large(self, exc, config.nav_cell)) from None
            except ValueError as exc:
                raise SceneError(f"scene {self.name!r} has no walkable floor ({exc})") from None
            if not navmap.largest.any():
                raise SceneError(f"scene {self.name!r} has no walkable floor: no place at floor height "
                                 f"{self.floor_height:.2f} m fits the agent (radius {config.agent_radius} m)")
            self._navmaps[key] = navmap
        return self._navmaps[key]

    def sensor_for(self, config: SimConfig) -> RGBDSensor:
        """Embree sensor of this mesh (cached per config)."""
        if config not in self._sensors:
            self._sensors[config] = RGBDSensor(self.mesh, config, surface=self.surface)
        return self._sensors[config]

    def export(self, path) -> Path:
        """Write the exact simulator mesh (world frame, y up, materials with their textures and
        samplers) as binary glTF (.glb)."""
        path = Path(path)
        if path.suffix.lower() != ".glb":
            raise InvalidInputError(f"export file must end in .glb: {path}")
        return write_glb(path, self.mesh.vertices, self.mesh.faces, self.surface)

    def sample_surface(self, n: int, seed: int = 0) -> np.ndarray:
        """(n, 3) points, uniform by area over the whole mesh, reproducible per seed."""
        rng = np.random.default_rng(seed)
        tri = np.asarray(self.mesh.triangles, dtype=np.float64)
        if self.surface_band is not None:  # a multi-storey mesh: this storey's faces only
            y = tri[:, :, 1].mean(axis=1)
            tri = tri[(y >= self.surface_band[0]) & (y < self.surface_band[1])]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        face = rng.choice(len(tri), size=n, p=area / area.sum())
        a, b = rng.random(n), rng.random(n)
        flip = a + b > 1.0
        a[flip], b[flip] = 1.0 - a[flip], 1.0 - b[flip]
        t = tri[face]
        return t[:, 0] + a[:, None] * (t[:, 1] - t[:, 0]) + b[:, None] * (t[:, 2] - t[:, 0])


def _too_large(scene: Scene, exc: GridTooLargeError, cell: float) -> str:
    """The message of a navigability grid beyond MAX_NAV_CELLS: the extent and the likely causes."""
    (x0, z0), (x1, z1) = exc.lo, exc.hi
    return (f"scene {scene.name!r}: the geometry within the agent's height of the floor at y = "
            f"{scene.floor_height:.2f} m spans {x1 - x0:.1f} x {z1 - z0:.1f} m (x {x0:.1f} to {x1:.1f}, "
            f"z {z0:.1f} to {z1:.1f}), a navigability grid of {exc.shape[0]} x {exc.shape[1]} cells of "
            f"{cell} m, more than the {MAX_NAV_CELLS:,} allowed: is the mesh in millimetres or centimetres "
            f"rather than metres, or does it hold stray geometry far from the building? (a larger "
            f"--sim.nav-cell allows a truly larger scene)")


# --------------------------------------------------------------------------- built-in houses
def build_house(name: str, config: HouseConfig | None = None) -> Scene:
    """`small-<seed>` or `medium-<seed>`; refurnishes (new furniture seed) until the navigable space
    is one component (secondary pockets below _MAX_SECONDARY_AREA are tolerated). A `-plain` suffix
    gives the same house (layout, furniture, triangles) with one flat colour per material."""
    config = config or HouseConfig()
    match = BUILTIN_PATTERN.match(name)
    if match is None:
        raise SceneError(f"unknown built-in scene {name!r}: expected {BUILTIN_NAMES}")
    kind, seed, plain = match.group(1), int(match.group(2)), match.group(3) is not None
    for attempt in range(_MAX_FURNITURE_TRIES):
        house = make_layout(f"{kind}-{seed}", seed, config, furniture_seed=attempt)
        mesh = house_mesh(house, seed, config, plain=plain)
        scene = Scene(name, mesh, 0.0, DEFAULT_STEPS[kind], rooms=house.n_rooms, house=house)
        navmap = scene.navmap
        secondary = (navmap.grid & ~navmap.largest).sum() * navmap.resolution**2
        if secondary <= _MAX_SECONDARY_AREA:
            return scene
    raise AssertionError(f"{name}: free space stayed disconnected after {_MAX_FURNITURE_TRIES} tries")


def box_room(width: float = 4.0, depth: float = 3.0, height: float = 2.6, textured: bool = True) -> Scene:
    """A closed box room x in [0, width], y in [0, height], z in [0, depth] (all faces inward);
    textured with plaster/wood, or one flat colour per face when textured=False."""
    from activesplat.sim.geometry import MeshBuilder

    for value in (width, depth, height):
        if not np.isfinite(value) or value <= 0.5:
            raise InvalidInputError(f"box_room sizes must be finite and > 0.5 m, got {value}")
    builder = MeshBuilder(build_atlas(0))
    lo, hi = np.zeros(3), np.array([width, height, depth])
    builder.add_box(lo, [width, 0.0, depth], "floor_wood", faces=("+y",))
    builder.add_box([0.0, height, 0.0], hi, "ceiling", faces=("-y",))
    for face, material in (("+x", "wall_a"), ("-x", "wall_b"), ("+z", "wall_c"), ("-z", "wall_d")):
        axis = {"x": 0, "z": 2}[face[1]]
        box_lo, box_hi = lo.copy(), hi.copy()
        if face[0] == "+":  # the wall at the low end faces +axis (into the room)
            box_hi[axis] = 0.0
        else:
            box_lo[axis] = hi[axis]
        builder.add_box(box_lo, box_hi, material, faces=(face,))
    mesh = builder.build()
    if not textured:
        colours = np.array([[200, 170, 120], [230, 230, 225], [180, 90, 80], [90, 150, 200],
                            [120, 180, 110], [210, 200, 90]], dtype=np.uint8)
        normals = np.round(mesh.face_normals).astype(int)
        which = np.argmax(np.abs(normals), axis=1) * 2 + (normals.max(axis=1) > 0)
        mesh = trimesh.Trimesh(mesh.vertices, mesh.faces, face_colors=colours[which], process=False)
    name = f"box_room-{width:g}x{depth:g}x{height:g}"
    return Scene(name, mesh, 0.0, DEFAULT_STEPS["file"])


# --------------------------------------------------------------------------- user meshes
def _check_mesh(mesh: trimesh.Trimesh, path: Path) -> trimesh.Trimesh:
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise SceneError(f"mesh file {path} contains no triangles")
    if not np.all(np.isfinite(mesh.vertices)):
        raise SceneError(f"mesh file {path} has non-finite vertex coordinates")
    return mesh


def _obj_missing_textures(path: Path) -> None:
    """Warn, per material, about texture files an .obj's material libraries name but that are absent
    (trimesh then shows the material's diffuse colour)."""
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError:
        return
    for lib in (ln.split(None, 1)[1].strip() for ln in lines if ln.startswith("mtllib ") and " " in ln):
        mtl = path.parent / lib
        material = None
        for line in mtl.read_text(errors="replace").splitlines() if mtl.is_file() else []:
            parts = line.split()
            if parts and parts[0] == "newmtl":
                material = " ".join(parts[1:])
            elif parts and parts[0] == "map_Kd" and len(parts) > 1 and not (mtl.parent / parts[-1]).is_file():
                warn_material(path, material, f"texture {parts[-1]!r} is missing")


def _read_mesh(path: Path) -> tuple[trimesh.Trimesh, Surface]:
    """Geometry (no visual) and per-face appearance of a mesh file: glTF through read_gltf (materials,
    samplers, node transforms), .obj as one part per material, .ply as one mesh."""
    suffix = path.suffix.lower()
    try:
        if suffix in (".glb", ".gltf"):
            vertices, faces, surface = read_gltf(path)
            return _check_mesh(trimesh.Trimesh(vertices, faces, process=False), path), surface
        if suffix == ".obj":
            _obj_missing_textures(path)
        loaded = trimesh.load(path, process=False, **({} if suffix == ".obj" else {"force": "mesh"}))
    except SceneError:
        raise
    except Exception as exc:  # the readers raise many types on corrupt files
        raise SceneError(f"cannot read mesh file {path}: {type(exc).__name__}: {exc}") from None
    if isinstance(loaded, trimesh.Scene):  # one geometry per material, node transforms applied
        parts = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        if not parts:
            raise SceneError(f"mesh file {path} contains no triangles")
        surface = Surface.concatenate([surface_from_trimesh(g, name=f"material {i}")
                                       for i, g in enumerate(parts)])
        mesh = trimesh.util.concatenate([trimesh.Trimesh(g.vertices, g.faces, process=False) for g in parts])
        return _check_mesh(mesh, path), surface
    mesh = _check_mesh(loaded, path)
    return mesh, surface_from_trimesh(mesh)


@dataclass(frozen=True)
class Storey:
    """A level of a mesh: floor height (m), upward-facing area in its height bin (m^2), and whether
    nothing lies above it (a flat roof or an open terrace rather than a floor under a ceiling)."""

    height: float
    area: float
    open_above: bool = False

    def describe(self, index: int) -> str:
        kind = "open above (roof?)" if self.open_above else "under a ceiling"
        return f"{index}: y = {self.height:.2f} m, {self.area:.1f} m^2, {kind}"


def _horizontal_faces(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """Masks of the near-horizontal faces (normal within ~25 deg of vertical) that floors and ceilings are
    made of: floors face +y and ceilings -y, the other way round in a mesh wound inside out (told apart by
    `_headroom`); every horizontal face is a floor candidate when none faces up."""
    normals, areas = mesh.face_normals, mesh.area_faces
    upward, downward = normals[:, 1] > 0.9, normals[:, 1] < -0.9
    if not areas[upward].sum() > 0:
        return upward | downward, np.zeros_like(upward)
    if areas[downward].sum() > 0:
        room_up, room_down = _headroom(mesh, upward, downward)
        if room_down > max(2.0 * room_up, 0.25 * areas[downward].sum()):  # a good share under a ceiling
            return downward, upward
    return upward, downward


def _upward_faces(mesh: trimesh.Trimesh, floors: np.ndarray | None = None):
    """Heights, areas and centres of the floor candidates (`_horizontal_faces`, unless given)."""
    floors = _horizontal_faces(mesh)[0] if floors is None else floors
    if not mesh.area_faces[floors].sum() > 0:
        raise SceneError("mesh has no horizontal faces, so no walkable floor")
    centres = mesh.triangles_center[floors]
    return centres[:, 1], mesh.area_faces[floors], centres


def _headroom(mesh: trimesh.Trimesh, *masks: np.ndarray, n: int = 512) -> list[float]:
    """Per mask of faces, the area (m^2) with room to stand above it: a surface at least HEADROOM higher
    straight above (a ceiling), estimated from `n` area-sampled points each. A floor has it; a ceiling taken
    as a floor (faces wound inside out) has nothing or its storey's slab above it."""
    rng = np.random.default_rng(0)
    picks = [rng.choice(len(mask), size=n, p=mesh.area_faces * mask / mesh.area_faces[mask].sum())
             for mask in masks]
    origins = mesh.triangles_center[np.concatenate(picks)] + [0.0, 0.02, 0.0]
    distance = hit_distance(mesh.vertices, mesh.faces, origins, np.tile([0.0, 1.0, 0.0], (len(origins), 1)))
    room = ((distance >= HEADROOM) & (distance < 1e6)).reshape(len(masks), n).mean(axis=1)
    return [float(mesh.area_faces[mask].sum() * r) for mask, r in zip(masks, room, strict=True)]


def _median_height(h: np.ndarray, a: np.ndarray) -> float:
    order = np.argsort(h)
    cum = np.cumsum(a[order])
    return float(h[order][np.searchsorted(cum, 0.5 * cum[-1])])


def find_storeys(mesh: trimesh.Trimesh, bin_size: float = 0.05, min_gap: float = STOREY_MIN_GAP,
                 floors: np.ndarray | None = None) -> list[Storey]:
    """Levels of a mesh, bottom to top: height bins of upward area at least STOREY_MIN_AREA_FRACTION
    of the largest (and 1 m^2), greedily kept by area when at least `min_gap` from a kept one. With
    several, each is tested for geometry above it (vertical rays from area-sampled floor points).
    `floors`: the mask of floor faces (default `_horizontal_faces`)."""
    h, a, centres = _upward_faces(mesh, floors)
    bins = np.floor((h - h.min()) / bin_size).astype(np.int64)
    area = np.bincount(bins, weights=a)
    threshold = min(area.max(), max(1.0, STOREY_MIN_AREA_FRACTION * area.max()))  # largest always kept
    kept: list[int] = []
    for b in np.argsort(-area, kind="stable"):
        if area[b] < threshold:
            break
        if all(abs(int(b) - k) * bin_size >= min_gap for k in kept):
            kept.append(int(b))
    kept.sort()
    storeys = [Storey(_median_height(h[bins == b], a[bins == b]), float(area[b])) for b in kept]
    if len(storeys) == 1:
        return storeys
    rng = np.random.default_rng(0)
    picks = []
    for b in kept:
        idx = np.flatnonzero(bins == b)
        picks.append(rng.choice(idx, size=min(256, len(idx)), p=a[idx] / a[idx].sum()))
    origins = centres[np.concatenate(picks)] + [0.0, 0.02, 0.0]
    up = np.tile([0.0, 1.0, 0.0], (len(origins), 1))
    covered = np.split(hit_distance(mesh.vertices, mesh.faces, origins, up) < 1e6,
                       np.cumsum([len(p) for p in picks])[:-1])
    return [Storey(s.height, s.area, open_above=bool(c.mean() < 0.5))
            for s, c in zip(storeys, covered, strict=True)]


def choose_storey(storeys: list[Storey], floor: int | float | None, name: str) -> tuple[float, float]:
    """(floor height, height of the next storey above or inf) for `floor`: None (the only storey
    under a ceiling, else the only storey), an int index from the bottom, or a float height in metres."""
    listing = "; ".join(s.describe(i) for i, s in enumerate(storeys))
    hint = "choose one with --floor INDEX (0 = lowest) or --floor HEIGHT in metres (e.g. 3.0)"
    if floor is None:
        indoor = [i for i, s in enumerate(storeys) if not s.open_above]
        candidates = indoor if indoor else list(range(len(storeys)))
        if len(candidates) > 1:
            raise SceneError(f"{name} has {len(candidates)} storeys ({listing}); {hint}")
        index = candidates[0]
    elif isinstance(floor, (int, np.integer)) and not isinstance(floor, bool):
        if not 0 <= floor < len(storeys):
            raise SceneError(f"{name}: --floor {floor} is not a storey index ({listing})")
        index = int(floor)
    else:
        height = float(floor)
        near = [i for i, s in enumerate(storeys) if abs(s.height - height) <= STOREY_SNAP]
        if not np.isfinite(height) or not near:
            raise SceneError(f"{name}: no storey within {STOREY_SNAP} m of --floor {floor} ({listing})")
        index = min(near, key=lambda i: abs(storeys[i].height - height))
    above = [s.height for s in storeys[index + 1 :]]
    return storeys[index].height, (above[0] if above else float("inf"))


def load_mesh_scene(path, z_up: bool = False, floor: int | float | None = None) -> Scene:
    """A user mesh; z_up files are rotated into the y-up world frame ((x, y, z) -> (x, z, -y)).
    `floor` picks the storey of a multi-storey mesh (see choose_storey)."""
    path = Path(path)
    if not path.exists():
        raise SceneNotFoundError(f"scene file not found: {path}")
    if not path.is_file():
        raise SceneError(f"scene path is not a regular file: {path}")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise SceneError(f"unsupported mesh format {path.suffix!r} for {path}: "
                         f"use {', '.join(MESH_SUFFIXES)}")
    mesh, surface = _read_mesh(path)
    if z_up:
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    try:
        floors, ceilings = _horizontal_faces(mesh)
        storeys = find_storeys(mesh, floors=floors)
        height, top = choose_storey(storeys, floor, str(path))
        if floor is None:
            _check_floor_under_ceiling(mesh, ceilings, next(s for s in storeys if s.height == height))
        scene = Scene(str(path), mesh, height, DEFAULT_STEPS["file"], surface=surface)
        scene.storeys = storeys
        if len(storeys) > 1:
            scene.surface_band = (height - STOREY_BAND_BELOW, top - STOREY_BAND_BELOW)
        scene.navmap  # noqa: B018 - raises SceneError when nothing is walkable
    except SceneError as exc:
        msg = str(exc)
        raise SceneError((msg if str(path) in msg else f"{path}: {msg}") + _axis_hint(mesh, z_up)) from None
    return scene


FLOOR_MIN_CEILING_FRACTION = 0.25
"""A floor found on its own needs at least this fraction of the largest ceiling level's area; less is
furniture tops in a mesh without a floor (a scan that missed it, a model exported without it)."""


def _check_floor_under_ceiling(mesh: trimesh.Trimesh, ceilings: np.ndarray, storey: Storey,
                               bin_size: float = 0.05) -> None:
    """SceneError when the floor found is much smaller than the largest level of ceiling faces."""
    if not ceilings.any():
        return  # no ceiling (an open scan): nothing to compare with
    h, a = mesh.triangles_center[ceilings, 1], mesh.area_faces[ceilings]
    level = np.bincount(np.floor((h - h.min()) / bin_size).astype(np.int64), weights=a)
    if storey.area < FLOOR_MIN_CEILING_FRACTION * level.max():
        ceiling = h.min() + bin_size * level.argmax()
        raise SceneError(f"the mesh seems to have no floor: the largest level of upward faces, y = "
                         f"{storey.height:.2f} m, has {storey.area:.1f} m^2 under {level.max():.1f} m^2 of "
                         f"ceiling (y = {ceiling:.2f} m), so the agent would walk on furniture; "
                         f"--floor {storey.height:.2f} walks there anyway")


def _axis_hint(mesh: trimesh.Trimesh, z_up: bool) -> str:
    """For an error about the floor: a hint at --z-up when the mesh, turned, would be lower than it is wide
    but tall enough to stand in, and more of its faces lie flat across z than across y (floors and ceilings
    lie across the up axis)."""
    normals, areas, size = mesh.face_normals, mesh.area_faces, np.ptp(mesh.vertices, axis=0)
    flat = [areas[np.abs(normals[:, axis]) > 0.9].sum() for axis in (1, 2)]
    if not HEADROOM <= size[2] < size[1] or flat[1] <= flat[0]:
        return ""
    return "; the file may be y-up: leave out --z-up" if z_up else "; the file may be z-up: add --z-up"


def load_scene(name, z_up: bool = False, floor: int | float | None = None) -> Scene:
    """A built-in house (`small-<seed>`, `medium-<seed>`, either with `-plain`) or a mesh file
    (.glb/.gltf/.ply/.obj). `floor` chooses the storey of a multi-storey mesh: an int index from the
    bottom or a float height in metres (see find_storeys); built-in houses have one storey (0 or 0.0)."""
    text = str(name)
    if BUILTIN_PATTERN.match(text):
        if floor not in (None, 0) or isinstance(floor, bool):
            raise SceneError(f"{text} has one storey (index 0, y = 0.0 m); got --floor {floor}")
        return build_house(text)
    if Path(text).suffix.lower() in MESH_SUFFIXES or Path(text).exists() or "/" in text:
        return load_mesh_scene(text, z_up=z_up, floor=floor)
    raise SceneError(f"unknown scene {text!r}: expected {BUILTIN_NAMES} or a mesh file "
                     f"({', '.join(MESH_SUFFIXES)})")


def scene_label(name: str) -> str:
    """A scene's name in figure titles and the progress bar: a mesh file by its file name (its full path
    would not fit), any other name as it is."""
    text = str(name)
    return Path(text).name if Path(text).suffix.lower() in MESH_SUFFIXES else text


def describe_builtin_scenes(seeds=(0, 1, 2)) -> str:
    """Text for `activesplat scenes list`: name patterns, layout families and a few examples with
    family, room count and size."""
    config = HouseConfig()
    lines = ["Built-in procedural houses (deterministic per seed; any integer seed works):",
             f"  small-<seed>   {config.small_rooms[0]}-{config.small_rooms[1]} rooms, "
             f"{DEFAULT_STEPS['small']} steps; layout family per seed: "
             f"{' / '.join(SMALL_FAMILIES)}",
             f"  medium-<seed>  {config.medium_rooms[0]}-{config.medium_rooms[1]} rooms + corridor, "
             f"{DEFAULT_STEPS['medium']} steps; layout family per seed: {' / '.join(MEDIUM_FAMILIES)}",
             "                 (rooms may be L-shaped, reached only through other rooms, joined by narrow",
             "                 doors or wide openings; an open-plan living room and kitchen are two rooms)",
             "  <name>-plain   the same house with one flat colour per material (textureless walls),",
             "                 e.g. small-0-plain, medium-2-plain",
             "  or a mesh file: .glb .gltf .ply .obj (y up; --z-up for z-up files)", "",
             f"{'name':<12}{'family':>12}{'rooms':>6}{'size (m)':>14}{'floor (m^2)':>13}"]
    for kind in ("small", "medium"):
        for seed in seeds:
            house = make_layout(f"{kind}-{seed}", seed, config)
            xs = [r.x1 for r in house.rooms]
            zs = [r.z1 for r in house.rooms]
            area = sum(r.area for r in house.rooms)
            size = f"{max(xs):.1f} x {max(zs):.1f}"
            lines.append(f"{kind + '-' + str(seed):<12}{house.family:>12}{house.n_rooms:>6}{size:>14}"
                         f"{area:>13.1f}")
    return "\n".join(lines)
