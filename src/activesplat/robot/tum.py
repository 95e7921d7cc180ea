"""TUM RGB-D folders (``rgb.txt``, ``depth.txt``, ``groundtruth.txt``) as a `robot.recording.Recording`
(conventions: that module's docstring)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from activesplat.errors import RecordingError
from activesplat.robot.recording import Recording, check_intrinsics, intrinsics_matrix, pair_nearest
from activesplat.robot.transforms import PoseTrack, pose_matrix


def _read_list(path: Path, columns: int) -> list[list[str]]:
    """Rows of a TUM list file (comments '#' skipped); RecordingError on a short row."""
    if not path.is_file():
        raise RecordingError(f"{path}: missing (a TUM RGB-D folder has rgb.txt, depth.txt, groundtruth.txt)")
    rows = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if len(parts) < columns:
            raise RecordingError(f"{path.name}: line {n}: expected {columns} columns, got {len(parts)}")
        rows.append(parts)
    return rows


def _stamps(rows: list[list[str]], name: str) -> np.ndarray:
    try:
        s = np.array([round(float(r[0]) * 1e9) for r in rows], dtype=np.int64)
    except ValueError as exc:
        raise RecordingError(f"{name}: unreadable time stamp ({exc})") from None
    back = np.flatnonzero(np.diff(s) < 0)
    if len(back):
        raise RecordingError(
            f"{name}: line {back[0] + 2}: time stamp {s[back[0] + 1] / 1e9:.6f} goes back (non-monotonic)"
        )
    return s


def open_tum(
    folder: Path,
    intrinsics,
    depth_scale: float,
    pose_file: str | None,
    max_dt: float,
    max_pose_gap: float,
    skip_unposed: bool,
) -> Recording:
    import cv2

    if intrinsics is None:
        raise RecordingError(
            f"{folder}: a TUM RGB-D folder needs --intrinsics FX FY CX CY (e.g. TUM freiburg1: "
            f"517.3 516.5 318.6 255.3)"
        )
    K = intrinsics_matrix(intrinsics)
    if depth_scale <= 0:
        raise RecordingError(f"--depth-scale must be > 0, got {depth_scale}")
    rgb_rows, depth_rows = _read_list(folder / "rgb.txt", 2), _read_list(folder / "depth.txt", 2)
    gt_path = folder / (pose_file or "groundtruth.txt")
    gt_rows = _read_list(gt_path, 8)
    rs, ds, gs = (
        _stamps(rgb_rows, "rgb.txt"),
        _stamps(depth_rows, "depth.txt"),
        _stamps(gt_rows, gt_path.name),
    )
    try:
        gt = [pose_matrix([float(v) for v in r[1:4]], [float(v) for v in r[4:8]]) for r in gt_rows]
    except ValueError as exc:
        raise RecordingError(f"{gt_path.name}: unreadable pose ({exc})") from None
    track = PoseTrack(list(gs), gt, gt_path.name)
    pairs, dropped = pair_nearest(
        [(int(s), i) for i, s in enumerate(rs)], [(int(s), i) for i, s in enumerate(ds)], int(max_dt * 1e9)
    )
    if not pairs:
        raise RecordingError(f"rgb.txt: no colour image has a depth image in depth.txt within {max_dt} s")
    first = cv2.imread(str(folder / rgb_rows[pairs[0][1]][1]), cv2.IMREAD_COLOR)
    if first is None:
        raise RecordingError(f"{rgb_rows[pairs[0][1]][1]}: missing or unreadable image")
    height, width = first.shape[:2]
    check_intrinsics(K, width, height, "--intrinsics")
    stamps, poses, files, unposed = [], [], [], 0
    for stamp, ri, di in pairs:
        T = track.at(stamp, int(max_pose_gap * 1e9))
        if T is None:
            if skip_unposed:
                unposed += 1
                continue
            raise RecordingError(
                f"rgb.txt: {rgb_rows[ri][1]} (t={stamp / 1e9:.6f} s) has no pose: "
                f"{track.why_none(stamp, int(max_pose_gap * 1e9))} (pass --skip-unposed to drop such frames)"
            )
        stamps.append(stamp)
        poses.append(T)
        files.append((rgb_rows[ri][1], depth_rows[di][1]))
    if not stamps:
        raise RecordingError(f"rgb.txt: no frame has a pose in {gt_path.name}")
    for name in {f for pair in files for f in pair}:
        if not (folder / name).is_file():
            raise RecordingError(f"{name}: missing image file")

    def stream(only=None):
        for k in range(len(files)) if only is None else only:
            rname, dname = files[k]
            bgr = cv2.imread(str(folder / rname), cv2.IMREAD_COLOR)
            raw = cv2.imread(str(folder / dname), cv2.IMREAD_UNCHANGED)
            if bgr is None or raw is None:
                raise RecordingError(f"{rname if bgr is None else dname}: unreadable image")
            if bgr.shape[:2] != (height, width) or raw.shape[:2] != (height, width):
                raise RecordingError(
                    f"{rname}: images of {bgr.shape[1]}x{bgr.shape[0]} / {raw.shape[1]}x"
                    f"{raw.shape[0]}, expected {width}x{height} (depth registered to colour)"
                )
            if raw.dtype != np.uint16 or raw.ndim != 2:
                raise RecordingError(f"{dname}: depth must be a 16-bit single-channel PNG, got {raw.dtype}")
            yield k, np.ascontiguousarray(bgr[..., ::-1]), raw.astype(np.float32) / np.float32(depth_scale)

    info = {
        "rgb_topic": "rgb.txt",
        "depth_topic": "depth.txt",
        "pose_source": gt_path.name,
        "colour_messages": len(rgb_rows),
        "depth_messages": len(depth_rows),
        "unpaired_colour": dropped,
        "unposed_dropped": unposed,
        "depth_scale": depth_scale,
    }
    rec = Recording(
        folder, "tum", K, width, height, np.asarray(stamps, dtype=np.int64), np.stack(poses), info
    )
    rec._frames = stream
    return rec


__all__ = ["open_tum"]
