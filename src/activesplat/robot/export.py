"""`activesplat export DIR --mcap FILE`: an episode or recorded-map folder as an MCAP file that Foxglove
opens (the ``mcap`` package; Foxglove's well-known schemas, JSON-encoded, bytes fields base64).

Topics (log time = step x ``STEP_S`` seconds from ``T0_S``; the episode stores no clock):

- ``/tf`` ``foxglove.FrameTransform``: ``world`` -> ``map`` once (the map is y-up, Foxglove's world z-up:
  the fixed rotation of ``activesplat map --world-up z``), then ``map`` -> ``camera`` at every step of
  ``poses.txt`` (camera optical frame: x right, y down, z forward).
- ``/trajectory`` ``foxglove.PosesInFrame``: the whole camera trajectory in ``map``, once at the end.
- ``/camera/rgb``, ``/camera/depth`` ``foxglove.RawImage`` (``rgb8``, ``32FC1`` metres) and
  ``/camera/calibration`` ``foxglove.CameraCalibration``: the keyframe buffer (``keyframes.npz``), each at
  its step, in frame ``camera_keyframe`` (its own ``/tf`` transform at that time).
- ``/map`` ``foxglove.PointCloud``: the Gaussian centres (x, y, z float32, red, green, blue, alpha uint8 =
  colour and opacity) in ``map``, once at the end.
"""

from __future__ import annotations

import base64
import json
import os
from pathlib import Path

import numpy as np

from activesplat.episode import remove_quietly
from activesplat.errors import EpisodeError, InvalidInputError, cannot_write, check_output_file
from activesplat.geometry import K_to_opencv

STEP_S = 0.1
T0_S = 1.0
_FLOAT32, _UINT8 = 7, 1  # foxglove.PackedElementField numeric types

_VEC = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
_QUAT = {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}
_TIME = {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}}
_POSE = {"type": "object", "properties": {"position": _VEC, "orientation": _QUAT}}
_BYTES = {"type": "string", "contentEncoding": "base64"}
SCHEMAS = {
    "foxglove.FrameTransform": {
        "timestamp": _TIME,
        "parent_frame_id": {"type": "string"},
        "child_frame_id": {"type": "string"},
        "translation": _VEC,
        "rotation": _QUAT,
    },
    "foxglove.PosesInFrame": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "poses": {"type": "array", "items": _POSE},
    },
    "foxglove.RawImage": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "width": {"type": "integer"},
        "height": {"type": "integer"},
        "encoding": {"type": "string"},
        "step": {"type": "integer"},
        "data": _BYTES,
    },
    "foxglove.CameraCalibration": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "width": {"type": "integer"},
        "height": {"type": "integer"},
        "distortion_model": {"type": "string"},
        **{k: {"type": "array", "items": {"type": "number"}} for k in ("D", "K", "R", "P")},
    },
    "foxglove.PointCloud": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "pose": _POSE,
        "point_stride": {"type": "integer"},
        "fields": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "name": {"type": "string"},
                    "offset": {"type": "integer"},
                    "type": {"type": "integer"},
                },
            },
        },
        "data": _BYTES,
    },
}
TOPICS = {
    "/tf": "foxglove.FrameTransform",
    "/trajectory": "foxglove.PosesInFrame",
    "/camera/rgb": "foxglove.RawImage",
    "/camera/depth": "foxglove.RawImage",
    "/camera/calibration": "foxglove.CameraCalibration",
    "/map": "foxglove.PointCloud",
}


def _time(step: float) -> dict:
    ns = int(round((T0_S + step * STEP_S) * 1e9))
    return {"sec": ns // 10**9, "nsec": ns % 10**9}


def _ns(step: float) -> int:
    return int(round((T0_S + step * STEP_S) * 1e9))


def _pose(T: np.ndarray) -> tuple[dict, dict]:
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(np.asarray(T)[:3, :3]).as_quat()
    t = np.asarray(T)[:3, 3]
    return (
        {"x": float(t[0]), "y": float(t[1]), "z": float(t[2])},
        {"x": float(q[0]), "y": float(q[1]), "z": float(q[2]), "w": float(q[3])},
    )


def _transform(step, parent, child, T) -> dict:
    t, q = _pose(T)
    return {
        "timestamp": _time(step),
        "parent_frame_id": parent,
        "child_frame_id": child,
        "translation": t,
        "rotation": q,
    }


def _read_poses(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """The steps (line numbers from 0: an episode's steps, a recorded map's frames) and poses of the folder's
    poses.txt; a corrupt one is refused in one line (`episode.read_poses`: an EpisodeError naming the file
    and the line), as is a missing one."""
    from activesplat.episode import read_poses

    if not (folder / "poses.txt").is_file():
        raise EpisodeError(f"{folder}: no poses.txt (not an episode or map folder)")
    poses = np.stack(read_poses(folder / "poses.txt"))
    return np.arange(len(poses)), poses


def export_mcap(
    folder: str | Path, out: str | Path, overwrite: bool = False, max_points: int | None = None
) -> dict:
    """Write the MCAP file ``out`` of an episode / map folder (module docstring); returns message counts per
    topic. The file is written under a temporary name and renamed when complete."""
    from mcap.writer import Writer

    from activesplat.robot.mapping import WORLD_UP
    from activesplat.splat.ply import load_ply

    folder, out = Path(folder), Path(out)
    if not folder.is_dir() or not (folder / "gaussians.ply").is_file():
        raise EpisodeError(f"{folder}: not an episode or map folder (no gaussians.ply)")
    if out.suffix != ".mcap":
        raise InvalidInputError(f"--mcap file must end in .mcap: {out}")
    if max_points is not None and (isinstance(max_points, bool) or max_points < 1):
        raise InvalidInputError(f"--max-points must be >= 1 (leave it out for every map point), got "
                                f"{max_points}")
    check_output_file(out, "--mcap")
    if out.exists() and not overwrite:
        raise EpisodeError(f"{out} exists; pass --overwrite to replace it")
    _make_parent(out)
    steps, poses = _read_poses(folder)
    mapper = json.loads((folder / "mapper.json").read_text()) if (folder / "mapper.json").is_file() else None
    gmap = load_ply(folder / "gaussians.ply")
    counts = dict.fromkeys(TOPICS, 0)
    tmp = out.with_name(out.name + ".partial")
    try:
        with _open_for_writing(tmp, out) as f:
            writer = Writer(f)
            writer.start(profile="", library="activesplat")
            channels = {}
            for name, props in SCHEMAS.items():
                schema = json.dumps({"title": name, "type": "object", "properties": props}).encode()
                sid = writer.register_schema(name=name, encoding="jsonschema", data=schema)
                for topic, kind in TOPICS.items():
                    if kind == name:
                        channels[topic] = writer.register_channel(
                            topic=topic, message_encoding="json", schema_id=sid
                        )

            def put(topic: str, step: float, msg: dict) -> None:
                writer.add_message(
                    channels[topic],
                    log_time=_ns(step),
                    publish_time=_ns(step),
                    data=json.dumps(msg).encode(),
                    sequence=counts[topic],
                )
                counts[topic] += 1

            world_T_map = np.linalg.inv(WORLD_UP["z"])
            put("/tf", steps[0], _transform(steps[0], "world", "map", world_T_map))
            events = [(int(s), "pose", i) for i, s in enumerate(steps)]
            if (folder / "keyframes.npz").is_file() and mapper is not None:
                with np.load(folder / "keyframes.npz") as kf:
                    kf_rgb, kf_depth, kf_pose, kf_step = kf["rgb"], kf["depth"], kf["pose"], kf["step"]
                events += [(int(s), "keyframe", i) for i, s in enumerate(kf_step)]
            for step, kind, i in sorted(events, key=lambda e: (e[0], e[1] != "pose")):
                if kind == "pose":
                    put("/tf", step, _transform(step, "map", "camera", poses[i]))
                    continue
                put("/tf", step, _transform(step, "map", "camera_keyframe", kf_pose[i]))
                _put_keyframe(put, step, kf_rgb[i], kf_depth[i], mapper)
            end = int(steps[-1])
            put(
                "/trajectory",
                end,
                {
                    "timestamp": _time(end),
                    "frame_id": "map",
                    "poses": [dict(zip(("position", "orientation"), _pose(T), strict=True)) for T in poses],
                },
            )
            put("/map", end, _point_cloud(gmap, end, max_points))
            writer.finish()
        os.replace(tmp, out)
    except BaseException:
        remove_quietly(tmp)  # never a half-written file
        raise
    return counts


def _make_parent(out: Path) -> None:
    """Create the folder of the file `out`; a one-line error when a file stands in its way."""
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise cannot_write(out, exc, "--mcap") from None


def _open_for_writing(tmp: Path, out: Path):
    """`tmp` (out's temporary name) open for writing; a one-line error naming `out` when it cannot be."""
    try:
        return open(tmp, "wb")
    except OSError as exc:
        raise cannot_write(out, exc, "--mcap") from None


def _put_keyframe(put, step: int, rgb: np.ndarray, depth: np.ndarray, mapper: dict) -> None:
    h, w = depth.shape
    frame = "camera_keyframe"
    put(
        "/camera/rgb",
        step,
        {
            "timestamp": _time(step),
            "frame_id": frame,
            "width": w,
            "height": h,
            "encoding": "rgb8",
            "step": 3 * w,
            "data": base64.b64encode(np.ascontiguousarray(rgb).tobytes()).decode(),
        },
    )
    d = np.ascontiguousarray(depth, dtype="<f4")
    put(
        "/camera/depth",
        step,
        {
            "timestamp": _time(step),
            "frame_id": frame,
            "width": w,
            "height": h,
            "encoding": "32FC1",
            "step": 4 * w,
            "data": base64.b64encode(d.tobytes()).decode(),
        },
    )
    K = K_to_opencv(mapper["K"])  # Foxglove's CameraCalibration follows ROS: pixel centres at whole numbers
    P = np.zeros((3, 4))
    P[:, :3] = K
    put(
        "/camera/calibration",
        step,
        {
            "timestamp": _time(step),
            "frame_id": frame,
            "width": w,
            "height": h,
            "distortion_model": "plumb_bob",
            "D": [0.0] * 5,
            "K": K.reshape(9).tolist(),
            "R": np.eye(3).reshape(9).tolist(),
            "P": P.reshape(12).tolist(),
        },
    )


def _point_cloud(gmap, step: int, max_points: int | None) -> dict:
    means = gmap.means.detach().cpu().numpy().astype("<f4")
    colors = np.clip(gmap.colors.detach().cpu().numpy(), 0.0, 1.0)
    alpha = np.clip(gmap.opacities.detach().cpu().numpy().reshape(-1), 0.0, 1.0)
    if max_points is not None and len(means) > max_points:
        keep = np.argsort(-alpha, kind="stable")[:max_points]
        means, colors, alpha = means[keep], colors[keep], alpha[keep]
    rec = np.zeros(len(means), dtype=[("xyz", "<f4", 3), ("rgba", "u1", 4)])
    rec["xyz"] = means
    rec["rgba"][:, :3] = np.round(colors[:, :3] * 255)
    rec["rgba"][:, 3] = np.round(alpha * 255)
    fields = [{"name": n, "offset": 4 * i, "type": _FLOAT32} for i, n in enumerate("xyz")]
    fields += [
        {"name": n, "offset": 12 + i, "type": _UINT8} for i, n in enumerate(("red", "green", "blue", "alpha"))
    ]
    identity = {
        "position": {"x": 0.0, "y": 0.0, "z": 0.0},
        "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
    }
    return {
        "timestamp": _time(step),
        "frame_id": "map",
        "pose": identity,
        "point_stride": 16,
        "fields": fields,
        "data": base64.b64encode(rec.tobytes()).decode(),
    }


def export_ply(folder: str | Path, out: str | Path, sh_degree: int = 0, overwrite: bool = False) -> Path:
    """Write the map of ``folder`` (an episode, map or ``refined_<method>`` folder: its ``gaussians.ply``)
    as the 3DGS PLY file ``out`` laid out for SH degree ``sh_degree`` (``splat.ply``: the f_rest_* the
    original 3DGS loader asserts for its ``--sh_degree``, all zero); written under a temporary name,
    renamed when complete."""
    from activesplat.splat.ply import load_ply, ply_fields, save_ply

    folder, out = Path(folder), Path(out)
    if not folder.is_dir() or not (folder / "gaussians.ply").is_file():
        raise EpisodeError(f"{folder}: not an episode, map or refined folder (no gaussians.ply)")
    if out.suffix != ".ply":
        raise InvalidInputError(f"--ply file must end in .ply: {out}")
    ply_fields(sh_degree)  # a bad degree fails before anything is written
    check_output_file(out, "--ply")
    if out.exists() and not overwrite:
        raise EpisodeError(f"{out} exists; pass --overwrite to replace it")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise cannot_write(out, exc, "--ply") from None
    gmap = load_ply(folder / "gaussians.ply")
    tmp = out.with_name(out.name + ".partial")
    try:
        try:
            save_ply(gmap, tmp, sh_degree)
        except OSError as exc:
            raise cannot_write(out, exc, "--ply") from None
        os.replace(tmp, out)
    except BaseException:
        remove_quietly(tmp)  # never a half-written file
        raise
    return out


def export_from_args(args) -> int:
    """The ``export`` command."""
    if args.mcap is None and args.ply is None:
        raise InvalidInputError("export needs --mcap FILE (Foxglove) or --ply FILE (3DGS PLY), or both")
    if args.sh_degree is not None and args.ply is None:
        raise InvalidInputError("--sh-degree applies to --ply FILE only")
    if args.max_points is not None and args.mcap is None:
        raise InvalidInputError("--max-points applies to --mcap FILE only")
    # neither is written when the other would be refused (it exists, or cannot be written)
    for out, label in ((args.ply, "--ply"), (args.mcap, "--mcap")):
        if out is not None:
            check_output_file(out, label)
            if Path(out).is_file() and not args.overwrite:
                raise EpisodeError(f"{out} exists; pass --overwrite to replace it")
    written: list = []  # the files complete so far
    current = None  # (option, file, whether a file was there before) of the file being written
    try:
        if args.ply is not None:
            sh = 0 if args.sh_degree is None else args.sh_degree
            current = ("--ply", args.ply, Path(args.ply).exists())
            export_ply(args.dir, args.ply, sh_degree=sh, overwrite=args.overwrite)
            written.append(args.ply)
            zero = " (higher coefficients zero)" if sh else ""
            print(f"wrote {args.ply}: the map's Gaussians, SH degree {sh}{zero}")
        if args.mcap is not None:
            current = ("--mcap", args.mcap, Path(args.mcap).exists())
            counts = export_mcap(args.dir, args.mcap, overwrite=args.overwrite, max_points=args.max_points)
            written.append(args.mcap)
            print(f"wrote {args.mcap}: " + ", ".join(f"{t} {n}" for t, n in counts.items()))
    except KeyboardInterrupt:
        raise _interrupted(current, written) from None
    return 0


def _interrupted(current: tuple | None, written: list):
    """The `Interrupted` of a Ctrl-C in `export`, its line printed: the file being written is left as it was
    (its partial copy, under a temporary name, is removed); a file written before it is complete."""
    from activesplat.errors import interrupted

    if current is None or current[1] in written:  # between the files' writes
        return interrupted(f"export interrupted: {' and '.join(map(str, written)) or 'nothing'} written")
    done = f"{written[0]} is written (complete)" if written else ""
    label, out, existed = current
    kept = "the file already there is kept as it was" if existed else "no partial file is left"
    again = f"run it again without --ply {written[0]}" if written else "run the same command again"
    return interrupted(f"export interrupted while writing {label} {out}: {done + ', ' if done else ''}{out} "
                      f"is not written ({kept}); {again}")
