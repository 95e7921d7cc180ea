"""Recorded posed RGB-D: ROS 1 bags, ROS 2 bags (sqlite3 or MCAP storage), bare MCAP files and TUM RGB-D
folders, read without a ROS install (``rosbags``, pure Python).

A :class:`Recording` is scanned once up front (:func:`open_recording`): the camera intrinsics, the time
stamp of every colour / depth pair and its camera pose are known, and every check that can fail (a
missing topic, an unsupported encoding, a frame without a pose, time stamps going backwards, a truncated
file) has run, before anything is mapped or written. :meth:`Recording.frames` then streams the images.
The readers: `robot.bags` (ROS 1 / ROS 2 bags, MCAP) and `robot.tum` (TUM RGB-D folders).

Conventions (README, "Recorded data"):

- **Images**: ``sensor_msgs/Image`` colour in ``rgb8``, ``bgr8``, ``rgba8`` or ``bgra8`` (or a
  ``sensor_msgs/CompressedImage`` JPEG / PNG), depth in ``16UC1`` / ``mono16`` (millimetres) or ``32FC1``
  (metres; NaN reads as no depth), or image_transport's ``compressedDepth`` PNG. Depth must be
  *registered to the colour camera* (same size, same intrinsics, e.g. the Azure Kinect driver's
  ``depth_to_rgb`` topic): it is not reprojected. Images are used as they are (rectified topics expected;
  distortion coefficients are ignored).
- **Intrinsics**: the first ``sensor_msgs/CameraInfo`` of the camera-info topic (``K``/``k``); any size;
  or ``intrinsics`` (fx fy cx cy) for a bag without one. A principal point outside the image is refused.
  Both in the ROS / OpenCV convention (pixel (u, v)'s centre at (u, v)); the map is made with the same
  camera in this project's (:attr:`Recording.mapper_K`, half a pixel more).
- **Time**: the header stamps. A colour image is paired with the depth image of the nearest stamp within
  ``max_dt``; unpaired colour images are dropped (counted in ``Recording.info``).
- **Poses** (camera-to-world, OpenCV optical axes, as the rest of the project): ``tf:WORLD`` or
  ``tf:WORLD:FRAME`` chains ``/tf`` and ``/tf_static`` from WORLD to FRAME (default: the camera-info
  header's frame, the optical frame); a topic of type ``nav_msgs/Odometry``,
  ``geometry_msgs/PoseStamped`` or ``PoseWithCovarianceStamped`` gives the pose of a body frame, moved
  to the camera by ``camera_in_body`` (x y z qx qy qz qw) or, when not given, by the ``/tf_static``
  chain from the odometry's child frame to the camera frame when the bag has one, else used as the
  camera's pose. Poses are interpolated (linear position, slerp rotation) at the colour stamp; a frame
  farther than ``max_pose_gap`` from a pose sample on either side has no pose (before the first or after
  the last sample: one within a tenth of ``max_pose_gap`` is used as it is).
- **TUM RGB-D folders** (``rgb.txt``, ``depth.txt``, ``groundtruth.txt``; 16-bit PNG depth divided by
  ``depth_scale``, 5000 in TUM): intrinsics from ``intrinsics`` (fx fy cx cy), poses from the ground
  truth (``timestamp tx ty tz qx qy qz qw``, the colour camera's optical frame in the world).
- **Depth unit**: checked against the camera motion after the scan (`robot.depth_check`): depth that a
  few pairs of frames 10 cm apart agree is off by a factor outside [0.8, 1.25] (a wrong ``depth_scale``,
  16UC1 depth that is not millimetres) is a RecordingError.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from activesplat.errors import RecordingError
from activesplat.geometry import K_from_opencv

RECORDINGS = ("a ROS 1 bag (.bag), a ROS 2 bag (its folder, its .db3 file, or an .mcap file of profile ros2) "
              "or a TUM RGB-D folder (rgb.txt, depth.txt, groundtruth.txt)")
"""What `activesplat map` reads, for its messages."""


# --------------------------------------------------------------------------- the recording
@dataclass
class Recording:
    """A scanned recording: ``K`` (3x3, as the recording gives it: ROS / OpenCV, pixel (u, v)'s centre at
    (u, v); :attr:`mapper_K` is the same camera in this project's convention), image size, and per frame
    (colour / depth pair, in time order) its stamp (ns) and camera-to-world pose in the pose source's world
    frame. :meth:`frames` streams the images."""

    path: Path
    kind: str  # "ros1", "ros2", "mcap", "tum"
    K: np.ndarray
    width: int
    height: int
    stamps: np.ndarray
    poses: np.ndarray
    info: dict = field(default_factory=dict)
    _frames: object = None  # callable (only=None) -> iterator of (index, rgb uint8 (H,W,3), depth float32 m)

    def __len__(self) -> int:
        return len(self.stamps)

    @property
    def mapper_K(self) -> np.ndarray:
        """K in this project's convention (pixel centres at integer + 0.5, `geometry.PIXEL_CENTRE`): what the
        mapper, render-eval and the viewer use; the principal point half a pixel more than ``K``'s."""
        return K_from_opencv(self.K)

    def frames(self, only=None) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        """(index, rgb uint8 (H, W, 3), depth float32 metres (H, W), 0 = no depth), in time order; ``only``
        (sorted frame indices): just those, the stream ending after the last."""
        return self._frames() if only is None else self._frames(only)


def open_recording(
    path: str | Path,
    rgb_topic: str | None = None,
    depth_topic: str | None = None,
    camera_info_topic: str | None = None,
    pose_source: str | None = None,
    camera_in_body=None,
    intrinsics=None,
    depth_scale: float = 5000.0,
    max_dt: float = 0.02,
    max_pose_gap: float = 0.5,
    skip_unposed: bool = False,
    depth_check: bool = True,
) -> Recording:
    """Scan a recording (module docstring): a ``.bag`` (ROS 1), a ROS 2 bag folder (``metadata.yaml``), a
    ``.mcap`` / ``.db3`` file, or a TUM RGB-D folder (``rgb.txt``). Raises RecordingError (one line naming
    the topic or file) on anything that cannot be mapped, a depth unit the camera motion contradicts
    included (`robot.depth_check`, unless ``depth_check`` is false; its result in ``info["depth_check"]``)."""
    rec = _scan(path, rgb_topic, depth_topic, camera_info_topic, pose_source, camera_in_body, intrinsics,
                depth_scale, max_dt, max_pose_gap, skip_unposed)
    if depth_check:
        from activesplat.robot.depth_check import check_depth_scale

        rec.info["depth_check"] = check_depth_scale(rec)
    else:
        rec.info["depth_check"] = {"note": "skipped (--no-depth-check)"}
    return rec


def _scan(path, rgb_topic, depth_topic, camera_info_topic, pose_source, camera_in_body, intrinsics,
          depth_scale, max_dt, max_pose_gap, skip_unposed) -> Recording:
    p = Path(path)
    if not p.exists():
        raise RecordingError(f"{p}: no such file or folder")
    if max_dt <= 0 or max_pose_gap <= 0:
        raise RecordingError(f"--max-dt and --max-pose-gap must be > 0, got {max_dt} and {max_pose_gap}")
    from activesplat.robot.bags import BagScan, describe_topics, topics_of
    from activesplat.robot.tum import open_tum

    if p.is_dir() and (p / "rgb.txt").is_file():
        return open_tum(p, intrinsics, depth_scale, pose_source, max_dt, max_pose_gap, skip_unposed)
    _check_recording(p)
    missing = [
        name
        for name, v in (
            ("--rgb-topic", rgb_topic),
            ("--depth-topic", depth_topic),
            ("--camera-info-topic (or --intrinsics)", camera_info_topic or intrinsics),
            ("--pose-source", pose_source),
        )
        if not v
    ]
    if missing:
        raise RecordingError(f"{p}: a bag needs {', '.join(missing)}; {describe_topics(topics_of(p))}")
    if camera_info_topic and intrinsics is not None:
        raise RecordingError("give --camera-info-topic or --intrinsics, not both")
    return BagScan(
        p,
        rgb_topic,
        depth_topic,
        camera_info_topic,
        pose_source,
        camera_in_body,
        max_dt,
        max_pose_gap,
        skip_unposed,
        intrinsics,
    ).run()


def intrinsics_matrix(values) -> np.ndarray:
    """K (3x3) of ``--intrinsics FX FY CX CY``."""
    fx, fy, cx, cy = (float(v) for v in values)
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def check_intrinsics(K: np.ndarray, width: int, height: int, where: str) -> None:
    """RecordingError unless K has positive focal lengths and its principal point lies inside the
    width x height image (intrinsics of another resolution otherwise map every pixel to the wrong ray)."""
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if not np.isfinite(K).all() or fx <= 0 or fy <= 0 or width <= 0 or height <= 0:
        raise RecordingError(f"{where}: invalid intrinsics K={K.tolist()} for a {width}x{height} camera")
    if not (0 < cx < width and 0 < cy < height):
        raise RecordingError(
            f"{where}: principal point ({cx:g}, {cy:g}) outside the {width}x{height} images: intrinsics of "
            f"another resolution? (scale fx fy cx cy by the image size over the calibrated size)"
        )


def _check_recording(p: Path) -> None:
    """A RecordingError saying what `map` reads when `p` (not a TUM folder) cannot be a ROS bag: a mesh or
    another file, a folder without a bag's metadata.yaml, an MCAP file that is not a ROS 2 bag."""
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return
        what = ("an episode or map folder, not a recording" if (p / "episode.json").is_file() else
                "a folder that is neither a ROS 2 bag (no metadata.yaml) nor a TUM RGB-D folder (no rgb.txt)")
        raise RecordingError(f"{p}: {what}; `map` reads {RECORDINGS}")
    from activesplat.sim.scene import MESH_SUFFIXES  # scenes to explore, not recordings

    if p.suffix.lower() in MESH_SUFFIXES:
        raise RecordingError(f"{p}: a mesh, not a recording; `map` reads {RECORDINGS}. To explore the mesh, "
                             f"run `activesplat explore --scene {p}`")
    if p.suffix not in (".bag", ".db3", ".mcap"):
        raise RecordingError(f"{p}: not a recording; `map` reads {RECORDINGS}")
    header = mcap_header(p) if p.suffix == ".mcap" else None
    if header is not None and header[0] != "ros2":
        profile, library = header
        if profile == "ros1":
            raise RecordingError(f"{p}: an MCAP file of profile 'ros1' (ROS 1 messages); `map` reads ROS 1 "
                                 f"recordings as .bag files and MCAP files of profile ros2 (ROS 2)")
        if library.startswith("activesplat"):
            by = " written by `activesplat export` for Foxglove (JSON messages)"
        else:
            by = f" (library {library!r})" if library else ""
        raise RecordingError(f"{p}: an MCAP file of profile {profile!r}{by}, not a ROS bag; `map` reads "
                             f"{RECORDINGS}")


def mcap_header(path: Path) -> tuple[str, str] | None:
    """(profile, library) of an MCAP file's header record; None when the file does not start like one (a
    truncated or corrupt file, which the bag reader then reports)."""
    import struct

    try:
        with open(path, "rb") as f:
            head = f.read(8 + 1 + 8 + 4096)
        if head[:8] != b"\x89MCAP0\r\n" or head[8] != 0x01:  # magic, then the Header record (op 0x01)
            return None
        at = 8 + 1 + 8
        strings = []
        for _ in range(2):  # profile, library: uint32 length + UTF-8
            (n,) = struct.unpack_from("<I", head, at)
            strings.append(head[at + 4: at + 4 + n].decode("utf-8", "replace"))
            at += 4 + n
        return strings[0], strings[1]
    except (OSError, IndexError, struct.error):
        return None


def pair_nearest(rgb: list[tuple[int, int]], depth: list[tuple[int, int]], max_dt_ns: int):
    """[(stamp, rgb index, depth index)] pairing each colour image with the depth of the nearest stamp
    within ``max_dt_ns``; and the number of colour images left without depth."""
    ds = np.array([s for s, _ in depth], dtype=np.int64)
    pairs, dropped = [], 0
    for stamp, ri in rgb:
        j = int(np.searchsorted(ds, stamp))
        best = min((k for k in (j - 1, j) if 0 <= k < len(ds)), key=lambda k: abs(int(ds[k]) - stamp))
        if abs(int(ds[best]) - stamp) <= max_dt_ns:
            pairs.append((stamp, ri, depth[best][1]))
        else:
            dropped += 1
    return pairs, dropped


__all__ = [
    "RECORDINGS",
    "Recording",
    "check_intrinsics",
    "intrinsics_matrix",
    "mcap_header",
    "open_recording",
    "pair_nearest",
]
