"""Simulator speed (targets in the README): one RGB-D step at 256x256 against a bare Embree depth raycast of
the same frame, measured in the same run (target <= 2x), and scene build + navigability map for
medium houses (target < 10 s). Prints a markdown table (median of repeats).

    python benchmarks/sim.py [--scene small-0] [--repeats 50] [--houses medium-0 medium-1 medium-2]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from activesplat.sim import Simulator, load_scene
from activesplat.sim.house import HouseConfig
from activesplat.sim.scene import build_house


def _median_ms(fn, repeats: int) -> float:
    fn()  # warm-up (ray directions cached, Embree BVH touched)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def step_vs_raycast(scene_name: str, repeats: int) -> list[tuple[str, str, str]]:
    """Per-frame ms: the full step (action + Embree hit + z-depth + texture lookup + shading), the
    render alone, and the bare Embree distance query over the same rays of the same pose."""
    scene = load_scene(scene_name)
    sim = Simulator(scene, seed=0)
    sim.reset()
    step_ms = _median_ms(lambda: sim.step("turn_left"), repeats)
    pose = sim.pose
    render_ms = _median_ms(lambda: sim.render(pose), repeats)
    origins, dirs = sim.sensor.world_rays(pose, sim.K, sim.width, sim.height)
    bare_ms = _median_ms(lambda: sim.sensor.distance(origins, dirs), repeats)
    step_name = f"RGB-D step 256x256 ({scene_name}, turn_left)"
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="small-0", help="scene of the step timing")
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--houses", nargs="+", default=["medium-0", "medium-1", "medium-2"])
    args = parser.parse_args()
    rows = step_vs_raycast(args.scene, args.repeats) + build_times(args.houses)
    print("| measurement | time | note |")
    print("|---|---:|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    print(f"\nnumpy {np.__version__}; medians of {args.repeats} repeats; 2-core CPU shared with other work.")


if __name__ == "__main__":
    main()
