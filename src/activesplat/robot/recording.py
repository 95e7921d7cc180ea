"""Recorded posed RGB-D: ROS 1 bags, ROS 2 bags (sqlite3 or MCAP storage), bare MCAP files and TUM RGB-D
folders, read without a ROS install (``rosbags``, pure Python).

A :class:`Recording` is scanned once up front (:func:`open_recording`): the camera intrinsics, the time
stamp of every colour / depth pair and its camera pose are known, and every check that can fail (a
missing topic, an unsupported encoding, a frame without a pose, time stamps going backwards, a truncated
file) has run, before anything is mapped or written. :meth:`Recording.frames` then streams the images.

Conventions (README, "Recorded data"):

- **Images**: ``sensor_msgs/Image`` colour in ``rgb8``, ``bgr8``, ``rgba8`` or ``bgra8`` (or a
  ``sensor_msgs/CompressedImage`` JPEG / PNG), depth in ``16UC1`` / ``mono16`` (millimetres) or ``32FC1``
  (metres; NaN reads as no depth). Depth must be *registered to the colour camera* (same size, same
  intrinsics, e.g. the Azure Kinect driver's ``depth_to_rgb`` topic): it is not reprojected. Images are
  used as they are (rectified topics expected; distortion coefficients are ignored).
- **Intrinsics**: the first ``sensor_msgs/CameraInfo`` of the camera-info topic (``K``/``k``); any size.
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
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from activesplat.errors import RecordingError
from activesplat.robot.transforms import PoseTrack, TfTree, pose_matrix, stamp_ns, xyz, xyzw

COLOR_ENCODINGS = ("rgb8", "bgr8", "rgba8", "bgra8")
DEPTH_ENCODINGS = {"16UC1": 0.001, "mono16": 0.001, "32FC1": 1.0}
"""Depth encodings and their scale to metres."""
POSE_TYPES = (
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "nav_msgs/Odometry",
    "geometry_msgs/PoseStamped",
    "geometry_msgs/PoseWithCovarianceStamped",
)


# --------------------------------------------------------------------------- the recording
@dataclass
class Recording:
    """A scanned recording: ``K`` (3x3), image size, and per frame (colour / depth pair, in time order) its
    stamp (ns) and camera-to-world pose in the pose source's world frame. :meth:`frames` streams the
    images."""

    path: Path
    kind: str  # "ros1", "ros2", "mcap", "tum"
    K: np.ndarray
    width: int
    height: int
    stamps: np.ndarray
    poses: np.ndarray
    info: dict = field(default_factory=dict)
    _frames: object = None  # callable () -> iterator of (index, rgb uint8 (H,W,3), depth float32 m (H,W))

    def __len__(self) -> int:
        return len(self.stamps)

    def frames(self) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        """(index, rgb uint8 (H, W, 3), depth float32 metres (H, W), 0 = no depth), in time order."""
        return self._frames()


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
) -> Recording:
    """Scan a recording (module docstring): a ``.bag`` (ROS 1), a ROS 2 bag folder (``metadata.yaml``), a
    ``.mcap`` / ``.db3`` file, or a TUM RGB-D folder (``rgb.txt``). Raises RecordingError (one line naming
    the topic or file) on anything that cannot be mapped."""
    p = Path(path)
    if not p.exists():
        raise RecordingError(f"{p}: no such file or folder")
    if max_dt <= 0 or max_pose_gap <= 0:
        raise RecordingError(f"--max-dt and --max-pose-gap must be > 0, got {max_dt} and {max_pose_gap}")
    if p.is_dir() and (p / "rgb.txt").is_file():
        return _open_tum(p, intrinsics, depth_scale, pose_source, max_dt, max_pose_gap, skip_unposed)
    missing = [
        name
        for name, v in (
            ("--rgb-topic", rgb_topic),
            ("--depth-topic", depth_topic),
            ("--camera-info-topic", camera_info_topic),
            ("--pose-source", pose_source),
        )
        if not v
    ]
    if missing:
        raise RecordingError(f"{p}: a bag needs {', '.join(missing)}")
    return _BagScan(
        p,
        rgb_topic,
        depth_topic,
        camera_info_topic,
        pose_source,
        camera_in_body,
        max_dt,
        max_pose_gap,
        skip_unposed,
    ).run()


# --------------------------------------------------------------------------- ROS bags
def _field(msg, *names):
    for n in names:
        if hasattr(msg, n):
            return getattr(msg, n)
    raise AttributeError(names[0])


def _image_kind(msgtype: str) -> str:
    return "compressed" if msgtype.endswith("CompressedImage") else "raw"


def decode_color(msg, topic: str, index: int, compressed: bool) -> np.ndarray:
    """RGB uint8 (H, W, 3) of a colour message; RecordingError naming topic and message otherwise."""
    if compressed:
        import cv2

        img = cv2.imdecode(np.asarray(msg.data, dtype=np.uint8), cv2.IMREAD_COLOR)
        if img is None:
            raise RecordingError(f"{topic}: message {index}: undecodable compressed image ({msg.format!r})")
        return np.ascontiguousarray(img[..., ::-1])
    enc = msg.encoding
    if enc not in COLOR_ENCODINGS:
        raise RecordingError(
            f"{topic}: message {index}: unsupported colour encoding {enc!r} "
            f"(supported: {', '.join(COLOR_ENCODINGS)})"
        )
    c = 4 if enc.endswith("a8") else 3
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < w * c or data.size < h * step:
        raise RecordingError(f"{topic}: message {index}: {data.size} bytes do not hold a {w}x{h} {enc} image")
    img = data[: h * step].reshape(h, step)[:, : w * c].reshape(h, w, c)[..., :3]
    if enc.startswith("bgr"):
        img = img[..., ::-1]
    return np.array(img, order="C")  # a writable copy (the message buffer may be read-only)


def decode_depth(msg, topic: str, index: int) -> np.ndarray:
    """Depth in metres (float32, 0 = invalid) of a depth message; RecordingError otherwise."""
    enc = msg.encoding
    if enc not in DEPTH_ENCODINGS:
        raise RecordingError(
            f"{topic}: message {index}: unsupported depth encoding {enc!r} "
            f"(supported: {', '.join(DEPTH_ENCODINGS)})"
        )
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    itemsize = 2 if enc != "32FC1" else 4
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < w * itemsize or data.size < h * step:
        raise RecordingError(f"{topic}: message {index}: {data.size} bytes do not hold a {w}x{h} {enc} image")
    dtype = np.dtype(np.uint16 if itemsize == 2 else np.float32).newbyteorder(
        ">" if msg.is_bigendian else "<"
    )
    rows = data[: h * step].reshape(h, step)[:, : w * itemsize]
    depth = np.ascontiguousarray(rows).view(dtype).reshape(h, w).astype(np.float32) * DEPTH_ENCODINGS[enc]
    depth[~np.isfinite(depth) | (depth < 0)] = 0.0
    return depth


class _BagScan:
    """The two passes over a bag: scan (poses, intrinsics, stamps, checks), then stream the images."""

    def __init__(
        self,
        path,
        rgb_topic,
        depth_topic,
        info_topic,
        pose_source,
        camera_in_body,
        max_dt,
        max_pose_gap,
        skip_unposed,
    ):
        self.path, self.rgb_topic, self.depth_topic, self.info_topic = (
            path,
            rgb_topic,
            depth_topic,
            info_topic,
        )
        self.pose_source = pose_source
        self.camera_in_body = None if camera_in_body is None else _body_transform(camera_in_body)
        self.max_dt_ns, self.max_gap_ns = int(max_dt * 1e9), int(max_pose_gap * 1e9)
        self.skip_unposed = skip_unposed
        if path.is_dir():
            self.kind = "ros2"
        elif path.suffix == ".bag":
            self.kind = "ros1"
        elif path.suffix in (".mcap", ".db3"):
            self.kind = "mcap" if path.suffix == ".mcap" else "ros2"
        else:
            raise RecordingError(
                f"{path}: not a recording (expected a .bag, .mcap or .db3 file, a ROS 2 bag "
                f"folder or a TUM RGB-D folder)"
            )

    def _reader(self):
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        return AnyReader([self.path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))

    def _read(self, topics: list[str]):
        """Yield (topic, msgtype, index within its topic, deserialized message) in log order; a truncated
        or corrupt file becomes a RecordingError naming the topic of the message it broke on."""
        counts = {t: 0 for t in topics}
        topic = None
        try:
            with self._reader() as reader:
                conns = [c for c in reader.connections if c.topic in topics]
                for conn, _, raw in reader.messages(connections=conns):
                    topic = conn.topic
                    msg = reader.deserialize(raw, conn.msgtype)
                    yield topic, conn.msgtype, counts[topic], msg
                    counts[topic] += 1
        except RecordingError:
            raise
        except Exception as exc:  # rosbags raises many types on a truncated or corrupt file
            where = f" at {topic} message {counts[topic]}" if topic is not None else ""
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise RecordingError(f"{self.path}: truncated or corrupt recording{where}: {text}") from None

    def _topics(self) -> dict[str, str]:
        try:
            with self._reader() as reader:
                return {c.topic: c.msgtype for c in reader.connections}
        except Exception as exc:
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise RecordingError(f"{self.path}: truncated or corrupt recording: {text}") from None

    def run(self) -> Recording:
        topics = self._topics()
        for option, topic in (
            ("--rgb-topic", self.rgb_topic),
            ("--depth-topic", self.depth_topic),
            ("--camera-info-topic", self.info_topic),
        ):
            if topic not in topics:
                raise RecordingError(
                    f"{option} {topic}: no such topic in {self.path.name} "
                    f"(topics: {', '.join(sorted(topics)) or 'none'})"
                )
        expected = {
            self.rgb_topic: ("Image", "CompressedImage"),
            self.depth_topic: ("Image",),
            self.info_topic: ("CameraInfo",),
        }
        for topic, kinds in expected.items():
            if topics[topic].split("/")[-1] not in kinds:
                raise RecordingError(
                    f"{topic}: messages of type {topics[topic]}, expected "
                    f"{' or '.join('sensor_msgs/' + k for k in kinds)}"
                )
        self.rgb_compressed = _image_kind(topics[self.rgb_topic]) == "compressed"
        pose_topics, self.tf_world, self.tf_frame = self._pose_topics(topics)

        rgb, depth = [], []  # (stamp, index)
        info = None
        tf = TfTree()
        track_stamps, track_poses, body_frame = [], [], None
        last = {}
        for topic, _, index, msg in self._read(
            [self.rgb_topic, self.depth_topic, self.info_topic, *pose_topics]
        ):
            if topic == self.info_topic:
                if info is None:
                    info = msg
                continue
            if topic in ("/tf", "/tf_static") and topic not in (self.rgb_topic, self.depth_topic):
                for tr in msg.transforms:
                    tf.add(tr, static=topic == "/tf_static", topic=topic, index=index)
                if topic != self.pose_source:
                    continue
            stamp = stamp_ns(msg)
            if topic in last and stamp < last[topic]:
                raise RecordingError(
                    f"{topic}: message {index}: time stamp {stamp / 1e9:.6f} s goes back "
                    f"before the previous message's {last[topic] / 1e9:.6f} s (non-monotonic)"
                )
            last[topic] = stamp
            if topic == self.rgb_topic:
                self._check_image(msg, topic, index, color=True)
                rgb.append((stamp, index, int(getattr(msg, "width", 0)), int(getattr(msg, "height", 0))))
            elif topic == self.depth_topic:
                self._check_image(msg, topic, index, color=False)
                depth.append((stamp, index, int(msg.width), int(msg.height)))
            elif topic == self.pose_source:
                pose_msg = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
                track_stamps.append(stamp)
                track_poses.append(pose_matrix(xyz(pose_msg.position), xyzw(pose_msg.orientation)))
                body_frame = getattr(msg, "child_frame_id", None) or body_frame
        if info is None:
            raise RecordingError(f"{self.info_topic}: no CameraInfo message in the recording")
        if not rgb or not depth:
            raise RecordingError(f"{self.rgb_topic if not rgb else self.depth_topic}: no messages")
        K = np.asarray(_field(info, "k", "K"), dtype=np.float64).reshape(3, 3)
        width, height = int(info.width), int(info.height)
        if K[0, 0] <= 0 or K[1, 1] <= 0 or width <= 0 or height <= 0:
            raise RecordingError(
                f"{self.info_topic}: message 0: invalid intrinsics K={K.tolist()} for a "
                f"{width}x{height} camera"
            )
        for topic, items in ((self.rgb_topic, rgb), (self.depth_topic, depth)):
            for _, index, w, h in items:
                if (w, h) != (width, height) and w:
                    raise RecordingError(
                        f"{topic}: message {index}: a {w}x{h} image, but {self.info_topic} "
                        f"describes a {width}x{height} camera (depth must be registered to "
                        f"colour)"
                    )
        camera_frame = self.tf_frame or info.header.frame_id
        pairs, dropped = _pair(
            [(s, i) for s, i, _, _ in rgb], [(s, i) for s, i, _, _ in depth], self.max_dt_ns
        )
        if not pairs:
            raise RecordingError(
                f"{self.rgb_topic}: no colour image has a depth image on {self.depth_topic} "
                f"within {self.max_dt_ns / 1e9:.3f} s"
            )
        if self.tf_world is not None:
            lookup = self._tf_lookup(tf, camera_frame)
            source = f"/tf ({self.tf_world} -> {camera_frame})"
        else:
            track = PoseTrack(track_stamps, track_poses, self.pose_source)
            if not len(track.stamps):
                raise RecordingError(f"{self.pose_source}: no pose messages")
            extrinsic = self.camera_in_body
            if extrinsic is None and body_frame:
                extrinsic = tf.static_chain(body_frame, camera_frame)
            extrinsic = np.eye(4) if extrinsic is None else extrinsic
            source = self.pose_source

            def lookup(stamp):
                T = track.at(stamp, self.max_gap_ns)
                return None if T is None else T @ extrinsic

        stamps, poses, indices, unposed = [], [], [], 0
        for stamp, ri, di in pairs:
            T = lookup(stamp)
            if T is None:
                if self.skip_unposed:
                    unposed += 1
                    continue
                raise RecordingError(
                    f"{self.rgb_topic}: message {ri} (t={stamp / 1e9:.6f} s) has no pose from "
                    f"{source} within {self.max_gap_ns / 1e9:.3f} s (pass --skip-unposed to "
                    f"drop such frames)"
                )
            stamps.append(stamp)
            poses.append(T)
            indices.append((ri, di))
        if not stamps:
            raise RecordingError(f"{self.rgb_topic}: no frame has a pose from {source}")
        rec_info = {
            "rgb_topic": self.rgb_topic,
            "depth_topic": self.depth_topic,
            "camera_info_topic": self.info_topic,
            "pose_source": source,
            "camera_frame": camera_frame,
            "colour_messages": len(rgb),
            "depth_messages": len(depth),
            "unpaired_colour": dropped,
            "unposed_dropped": unposed,
        }
        rec = Recording(
            self.path,
            self.kind,
            K,
            width,
            height,
            np.asarray(stamps, dtype=np.int64),
            np.stack(poses),
            rec_info,
        )
        rec._frames = lambda: self._stream(indices)
        return rec

    def _pose_topics(self, topics: dict[str, str]) -> tuple[list[str], str | None, str | None]:
        src = self.pose_source
        if src.startswith("tf:"):
            parts = src.split(":")
            if len(parts) not in (2, 3) or not parts[1]:
                raise RecordingError(
                    f"--pose-source {src}: expected tf:WORLD_FRAME or tf:WORLD_FRAME:CAMERA_FRAME"
                )
            if "/tf" not in topics and "/tf_static" not in topics:
                raise RecordingError(f"--pose-source {src}: the recording has no /tf topic")
            return (
                [t for t in ("/tf", "/tf_static") if t in topics],
                parts[1],
                (parts[2] if len(parts) == 3 else None),
            )
        if src not in topics:
            raise RecordingError(
                f"--pose-source {src}: no such topic in {self.path.name} "
                f"(topics: {', '.join(sorted(topics))})"
            )
        if topics[src] not in POSE_TYPES:
            raise RecordingError(
                f"{src}: messages of type {topics[src]}; a pose source is nav_msgs/Odometry, "
                f"geometry_msgs/PoseStamped or PoseWithCovarianceStamped, or tf:WORLD_FRAME"
            )
        return [src] + (["/tf_static"] if "/tf_static" in topics else []), None, None

    def _check_image(self, msg, topic: str, index: int, color: bool) -> None:
        if color and self.rgb_compressed:
            return
        enc = msg.encoding
        if color and enc not in COLOR_ENCODINGS:
            raise RecordingError(
                f"{topic}: message {index}: unsupported colour encoding {enc!r} "
                f"(supported: {', '.join(COLOR_ENCODINGS)})"
            )
        if not color and enc not in DEPTH_ENCODINGS:
            raise RecordingError(
                f"{topic}: message {index}: unsupported depth encoding {enc!r} "
                f"(supported: {', '.join(DEPTH_ENCODINGS)})"
            )

    def _tf_lookup(self, tf: TfTree, camera_frame: str):
        world = self.tf_world
        if not tf.connected(world, camera_frame):
            raise RecordingError(
                f"/tf: no chain of transforms from {world!r} to {camera_frame!r} "
                f"(frames: {', '.join(sorted(tf.frames()))})"
            )
        return lambda stamp: tf.lookup(world, camera_frame, stamp, self.max_gap_ns)

    def _stream(self, indices: list[tuple[int, int]]):
        want_rgb = {ri: k for k, (ri, _) in enumerate(indices)}
        want_depth: dict[int, list[int]] = {}
        for k, (_, di) in enumerate(indices):
            want_depth.setdefault(di, []).append(k)
        got_rgb: dict[int, np.ndarray] = {}
        got_depth: dict[int, np.ndarray] = {}
        nxt = 0
        for topic, _, index, msg in self._read([self.rgb_topic, self.depth_topic]):
            if topic == self.rgb_topic and index in want_rgb:
                got_rgb[want_rgb[index]] = decode_color(msg, topic, index, self.rgb_compressed)
            if topic == self.depth_topic and index in want_depth:
                d = decode_depth(msg, topic, index)
                for k in want_depth[index]:
                    got_depth[k] = d
            while nxt < len(indices) and nxt in got_rgb and nxt in got_depth:
                yield nxt, got_rgb.pop(nxt), got_depth.pop(nxt)
                nxt += 1
        if nxt < len(indices):
            raise RecordingError(f"{self.rgb_topic}: message {indices[nxt][0]} could not be read back")


def _body_transform(values) -> np.ndarray:
    v = [float(x) for x in values]
    if len(v) != 7:
        raise RecordingError(f"--camera-in-body expects 7 numbers (x y z qx qy qz qw), got {len(v)}")
    try:
        return pose_matrix(v[:3], v[3:])
    except ValueError as exc:
        raise RecordingError(f"--camera-in-body: {exc}") from None


def _pair(rgb: list[tuple[int, int]], depth: list[tuple[int, int]], max_dt_ns: int):
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


# --------------------------------------------------------------------------- TUM RGB-D folders
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


def _open_tum(
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
    fx, fy, cx, cy = (float(v) for v in intrinsics)
    if fx <= 0 or fy <= 0 or depth_scale <= 0:
        raise RecordingError(
            f"--intrinsics fx, fy and --depth-scale must be > 0, got {fx}, {fy}, {depth_scale}"
        )
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
    pairs, dropped = _pair(
        [(int(s), i) for i, s in enumerate(rs)], [(int(s), i) for i, s in enumerate(ds)], int(max_dt * 1e9)
    )
    if not pairs:
        raise RecordingError(f"rgb.txt: no colour image has a depth image in depth.txt within {max_dt} s")
    first = cv2.imread(str(folder / rgb_rows[pairs[0][1]][1]), cv2.IMREAD_COLOR)
    if first is None:
        raise RecordingError(f"{rgb_rows[pairs[0][1]][1]}: missing or unreadable image")
    height, width = first.shape[:2]
    stamps, poses, files, unposed = [], [], [], 0
    for stamp, ri, di in pairs:
        T = track.at(stamp, int(max_pose_gap * 1e9))
        if T is None:
            if skip_unposed:
                unposed += 1
                continue
            raise RecordingError(
                f"rgb.txt: {rgb_rows[ri][1]} (t={stamp / 1e9:.6f} s) has no pose in "
                f"{gt_path.name} within {max_pose_gap} s (pass --skip-unposed to drop such frames)"
            )
        stamps.append(stamp)
        poses.append(T)
        files.append((rgb_rows[ri][1], depth_rows[di][1]))
    if not stamps:
        raise RecordingError(f"rgb.txt: no frame has a pose in {gt_path.name}")
    for name in {f for pair in files for f in pair}:
        if not (folder / name).is_file():
            raise RecordingError(f"{name}: missing image file")

    def stream():
        for k, (rname, dname) in enumerate(files):
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

    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
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
