"""What the online mapper reaches when the trajectory sees the whole house: the mapping ceiling.

    python benchmarks/mapper_ceiling.py --scenes medium-0 medium-2-plain --out runs/ceiling
    python benchmarks/mapper.py --episode runs/ceiling/medium-0/tour --out runs/ceiling/medium-0/map

The render-eval test split (50 random free-space views) of an explored house mixes two errors: what the
mapper got wrong where the robot looked, and surfaces no frame of the trajectory observed (rooms never
entered, the door side of a room, floor behind furniture). This script takes the explorer out. It writes
a synthetic episode folder whose trajectory is a known-map look-around on a regular grid over the
navigable space (the exhaustive sweep's poses, `eval/sweep.py`, coarser: `--spacing` m, a full circle in
`--yaw-step` deg steps at each of `--pitches`), every frame mapped with the look-around (dense) schedule,
as `benchmarks/mapper.py --episode` replays turns. Then, unless `--no-map`, it runs that replay on it,
which maps the frames with the default mapper (or `--set` overrides) and evaluates the map with
render-eval: the same test views as every episode of the scene, the train views drawn from the tour.

The tour jumps from one grid position to the next (it is not a walk); the mapper only sees posed frames,
so that does not matter to it. The test PSNR of this map is what the mapper gives when observation is
complete; the gap between it and an explored map's test PSNR is the explorer's share of the error.
"""

from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np

from activesplat.episode import EpisodeWriter
from activesplat.errors import InvalidInputError, check_output_folder
from activesplat.eval.sweep import SweepConfig, sweep_poses
from activesplat.sim import SimConfig, load_scene


def serpentine(poses: np.ndarray, per_position: int) -> np.ndarray:
    """Reorder the sweep's positions (row-major grid order) so that every other row runs backwards: the
    tour's consecutive positions are grid neighbours, as a walk's would be."""
    groups = poses.reshape(-1, per_position, 4, 4)
    x = np.round(groups[:, 0, 0, 3], 3)
    rows: dict[float, list[int]] = {}
    for i, xi in enumerate(x):
        rows.setdefault(float(xi), []).append(i)
    order: list[int] = []
    for r, key in enumerate(sorted(rows)):
        idx = sorted(rows[key], key=lambda i: groups[i, 0, 2, 3])
        order.extend(idx[::-1] if r % 2 else idx)
    return groups[order].reshape(-1, 4, 4)


def write_tour(scene_name: str, out_dir: Path, cfg: SweepConfig) -> int:
    """The tour of `scene_name` as an episode folder in `out_dir`; returns its number of frames."""
    sim = SimConfig()
    scene = load_scene(scene_name)
    per_position = int(round(360.0 / cfg.yaw_step_deg)) * len(cfg.pitches_deg)
    poses = serpentine(sweep_poses(scene, sim, cfg), per_position)
    nav = scene.navmap_for(sim)
    meta = {"scene": scene_name, "scene_name": scene.name, "seed": 0, "policy": "known-map tour",
            "steps": len(poses) - 1, "start_pose": poses[0].tolist(), "z_up": False, "floor": None,
            "floor_height": float(nav.floor_height), "backend": "auto",
            "config": {"scene": scene_name, "sim": dataclasses.asdict(sim),
                       "tour": dataclasses.asdict(cfg)}}
    writer = EpisodeWriter(out_dir, overwrite=True)
    writer.start(meta, poses[0])
    for step, pose in enumerate(poses[1:], start=1):
        writer.record(step, "turn_left", pose)  # not move_forward: mapped with the dense schedule
    writer.close()
    return len(poses)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["medium-0", "medium-1", "medium-2", "medium-3",
                                                    "medium-2-plain"])
    ap.add_argument("--out", type=Path, required=True, help="OUT/<scene>/tour (episode), OUT/<scene>/map")
    ap.add_argument("--spacing", type=float, default=1.0, help="grid spacing of the positions (m)")
    ap.add_argument("--yaw-step", type=float, default=30.0, help="yaw step of the look-around (deg)")
    ap.add_argument("--pitches", type=float, nargs="+", default=[-30.0, 0.0, 30.0],
                    help="camera pitches at every yaw (deg; the agent reaches +-45)")
    ap.add_argument("--threads", type=int, default=1, help="passed to benchmarks/mapper.py")
    ap.add_argument("--set", nargs="*", default=[], metavar="FIELD=VALUE",
                    help="mapper config overrides, passed to benchmarks/mapper.py")
    ap.add_argument("--no-map", action="store_true", help="only write the tour episodes")
    args = ap.parse_args()
    try:
        check_output_folder(args.out, "--out")  # before the tours
    except InvalidInputError as exc:
        ap.error(str(exc))
    cfg = SweepConfig(spacing_m=args.spacing, yaw_step_deg=args.yaw_step, pitches_deg=tuple(args.pitches))
    for name in args.scenes:
        tour = args.out / name / "tour"
        n = write_tour(name, tour, cfg)
        print(f"{name}: {n} frames -> {tour}", flush=True)
        if args.no_map:
            continue
        cmd = [sys.executable, str(Path(__file__).with_name("mapper.py")), "--episode", str(tour),
               "--out", str(args.out / name / "map"), "--threads", str(args.threads)]
        if args.set:
            cmd += ["--set", *args.set]
        log = args.out / name / "mapper.md"
        with open(log, "w", encoding="utf-8") as f:
            subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, check=True)
        tail = log.read_text().split("### render-eval")[-1]
        print(f"{name}: {log}\n### render-eval{tail}", flush=True)


if __name__ == "__main__":
    main()
