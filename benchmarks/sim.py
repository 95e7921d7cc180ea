"""Simulator speed (targets in the README): one RGB-D step at 256x256 against a bare Embree depth
raycast of the same frame, measured in the same run (target <= 2x), scene build + navigability map
for medium houses (target < 10 s), and loading a generated furnished glb of ~1M faces and 50
materials with their own tiling textures and samplers (target < 10 s, with the time per stage).
Prints a markdown table (median of repeats). The generated glb is written to a temporary folder.

    python benchmarks/sim.py [--scene small-0] [--repeats 50] [--houses medium-0 medium-1 medium-2]
                             [--faces 1000000] [--materials 50]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from activesplat.sim import Scene, SimConfig, Simulator, load_scene
from activesplat.sim.gltf import read_gltf, write_glb
from activesplat.sim.house import HouseConfig
from activesplat.sim.materials import CLAMP_TO_EDGE, MIRRORED_REPEAT, REPEAT, Material, Surface
from activesplat.sim.scene import build_house, choose_storey, find_storeys


def _median_ms(fn, repeats: int) -> float:
    """Median CPU time (process_time) per call in ms: steadier than wall time on a shared machine;
    the sensor is single-threaded (numpy, numba kernel, one Embree query per frame)."""
    fn()  # warm-up (ray directions cached, Embree BVH touched, kernel compiled)
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return 1e3 * statistics.median(times)


def step_vs_raycast(scene: str | Scene, repeats: int,
                    texture_filter: str = "area") -> list[tuple[str, str, str]]:
    """Per-frame ms: the full step (action + Embree hit + z-depth + texture lookup + shading), the
    render alone, and the bare Embree distance query over the same rays of the same pose."""
    scene = load_scene(scene) if isinstance(scene, str) else scene
    scene_name = Path(scene.name).name
    sim = Simulator(scene, seed=0, config=SimConfig(texture_filter=texture_filter))
    sim.reset()
    step_ms = _median_ms(lambda: sim.step("turn_left"), repeats)
    pose = sim.pose
    render_ms = _median_ms(lambda: sim.render(pose), repeats)
    origins, dirs = sim.sensor.world_rays(pose, sim.K, sim.width, sim.height)
    bare_ms = _median_ms(lambda: sim.sensor.distance(origins, dirs), repeats)
    step_name = f"RGB-D step 256x256 ({scene_name}, turn_left, {texture_filter} texture filter)"
    return [
        (step_name, f"{step_ms:.1f} ms", f"{step_ms / bare_ms:.2f}x bare (target <= 2x)"),
        ("  render only", f"{render_ms:.1f} ms", f"{render_ms / bare_ms:.2f}x bare"),
        ("  bare Embree depth raycast, same frame", f"{bare_ms:.1f} ms", "1.00x"),
    ]


def build_times(names: list[str]) -> list[tuple[str, str, str]]:
    """Wall time of build_house (layout, furniture, mesh, navmap and connectivity check) per house."""
    rows = []
    for name in names:
        t0 = time.perf_counter()
        scene = build_house(name, HouseConfig())
        seconds = time.perf_counter() - t0
        navmap = scene.navmap
        detail = f"{scene.rooms} rooms, {len(scene.mesh.faces)} faces, {navmap.navigable_area:.0f} m^2 free"
        rows.append((f"build + navmap {name}", f"{seconds:.2f} s", f"{detail} (target < 10 s)"))
    return rows


def furnished_glb(path: Path, faces: int, materials: int, seed: int = 0) -> Path:
    """A 16 x 16 m room (floor, walls, ceiling) filled with textured objects (icospheres and boxes
    on a grid) until ~`faces` triangles; `materials` materials, each with its own 128^2 noise
    texture, UVs from -2 to 4 (tiling) and a sampler cycling repeat / mirrored repeat / clamp."""
    rng = np.random.default_rng(seed)
    mats = []
    for k in range(materials):
        base = rng.uniform(0.2, 0.9, size=3)
        noise = rng.uniform(0.6, 1.0, size=(128, 128, 1)) * base
        wrap = (REPEAT, MIRRORED_REPEAT, CLAMP_TO_EDGE)[k % 3]
        mats.append(Material(f"mat{k:02d}", np.ones(3), np.round(noise * 255).astype(np.uint8), wrap, wrap))
    size, height = 16.0, 3.0
    room = trimesh.creation.box(extents=[size, height, size])
    room.apply_translation([size / 2, height / 2, size / 2])
    room.invert()  # faces point into the room
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.35)  # 20480 faces
    parts = [room]
    n_objects = max(1, (faces - len(room.faces)) // len(sphere.faces))
    side = int(np.ceil(np.sqrt(n_objects)))
    spacing = (size - 2.0) / side
    for i in range(n_objects):
        obj = sphere.copy()
        ix, iz = divmod(i, side)
        obj.apply_translation([1.0 + (ix + 0.5) * spacing, rng.uniform(0.4, 2.0), 1.0 + (iz + 0.5) * spacing])
        parts.append(obj)
    vertices = np.concatenate([p.vertices for p in parts])
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    face_list = np.concatenate([p.faces + o for p, o in zip(parts, offsets, strict=True)])
    face_mat = np.concatenate([np.full(len(p.faces), i % materials) for i, p in enumerate(parts)])
    tri = vertices[face_list]
    uv = np.stack([tri[..., 0] + tri[..., 1], tri[..., 2] + tri[..., 1]], axis=-1) % 6.0 - 2.0  # -2..4
    write_glb(path, vertices, face_list, Surface(mats, face_mat, uv.astype(np.float32)))
    return path


def mesh_load(faces: int, materials: int, repeats: int,
              texture_filter: str = "area") -> list[tuple[str, str, str]]:
    """Load time of a generated furnished glb, by stage, and its sensor step time."""
    def timed(fn):
        wall, cpu = time.perf_counter(), time.process_time()
        out = fn()
        return out, time.perf_counter() - wall, time.process_time() - cpu

    def cell(wall: float, cpu: float) -> str:
        return f"{wall:.2f} s ({cpu:.2f} s CPU)"

    with tempfile.TemporaryDirectory() as folder:
        path = furnished_glb(Path(folder) / "furnished.glb", faces, materials)
        mb = path.stat().st_size / 2**20
        scene, total, total_cpu = timed(lambda: load_scene(path))
        (vertices, face_idx, _), t_read, c_read = timed(lambda: read_gltf(path))
        mesh = trimesh.Trimesh(vertices, face_idx, process=False)
        _, t_storey, c_storey = timed(lambda: choose_storey(find_storeys(mesh), None, str(path)))
        _, t_sensor, c_sensor = timed(lambda: scene.sensor_for(SimConfig()))
        n = len(scene.mesh.faces)
        rows = [(f"load_scene furnished glb ({n / 1e6:.2f}M faces, {materials} materials, {mb:.0f} MB)",
                 cell(total, total_cpu), "target < 10 s"),
                ("  read glTF (JSON, accessors, node transforms, PNG decode)", cell(t_read, c_read), ""),
                ("  storeys (face normals, areas, height bins)", cell(t_storey, c_storey), ""),
                ("  navigability map", cell(total - t_read - t_storey, total_cpu - c_read - c_storey),
                 "remainder of load_scene"),
                ("sensor build (Embree BVH, texel planes), on first Simulator", cell(t_sensor, c_sensor), "")]
        return rows + step_vs_raycast(scene, repeats, texture_filter)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="small-0", help="scene of the step timing")
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--texture-filter", default="area", choices=["area", "nearest"])
    parser.add_argument("--houses", nargs="+", default=["medium-0", "medium-1", "medium-2"])
    parser.add_argument("--faces", type=int, default=1_000_000, help="faces of the generated glb (0: skip)")
    parser.add_argument("--materials", type=int, default=50, help="materials of the generated glb")
    args = parser.parse_args()
    rows = step_vs_raycast(args.scene, args.repeats, args.texture_filter) + build_times(args.houses)
    if args.faces > 0:
        rows += mesh_load(args.faces, args.materials, args.repeats, args.texture_filter)
    print("| measurement | time | note |")
    print("|---|---:|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    print(f"\nnumpy {np.__version__}; per-frame times are medians of {args.repeats} repeats in CPU time; "
          f"loads are wall time (CPU time in brackets).")


if __name__ == "__main__":
    main()
