"""`activesplat map RECORDING`: a recorded walk-through (ROS bag, MCAP, TUM RGB-D folder) into a map folder
in the episode layout, readable by ``render-eval``, ``refine``, ``export`` and ``view``.

Every frame goes through the same online mapper the explorer uses (``Mapper.add_frame``, the regular
schedule), in time order, except the held-out frames, which are kept out of the map and saved as ground
truth (``heldout.npz``): every ``holdout_every``-th frame (of those ``stride`` keeps), at most
``max_heldout`` of them (default 200, about 2 MB each at 640x480) spread uniformly over the recording
(:func:`heldout_indices`, chosen before the images are read; the every-N-th frames left over are mapped).
``render-eval`` scores the map on up to 50 of those held-out recorded views (its *train* split, views near
the trajectory). Without a scene mesh there are no random free-space views, so a recorded map has no test
split.

World frame: the map's world is the pose source's world turned by one fixed rotation so that its up axis
becomes +y (the project's convention, docs/protocol.md §8; the top-down workspace slices along y). ROS
worlds are z-up (REP 103): ``world_up="z"`` maps (x, y, z) to (x, z, -y). ``world_up="y"`` keeps the
frame as it is. The rotation is recorded in ``episode.json`` (``world_from_source``); ``poses.txt`` and
the map are in the rotated frame, ``trajectory_tum.txt`` in the source frame.

Folder (written to ``OUT.partial`` and renamed to ``OUT`` only when complete, so a failure never leaves a
folder that looks finished; Ctrl-C keeps the map of the frames read so far, ``"complete": false`` in
``metrics.json``, as an interrupted exploration keeps its episode): ``episode.json`` (``"source":
"recording"``, topics, intrinsics, frame counts), ``poses.txt`` (every frame's camera-to-world in
the map frame, the first column the frame index), ``trajectory_tum.txt`` (stamp tx ty tz qx qy qz qw,
source frame), ``gaussians.ply``, ``keyframes.npz``, ``mapper.json``, ``heldout.npz`` (rgb, depth, pose,
index), ``topdown.png``, ``metrics.json`` (timing).
"""

from __future__ import annotations

import json
import shutil
import time
import warnings
from dataclasses import asdict
from pathlib import Path

import numpy as np

from activesplat.episode import software, write_json_atomic, write_npz
from activesplat.errors import EpisodeError, Interrupted, InvalidInputError, check_output_folder, interrupted
from activesplat.eval.render_eval import HELDOUT_FILE
from activesplat.robot.recording import Recording
from activesplat.robot.transforms import matrix_tq
from activesplat.timing import progress_bar

MAX_HELDOUT = 200
"""Default cap on the held-out frames of a recorded map (render-eval scores up to 50 of them)."""

WORLD_UP = {"y": np.eye(4), "z": np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])}
"""map_T_source per up axis of the source world: z-up (x, y, z) -> (x, z, -y), a proper rotation."""


def check_out(out: str | Path, overwrite: bool = False) -> None:
    """The map folder `out` can be written (the map is made in ``OUT.partial`` beside it, then renamed) and
    holds nothing, or a map or episode to replace with `overwrite`: checked before the recording is scanned.
    InvalidInputError / EpisodeError, in one line."""
    out = Path(out)
    check_output_folder(out)
    check_output_folder(out.with_name(out.name + ".partial"))
    if out.is_dir() and any(out.iterdir()):
        if not overwrite:
            raise EpisodeError(f"{out} exists and is not empty; pass --overwrite to replace it")
        if not (out / "episode.json").is_file():
            raise EpisodeError(f"{out} is not a map or episode folder; refusing to replace it")


def _prepare_out(out: Path, overwrite: bool) -> Path:
    check_out(out, overwrite)
    tmp = out.with_name(out.name + ".partial")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    return tmp


def map_recording(
    rec: Recording,
    out: str | Path,
    holdout_every: int = 8,
    world_up: str = "z",
    mapper_config=None,
    workspace_config=None,
    backend: str = "auto",
    stride: int = 1,
    overwrite: bool = False,
    progress: bool = True,
    floor_height: float | None = None,
    max_heldout: int = MAX_HELDOUT,
) -> dict:
    """Map a scanned recording into the folder ``out`` (module docstring); returns metrics.json's content."""
    import torch

    from activesplat.splat import Mapper

    if world_up not in WORLD_UP:
        raise InvalidInputError(f"--world-up must be one of {', '.join(WORLD_UP)}, got {world_up!r}")
    if holdout_every < 0 or holdout_every == 1 or stride < 1 or max_heldout < 0:
        raise InvalidInputError(
            f"--holdout-every must be 0 (none) or >= 2, --stride >= 1 and --max-heldout >= 0, got "
            f"{holdout_every}, {stride} and {max_heldout}"
        )
    out = Path(out)
    tmp = _prepare_out(out, overwrite)
    phase = "while setting up the mapper"  # for the line of a Ctrl-C outside the frames
    try:
        W = WORLD_UP[world_up]
        poses = np.einsum("ij,njk->nik", W, rec.poses)
        upright = upright_pct(poses)
        if upright < 50.0:
            warnings.warn(
                f"the camera is upright (image down within 60 deg of the world's down) in only "
                f"{upright:.0f}% of the frames: are the poses of the camera's optical frame (x right, y "
                f"down, z forward; a body frame needs --camera-in-body) in a {world_up}-up world "
                f"(--world-up)? Otherwise the map's floor and topdown.png are wrong (a camera looking "
                f"straight down also does this)",
                stacklevel=2,
            )
        torch.manual_seed(0)
        mapper = Mapper(rec.mapper_K, rec.width, rec.height, config=mapper_config, backend=backend)
        h, w = rec.height, rec.width
        every_nth = heldout_indices(len(rec), holdout_every, stride, None)
        held_index = heldout_indices(len(rec), holdout_every, stride, max_heldout)
        held_out = set(held_index.tolist())  # streamed in order: the n-th held-out frame is held_index[n]
        held_rgb = np.empty((len(held_index), h, w, 3), np.uint8)  # filled in place: no list, no np.stack
        held_depth = np.empty((len(held_index), h, w), np.float32)
        n_held = 0
        used, mapper_ms, seen, stopped = [], 0.0, 0, False
        bar = progress_bar(len(rec), "map", "frame", progress)
        t0 = time.perf_counter()
        try:
            for k, rgb, depth in rec.frames():
                if bar is not None:
                    bar.update(1)
                seen = k + 1
                if k % stride:
                    continue
                if k in held_out:
                    held_rgb[n_held], held_depth[n_held] = rgb, depth
                    n_held += 1
                    continue
                t1 = time.perf_counter()
                mapper.add_frame(rgb, depth, poses[k])
                mapper_ms += 1000.0 * (time.perf_counter() - t1)
                used.append(k)
        except KeyboardInterrupt:  # Ctrl-C: keep the map of the frames so far, as `explore` keeps its episode
            if not used:
                if bar is not None:
                    bar.close()
                raise _interrupted(f"before the first frame was mapped ({seen} of {len(rec)} read)", out,
                                   overwrite) from None
            stopped = True
        wall = time.perf_counter() - t0
        phase = "while writing the map"
        if bar is not None:
            bar.close()
        if not used:
            raise InvalidInputError(
                f"{rec.path}: no frame left to map (stride {stride}, holdout {holdout_every})"
            )
        mapper.save(tmp)
        write_npz(
            tmp / HELDOUT_FILE,
            rgb=held_rgb[:n_held],
            depth=held_depth[:n_held],
            pose=poses[held_index[:n_held]],
            index=held_index[:n_held],
        )
        _write_trajectory(tmp, rec, poses, seen)
        floor = _floor_height(mapper, poses) if floor_height is None else float(floor_height)
        topdown = _draw_topdown(tmp, mapper, poses[used], floor, workspace_config)
        meta = {
            "source": "recording",
            "recording": str(rec.path),
            "kind": rec.kind,
            **rec.info,
            "K": rec.mapper_K.tolist(),  # this project's convention, as a simulated episode's
            "K_ros": rec.K.tolist(),
            "width": rec.width,
            "height": rec.height,
            "world_up": world_up,
            "world_from_source": W.tolist(),
            "start_pose": poses[used[0]].tolist(),
            "floor_height": floor,
            "frames": len(rec),
            "mapped_frames": len(used),
            "heldout_frames": n_held,
            "holdout_every": holdout_every,
            "max_heldout": max_heldout,
            "holdout_candidates": len(every_nth),  # every holdout_every-th frame, before max_heldout
            "stride": stride,
            "upright_pct": upright,
            "software": software(),
            "backend": mapper.backend,
            "config": {"mapper": asdict(mapper.config)},
        }
        write_json_atomic(tmp / "episode.json", meta)
        metrics = {
            "frames": len(rec),
            "mapped_frames": len(used),
            "heldout_frames": n_held,
            "n_gaussians": len(mapper.gaussians),
            "wall_time_s": wall,
            "ms_per_frame": 1000.0 * wall / max(len(used), 1),
            "mapper_ms_per_frame": mapper_ms / max(len(used), 1),
            "topdown": topdown,
        }
        if stopped:  # a partial map: `complete` false, as `evaluate` marks a partial episode
            metrics.update(complete=False, read_frames=seen)
        write_json_atomic(tmp / "metrics.json", metrics)
    except KeyboardInterrupt as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, Interrupted):
            raise
        raise _interrupted(phase, out, overwrite) from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if out.exists():
        shutil.rmtree(out)
    tmp.rename(out)
    if stopped:
        raise interrupted(f"interrupted after {seen} of {len(rec)} frames: partial map of {len(used)} frames "
                          f"in {out} (\"complete\": false in its metrics.json); the same command with "
                          f"--overwrite maps the whole recording")
    return metrics


def _interrupted(when: str, out: Path, overwrite: bool) -> Interrupted:
    """The `Interrupted` of a Ctrl-C that leaves no map (`when`), its line printed: ``OUT`` is as it was."""
    kept = " (the one there is kept)" if overwrite and (out / "episode.json").is_file() else ""
    return interrupted(f"interrupted {when}: no map written to {out}{kept}; the same command starts again")


def heldout_indices(n: int, holdout_every: int, stride: int, max_heldout: int | None) -> np.ndarray:
    """The frames of a recording of ``n`` frames held out of its map: every ``holdout_every``-th of those
    ``stride`` keeps (none for 0), at most ``max_heldout`` (None: no cap) spread uniformly over them, the
    first and last included (as render-eval spreads its views, `eval.render_eval.train_indices`)."""
    from activesplat.eval.render_eval import train_indices

    if not holdout_every:
        return np.zeros(0, dtype=np.int64)
    kept = np.arange(0, n, stride, dtype=np.int64)
    every = kept[np.arange(len(kept)) % holdout_every == holdout_every - 1]
    if max_heldout is None or len(every) <= max_heldout:
        return every
    return every[train_indices(len(every), max_heldout)] if max_heldout else every[:0]


def upright_pct(poses: np.ndarray) -> float:
    """Percentage of camera-to-world poses (map frame, y up) whose image-down axis (camera +y) points
    within 60 degrees of the world's down (-y): near 100 for a camera on a robot or in a hand, near 0
    when the poses are of a body frame (x forward, z up) or the world's up axis was mistaken."""
    return 100.0 * float(np.mean(poses[:, 1, 1] < -0.5)) if len(poses) else 100.0


def _write_trajectory(folder: Path, rec: Recording, poses: np.ndarray, n: int) -> None:
    """poses.txt and trajectory_tum.txt of the first ``n`` frames (all but those after an interrupt)."""
    lines = [f"{i} " + " ".join(f"{v:.9g}" for v in p.reshape(16)) for i, p in enumerate(poses[:n])]
    (folder / "poses.txt").write_text("\n".join(lines) + "\n")
    tum = ["# timestamp tx ty tz qx qy qz qw (camera optical frame in the pose source's world)"]
    for stamp, T in zip(rec.stamps[:n], rec.poses[:n], strict=True):
        t, q = matrix_tq(T)
        tum.append(f"{stamp / 1e9:.9f} " + " ".join(f"{v:.9g}" for v in (*t, *q)))
    (folder / "trajectory_tum.txt").write_text("\n".join(tum) + "\n")


def _floor_height(mapper, poses: np.ndarray) -> float:
    """The floor: the 2nd percentile of the map's heights (y), never above the lowest camera."""
    means = mapper.gaussians.means.detach().cpu().numpy()
    low = float(poses[:, 1, 3].min())
    if len(means) == 0:
        return low - 1.25
    return min(float(np.percentile(means[:, 1], 2.0)), low - 0.1)


def _draw_topdown(folder: Path, mapper, poses: np.ndarray, floor: float, wcfg) -> str | None:
    """topdown.png of the map with the trajectory; the reason as a string when it cannot be drawn."""
    from activesplat.planning.controller import floor_xz
    from activesplat.workspace.config import WorkspaceConfig
    from activesplat.workspace.draw import draw_topdown
    from activesplat.workspace.plan import build_plan

    if len(mapper.gaussians) == 0:
        return "empty map"
    traj = np.array([floor_xz(p) for p in poses])
    try:
        plan = build_plan(mapper.gaussians, floor, traj[-1], wcfg or WorkspaceConfig())
        draw_topdown(
            folder / "topdown.png",
            plan.grids,
            plan.workspace,
            plan.graph,
            trajectory=traj,
            title="recorded map: workspace, Voronoi graph, trajectory",
        )
    except Exception as exc:  # a map the workspace cannot polish (e.g. too small): keep the map, say why
        warnings.warn(f"topdown.png not drawn: {exc}", stacklevel=2)
        return f"not drawn: {exc}"
    return "topdown.png"


def map_from_args(args) -> int:
    """The ``map`` command."""
    from activesplat.robot.recording import open_recording

    out = Path(args.out) if args.out else Path("runs") / (Path(args.recording).stem + "-map")
    check_out(out, args.overwrite)  # before the recording is scanned
    try:
        rec = open_recording(
            args.recording,
            args.rgb_topic,
            args.depth_topic,
            args.camera_info_topic,
            args.pose_source,
            camera_in_body=args.camera_in_body,
            intrinsics=args.intrinsics,
            depth_scale=args.depth_scale,
            max_dt=args.max_dt,
            max_pose_gap=args.max_pose_gap,
            skip_unposed=args.skip_unposed,
            depth_check=not args.no_depth_check,
        )
    except KeyboardInterrupt:
        raise _interrupted("while scanning the recording", out, args.overwrite) from None
    m = map_recording(
        rec,
        out,
        holdout_every=args.holdout_every,
        world_up=args.world_up,
        backend=args.backend,
        stride=args.stride,
        max_heldout=args.max_heldout,
        overwrite=args.overwrite,
        progress=not args.no_progress,
    )
    print(
        f"mapped {m['mapped_frames']} of {m['frames']} frames "
        f"({m['heldout_frames']} held out for render-eval), "
        f"{rec.width}x{rec.height}, {m['n_gaussians']} Gaussians, {m['ms_per_frame']:.0f} ms/frame "
        f"(mapper {m['mapper_ms_per_frame']:.0f}) -> {out}"
    )
    check = rec.info["depth_check"]
    print(json.dumps({**{k: rec.info[k] for k in ("pose_source", "unpaired_colour", "unposed_dropped")},
                      "depth_scale_check": check.get("scale") or check.get("note")}))
    return 0
