"""Online mapper benchmark: map a trajectory, watch the first keyframes for forgetting, evaluate the map.

    python benchmarks/mapper.py --episode runs/medium-0          # replay a recorded exploration
    python benchmarks/mapper.py --scene small-0 --steps 300      # scripted look-around-and-walk

Trajectory. ``--episode DIR`` replays the poses of an exploration's episode folder (``poses.txt``): the
observations are re-rendered by the simulator at exactly those poses, so the mapper sees what the
explorer's mapper saw, whatever the mapper under test does (the path does not depend on the map). The
look-around (dense) schedule is used for every action that is not ``move_forward`` (the live loop uses
it only while the agent turns on the spot, so this slightly over-counts the dense frames). Without
``--episode`` the script walks: the bootstrap look-around (36 turns, each followed by a tilt), then
forward, turning on the spot by a seeded random 60-120 deg when a move is blocked.

Forgetting curve. The first ``--probe`` keyframes that were mapped frames are rendered right after
mapping ("when mapped") and again every ``--every`` steps; a map that forgets loses PSNR on them as the
episode goes on.

Final numbers. With ``--episode``, the final map is evaluated by ``activesplat render-eval`` (the 50 train
views over the trajectory and the 50 random test views of the episode's scene) into ``--out``. Always:
PSNR / depth L1 on every keyframe, mapper wall and CPU time per step (warm numba), the phases, Gaussians,
bytes per m^2 of observed surface and the peak RSS of the process.

Observed surface: the number of 5 cm voxels hit by back-projected observed depth (every 4th pixel of
every frame) times (5 cm)^2, an estimate of the area the sensor has seen.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import time
from collections import defaultdict
from pathlib import Path

import numba
import numpy as np
import torch

from activesplat.episode import read_episode
from activesplat.errors import InvalidInputError, check_output_folder
from activesplat.eval.evaluate import parse_sim_overrides
from activesplat.geometry import backproject
from activesplat.sim import SimConfig, Simulator, load_scene
from activesplat.splat import Mapper, MapperConfig
from activesplat.timing import peak_rss_mb as peak_rss

TILTS = ("look_down", "look_down", "look_down", "look_up", "look_up", "look_up")
SURFACE_VOXEL_M = 0.05
BYTES_PER_GAUSSIAN = 4 * (14 + 2 * 14) + 4  # float32 parameters, two Adam moments, a step count


def config_with(overrides: list[str]) -> MapperConfig:
    """MapperConfig with FIELD=VALUE overrides; a dotted FIELD sets a field of a nested dataclass
    (``schedule.iterations=4``, ``lr.means=2e-3``)."""
    config = MapperConfig()
    for item in overrides:
        key, value = item.split("=", 1)
        head, _, sub = key.partition(".")
        new = ast.literal_eval(value)
        if sub:
            new = dataclasses.replace(getattr(config, head), **{sub: new})
        config = dataclasses.replace(config, **{head: new})
    return config


def bootstrap_actions() -> list[str]:
    """The bootstrap look-around (docs/protocol.md §1): a tilt after each of the 36 turns, ending level."""
    actions = []
    for i in range(36):
        actions += ["turn_left", TILTS[i % len(TILTS)]]
    return actions


def scripted_poses(sim: Simulator, steps: int, seed: int) -> tuple[list[np.ndarray], list[bool]]:
    """Poses and dense flags of the scripted look-around-and-walk (module docstring)."""
    rng = np.random.default_rng(seed)
    sim.reset()
    poses, dense = [sim.pose], [True]
    script, pending = bootstrap_actions(), []
    for step in range(steps):
        if step < len(script):
            action, is_dense = script[step], True
        elif pending:
            action, is_dense = pending.pop(), True
        else:
            action, is_dense = "move_forward", False
        moved = sim.act(action)
        if action == "move_forward" and not moved:
            pending = [str(rng.choice(["turn_left", "turn_right"]))] * int(rng.integers(6, 13))
        poses.append(sim.pose)
        dense.append(is_dense)
    return poses, dense


def episode_poses(episode_dir: Path, steps: int | None,
                  sim_overrides: dict | None = None) -> tuple[Simulator, list[np.ndarray], list[bool]]:
    episode = read_episode(episode_dir)
    from activesplat.eval.evaluate import recorded_sim_config

    scene = load_scene(episode.meta["scene"], z_up=bool(episode.meta.get("z_up", False)))
    sim = Simulator(scene, start=episode.start_pose, config=recorded_sim_config(episode.meta, sim_overrides,
                                                                             episode.dir / "episode.json"))
    n = len(episode.actions) if steps is None else min(steps, len(episode.actions))
    dense = [True] + [a != "move_forward" for a in episode.actions[:n]]
    return sim, list(episode.poses[: n + 1]), dense


def psnr(mapper: Mapper, rgb: np.ndarray, pose: np.ndarray, out=None) -> float:
    """PSNR of the map's render at ``pose`` (or of the given render ``out``) against ``rgb``."""
    out = mapper.render(pose) if out is None else out
    mse = float(np.mean((out.rgb.clamp(0, 1).numpy() - rgb.astype(np.float32) / 255.0) ** 2))
    return -10.0 * np.log10(max(mse, 1e-10))


def evaluate_keyframes(mapper: Mapper) -> dict[str, float]:
    """Means over the keyframes of the map rendered there: PSNR (dB), depth L1 (cm, over valid depth) of
    the alpha-blended depth sum w_i z_i (what the mapper trains on), its signed mean, the share of pixels
    off by more than 10 cm and the mean opacity over valid pixels."""
    rows: dict[str, list[float]] = defaultdict(list)
    for kf in mapper.keyframes:
        out = mapper.render(kf.pose)
        rows["psnr"].append(psnr(mapper, kf.rgb, kf.pose, out))
        valid = kf.depth > 0
        error = out.depth.numpy()[valid] - kf.depth[valid]
        rows["depth_l1"].append(100.0 * float(np.abs(error).mean()))
        rows["depth_signed"].append(100.0 * float(error.mean()))
        rows["share_over_10cm"].append(100.0 * float((np.abs(error) > 0.1).mean()))
        rows["opacity"].append(float(out.alpha.numpy()[valid].mean()))
    return {name: float(np.mean(values)) for name, values in rows.items()}


def observed_voxels(depth: np.ndarray, pose: np.ndarray, K: np.ndarray) -> np.ndarray:
    v, u = np.nonzero(depth[::4, ::4] > 0)
    points = backproject(depth, pose, K, 4 * v, 4 * u)
    return np.unique(np.floor(points / SURFACE_VOXEL_M).astype(np.int64), axis=0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episode", type=Path, help="replay this episode folder's poses")
    parser.add_argument("--scene", default="small-0", help="scripted walk in this scene (without --episode)")
    parser.add_argument("--steps", type=int, default=None, help="actions to map (default: all / 300)")
    parser.add_argument("--backend", default="auto")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2, help="torch and numba threads (target: 2 cores)")
    parser.add_argument("--probe", type=int, default=5, help="first keyframes watched for forgetting")
    parser.add_argument("--every", type=int, default=250, help="steps between forgetting-curve points")
    parser.add_argument("--repeat", type=int, default=1,
                        help="map the trajectory this many times in a row (nothing new after the first: "
                             "a map whose memory grows with the scene, not with time, stops growing)")
    parser.add_argument("--out", type=Path, help="write the map (and render-eval, with --episode) here")
    parser.add_argument("--set", nargs="*", default=[], metavar="FIELD=VALUE",
                        help="MapperConfig overrides, e.g. sparse_adam=False schedule.iterations=4")
    parser.add_argument("--sim", nargs="*", default=[], metavar="FIELD=VALUE",
                        help="SimConfig overrides of the replayed (or scripted) camera and of render-eval's "
                             "ground truth, e.g. texture_filter=nearest")
    args = parser.parse_args()
    if args.out is not None:
        try:
            check_output_folder(args.out, "--out")  # before the mapping
        except InvalidInputError as exc:
            parser.error(str(exc))
    torch.set_num_threads(args.threads)
    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))  # the kernels' threads too
    config = config_with(args.set)
    sim_overrides = parse_sim_overrides(args.sim)

    if args.episode is not None:
        sim, poses, dense = episode_poses(args.episode, args.steps, sim_overrides)
        label = f"replay of {args.episode} ({len(poses) - 1} actions)"
    else:
        sim = Simulator(load_scene(args.scene), seed=args.seed, config=SimConfig(**sim_overrides))
        poses, dense = scripted_poses(sim, args.steps or 300, args.seed)
        label = f"scripted walk in {args.scene}, {len(poses) - 1} actions"

    poses, dense = poses + poses[1:] * (args.repeat - 1), dense + dense[1:] * (args.repeat - 1)
    if args.repeat > 1:
        label += f", {args.repeat} times"
    warm = Mapper(sim.K, sim.width, sim.height, config, backend=args.backend)  # compile numba outside timing
    rgb, depth = sim.render(poses[0])
    for _ in range(2):
        warm.add_frame(rgb, depth, poses[0], dense=True)

    mapper = Mapper(sim.K, sim.width, sim.height, config, backend=args.backend)
    probes: dict[int, dict] = {}  # keyframe step -> {"rgb", "pose", "psnr": {step: value}}
    curve_steps: list[int] = []
    curve_area: dict[int, float] = {}
    records, cpu_ms, voxels = [], [], set()
    t_start = time.perf_counter()
    for step, (pose, is_dense) in enumerate(zip(poses, dense, strict=True)):
        rgb, depth = sim.render(pose)
        t0 = time.process_time()
        stats = mapper.add_frame(rgb, depth, pose, dense=is_dense)
        cpu_ms.append(1000.0 * (time.process_time() - t0))
        records.append(stats)
        if step % 2 == 0:
            voxels.update(map(tuple, observed_voxels(depth, pose, sim.K)))
        if stats.keyframe and stats.mapped and len(probes) < args.probe:  # mapped: its PSNR "when mapped"
            probes[step] = {"rgb": rgb, "pose": pose, "psnr": {step: psnr(mapper, rgb, pose)}}
        if step > 0 and (step % args.every == 0 or step == len(poses) - 1):
            curve_steps.append(step)
            curve_area[step] = len(voxels) * SURFACE_VOXEL_M ** 2
            for p in probes.values():
                p["psnr"][step] = psnr(mapper, p["rgb"], p["pose"])
    wall = time.perf_counter() - t_start
    peak_rss_mb = peak_rss()
    area = len(voxels) * SURFACE_VOXEL_M ** 2

    print(f"## Mapper benchmark: {label}, backend {args.backend}, {args.threads} threads\n")
    if config != MapperConfig():
        print(f"config overrides: {' '.join(args.set)}\n")
    print("### Forgetting curve: PSNR (dB) of the first keyframes, re-rendered as the episode goes on\n")
    print("| step | " + " | ".join(f"kf@{s}" for s in probes)
          + " | mean | Gaussians | observed m^2 | per m^2 |")
    print("|---|" + "---|" * (len(probes) + 4))
    when_mapped = [p["psnr"][s] for s, p in probes.items()]
    print("| when mapped | " + " | ".join(f"{v:.2f}" for v in when_mapped)
          + f" | {np.mean(when_mapped):.2f} | | | |")
    for s in curve_steps:
        values = [p["psnr"][s] for p in probes.values()]
        n_g, area_s = records[s].n_gaussians, curve_area[s]
        print(f"| {s} | " + " | ".join(f"{v:.2f}" for v in values)
              + f" | {np.mean(values):.2f} | {n_g} | {area_s:.0f} | {n_g / max(area_s, 1e-9):.0f} |")

    q = evaluate_keyframes(mapper)
    n = len(records)
    phases: dict[str, float] = defaultdict(float)
    for r in records:
        for name, ms in r.timings.items():
            phases[name] += ms
    print("\n### Final map\n\n| metric | value |\n|---|---|")
    print(f"| PSNR on all keyframes | {q['psnr']:.2f} dB |")
    print(f"| depth L1 on all keyframes (sum w_i z_i) | {q['depth_l1']:.2f} cm "
          f"(signed {q['depth_signed']:+.2f}) |")
    print(f"| pixels off by > 10 cm / mean opacity | {q['share_over_10cm']:.2f} % / {q['opacity']:.4f} |")
    print(f"| mapper wall time per step (mean) | {np.mean([r.ms for r in records]):.1f} ms |")
    print(f"| mapper CPU time per step (mean, all threads) | {np.mean(cpu_ms):.1f} ms |")
    print(f"| Gaussians final / peak | {len(mapper.gaussians)} / {mapper.peak_gaussians} |")
    print(f"| observed surface (5 cm voxels) | {area:.1f} m^2 |")
    print(f"| Gaussians per m^2 observed | {len(mapper.gaussians) / max(area, 1e-9):.0f} |")
    print(f"| map + optimiser bytes per m^2 observed | "
          f"{len(mapper.gaussians) * BYTES_PER_GAUSSIAN / max(area, 1e-9) / 1024:.1f} KiB |")
    print(f"| peak RSS of this process | {'n/a' if peak_rss_mb is None else f'{peak_rss_mb:.0f} MB'} |")
    print(f"| added / pruned / merged | {sum(r.added for r in records)} / {sum(r.pruned for r in records)} / "
          f"{sum(r.merged for r in records)} |")
    print(f"| mapped frames / keyframes | {sum(r.mapped for r in records)} / {len(mapper.keyframes)} |")
    print(f"| episode wall time | {wall:.1f} s |")
    print("\n| phase | ms per step | share |\n|---|---|---|")
    total = sum(r.ms for r in records)
    other = total - sum(phases.values())
    for name, ms in [*phases.items(), ("other (checks, keyframe copy)", other)]:
        print(f"| {name} | {ms / n:.1f} | {100 * ms / total:.0f} % |")

    if args.out is not None:
        mapper.save(args.out)
        if args.episode is not None:
            from activesplat.eval.render_eval import render_eval

            r = render_eval(args.episode, gaussians_path=args.out / "gaussians.ply", out_dir=args.out,
                            progress=False, sim_overrides=sim_overrides)
            print("\n### render-eval (train: 50 trajectory views, test: 50 random free-space views)\n")
            print("| split | PSNR | SSIM | LPIPS | depth L1 cm | unmapped % |\n|---|---|---|---|---|---|")
            for split in ("train", "test"):
                m = r[split]
                print(f"| {split} | {m['psnr']:.2f} | {m['ssim']:.3f} | {m['lpips']:.3f} | "
                      f"{m['depth_l1_cm']:.2f} | {m['unmapped_pct']:.2f} |")


if __name__ == "__main__":
    main()
