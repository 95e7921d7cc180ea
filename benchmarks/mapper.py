"""Online mapper benchmark: a scripted look-around-and-walk in a built-in scene (paper sec. III-A).

    python benchmarks/mapper.py [--scene small-0] [--steps 300] [--backend auto] [--seed 0]

Trajectory: the release's bootstrap look-around (36 x turn_left, each followed by one tilt in a
down,down,down,up,up,up pattern; dense schedule), then a walk: move forward, and on a blocked move
turn on the spot by a seeded random 60-120 deg (dense schedule while turning, as the release does for
on-the-spot rotations). Afterwards every keyframe (train view) is rendered from the final map:
PSNR (full image, colours clamped to [0,1]) and depth L1 (cm, over valid depth). Prints markdown.
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

import numpy as np
import torch

from activesplat.sim import Simulator, load_scene
from activesplat.splat import Mapper, MapperConfig

TILTS = ("look_down", "look_down", "look_down", "look_up", "look_up", "look_up")


def bootstrap_actions() -> list[str]:
    """docs/protocol.md §1: one tilt after each of the 36 turns, ~72 actions, ending level."""
    actions = []
    for i in range(36):
        actions += ["turn_left", TILTS[i % len(TILTS)]]
    return actions


def warm_up(sim: Simulator, backend: str, config: MapperConfig) -> None:
    """Compile the JIT kernels (numba) outside the timed episode: map the start view twice."""
    mapper = Mapper(sim.K, sim.width, sim.height, config, backend=backend)
    obs = sim.reset()
    for _ in range(2):
        mapper.add_frame(obs.rgb, obs.depth, obs.pose, dense=True)


def timed_add_frame(mapper: Mapper, obs, dense: bool, cpu_ms: list[float]):
    """``mapper.add_frame`` that also records the process CPU time of the call (all threads)."""
    t0 = time.process_time()
    stats = mapper.add_frame(obs.rgb, obs.depth, obs.pose, dense=dense)
    cpu_ms.append(1000.0 * (time.process_time() - t0))
    return stats


def run_episode(scene_name: str, steps: int, backend: str, seed: int, config: MapperConfig,
                cpu_ms: list[float] | None = None):
    sim = Simulator(load_scene(scene_name), seed=seed)
    warm_up(sim, backend, config)
    mapper = Mapper(sim.K, sim.width, sim.height, config, backend=backend)
    rng = np.random.default_rng(seed)
    cpu_ms = [] if cpu_ms is None else cpu_ms
    obs = sim.reset()
    records = [timed_add_frame(mapper, obs, True, cpu_ms)]
    script = bootstrap_actions()
    pending: list[str] = []
    for step in range(steps):
        if step < len(script):
            action, dense = script[step], True
        elif pending:
            action, dense = pending.pop(), True
        else:
            action, dense = "move_forward", False
        obs = sim.step(action)
        if action == "move_forward" and obs.collided:
            pending = [str(rng.choice(["turn_left", "turn_right"]))] * int(rng.integers(6, 13))
        records.append(timed_add_frame(mapper, obs, dense, cpu_ms))
    return mapper, records


def evaluate_keyframes(mapper: Mapper) -> dict[str, float]:
    """Means over the keyframes of the map rendered there: PSNR (dB); depth L1 (cm, over valid GT depth)
    of the rendered depth as the rasterizer defines it (docs/protocol.md §8: alpha-blended sum w_i z_i, *not*
    divided by the opacity; the metric of the target), its signed mean, and two secondary views for diagnosis:
    the opacity-normalised depth sum w_i z_i / O and the median depth; the share of valid pixels whose
    rendered depth is off by more than 10 cm; the mean opacity over valid pixels."""
    rows: dict[str, list[float]] = defaultdict(list)
    for kf in mapper.keyframes:
        out = mapper.render(kf.pose)
        rgb = out.rgb.clamp(0, 1).numpy()
        mse = float(np.mean((rgb - kf.rgb.astype(np.float32) / 255.0) ** 2))
        rows["psnr"].append(-10.0 * np.log10(max(mse, 1e-10)))
        valid = kf.depth > 0
        gt, alpha = kf.depth[valid], out.alpha.numpy()[valid]
        error = out.depth.numpy()[valid] - gt
        rows["depth_l1"].append(100.0 * float(np.abs(error).mean()))
        rows["depth_signed"].append(100.0 * float(error.mean()))
        rows["depth_l1_normalised"].append(
            100.0 * float(np.abs(out.depth.numpy()[valid] / np.maximum(alpha, 1e-6) - gt).mean()))
        rows["depth_l1_median"].append(100.0 * float(np.abs(out.median_depth.numpy()[valid] - gt).mean()))
        rows["share_over_10cm"].append(100.0 * float((np.abs(error) > 0.1).mean()))
        rows["opacity"].append(float(alpha.mean()))
    return {name: float(np.mean(values)) for name, values in rows.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="small-0")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--backend", default="auto")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2, help="torch threads (the target is 2 cores)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    config = MapperConfig()
    t0 = time.perf_counter()
    cpu_ms: list[float] = []
    mapper, records = run_episode(args.scene, args.steps, args.backend, args.seed, config, cpu_ms)
    wall = time.perf_counter() - t0
    q = evaluate_keyframes(mapper)
    n = len(records)
    phases: dict[str, float] = defaultdict(float)
    for r in records:
        for name, ms in r.timings.items():
            phases[name] += ms
    mapped = sum(r.mapped for r in records)
    print(f"## Mapper benchmark: {args.scene}, {args.steps} steps (+ reset), backend {args.backend}, "
          f"{args.threads} threads\n")
    print("| metric | value | target |\n|---|---|---|")
    print(f"| PSNR on keyframes (train views) | {q['psnr']:.2f} dB | >= 25 dB |")
    print(f"| depth L1 on keyframes (rendered depth sum w_i z_i, over valid GT depth) | "
          f"{q['depth_l1']:.2f} cm | <= 2 cm |")
    print(f"| - signed mean (rendered - GT) | {q['depth_signed']:+.2f} cm | |")
    print(f"| - pixels off by > 10 cm | {q['share_over_10cm']:.2f} % | |")
    print(f"| - for diagnosis: L1 of sum w_i z_i / O, of median depth | {q['depth_l1_normalised']:.2f} cm, "
          f"{q['depth_l1_median']:.2f} cm | |")
    print(f"| - mean opacity O on valid pixels | {q['opacity']:.4f} | |")
    print(f"| mapper time per step (mean, wall) | {np.mean([r.ms for r in records]):.1f} ms | ~90 ms |")
    print(f"| mapper CPU time per step (mean, all threads) | {np.mean(cpu_ms):.1f} ms | |")
    print(f"| mapper time per mapped frame (mean) | "
          f"{np.mean([r.ms for r in records if r.mapped]):.1f} ms | |")
    print(f"| peak Gaussians | {mapper.peak_gaussians} | bounded |")
    print(f"| final Gaussians | {len(mapper.gaussians)} | |")
    added, pruned = sum(r.added for r in records), sum(r.pruned for r in records)
    print(f"| added / pruned (total) | {added} / {pruned} | |")
    print(f"| mapped frames / keyframes | {mapped} / {len(mapper.keyframes)} | |")
    print(f"| episode wall time | {wall:.1f} s | |")
    print("\n| phase | ms per step | share |\n|---|---|---|")
    total = sum(r.ms for r in records)
    other = total - sum(phases.values())
    for name, ms in [*phases.items(), ("other (checks, keyframe copy)", other)]:
        print(f"| {name} | {ms / n:.1f} | {100 * ms / total:.0f} % |")


if __name__ == "__main__":
    main()
