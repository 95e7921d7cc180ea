"""Online mapper benchmark: a scripted look-around-and-walk in a built-in scene (issue 4).

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
    """REFERENCE.md sec. 1: one tilt after each of the 36 turns, ~72 actions, ending level."""
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


def run_episode(scene_name: str, steps: int, backend: str, seed: int, config: MapperConfig):
    sim = Simulator(load_scene(scene_name), seed=seed)
    warm_up(sim, backend, config)
    mapper = Mapper(sim.K, sim.width, sim.height, config, backend=backend)
    rng = np.random.default_rng(seed)
    obs = sim.reset()
    records = [mapper.add_frame(obs.rgb, obs.depth, obs.pose, dense=True)]
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
        records.append(mapper.add_frame(obs.rgb, obs.depth, obs.pose, dense=dense))
    return mapper, records


def evaluate_keyframes(mapper: Mapper) -> tuple[float, float]:
    """Mean PSNR (dB) and depth L1 (cm) of the map rendered at the keyframes."""
    psnrs, l1s = [], []
    for kf in mapper.keyframes:
        out = mapper.render(kf.pose)
        rgb = out.rgb.clamp(0, 1).numpy()
        mse = float(np.mean((rgb - kf.rgb.astype(np.float32) / 255.0) ** 2))
        psnrs.append(-10.0 * np.log10(max(mse, 1e-10)))
        valid = kf.depth > 0
        l1s.append(100.0 * float(np.abs(out.depth.numpy() - kf.depth)[valid].mean()))
    return float(np.mean(psnrs)), float(np.mean(l1s))


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
    mapper, records = run_episode(args.scene, args.steps, args.backend, args.seed, config)
    wall = time.perf_counter() - t0
    psnr, depth_l1 = evaluate_keyframes(mapper)
    n = len(records)
    phases: dict[str, float] = defaultdict(float)
    for r in records:
        for name, ms in r.timings.items():
            phases[name] += ms
    mapped = sum(r.mapped for r in records)
    print(f"## Mapper benchmark: {args.scene}, {args.steps} steps (+ reset), backend {args.backend}, "
          f"{args.threads} threads\n")
    print("| metric | value | target |\n|---|---|---|")
    print(f"| PSNR on keyframes (train views) | {psnr:.2f} dB | >= 25 dB |")
    print(f"| depth L1 on keyframes | {depth_l1:.2f} cm | <= 2 cm |")
    print(f"| mapper time per step (mean) | {np.mean([r.ms for r in records]):.1f} ms | ~90 ms |")
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
