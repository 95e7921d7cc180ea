"""ROS 1 bags, ROS 2 bags (sqlite3 or MCAP storage) and bare MCAP files, read with ``rosbags`` (pure
Python, no ROS install): the image decoders (also used by the live bridge) and the two passes over a bag
that `robot.recording.open_recording` runs (conventions: its module docstring)."""

from __future__ import annotations

import numpy as np

from activesplat.errors import RecordingError
from activesplat.robot.recording import Recording, check_intrinsics, intrinsics_matrix, pair_nearest
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


def decode_compressed_depth(msg, topic: str, index: int) -> np.ndarray:
    """Depth in metres of a ``sensor_msgs/CompressedImage`` from image_transport's compressedDepth
    plugin (format ``16UC1; compressedDepth png`` or ``32FC1; ...``): a 12-byte header (an int32 and
    the two float32 inverse-depth quantisation parameters A, B), then a 16-bit PNG of millimetres
    (16UC1) or of A / depth + B (32FC1, 0 = no depth)."""
    import cv2

    fmt = str(msg.format)
    enc = fmt.split(";")[0].strip()
    if "compresseddepth" not in fmt.lower() or enc not in ("16UC1", "32FC1") or "rvl" in fmt.lower():
        raise RecordingError(
            f"{topic}: message {index}: a CompressedImage of format {fmt!r}; depth is read from "
            f"sensor_msgs/Image or image_transport's compressedDepth PNG (16UC1 or 32FC1)"
        )
    data = np.asarray(msg.data, dtype=np.uint8)
    png = cv2.imdecode(data[12:], cv2.IMREAD_UNCHANGED) if data.size > 12 else None
    if png is None or png.dtype != np.uint16 or png.ndim != 2:
        raise RecordingError(f"{topic}: message {index}: undecodable compressedDepth image ({fmt!r})")
    if enc == "16UC1":
        return png.astype(np.float32) * np.float32(0.001)
    a, b = np.frombuffer(data[4:12].tobytes(), dtype="<f4")
    depth = np.zeros(png.shape, np.float32)
    valid = png > 0
    depth[valid] = a / (png[valid].astype(np.float32) - b)
    depth[~np.isfinite(depth) | (depth < 0)] = 0.0
    return depth


def decode_depth(msg, topic: str, index: int, compressed: bool = False) -> np.ndarray:
    """Depth in metres (float32, 0 = invalid) of a depth message; RecordingError otherwise."""
    if compressed:
        return decode_compressed_depth(msg, topic, index)
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


class BagScan:
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
        intrinsics=None,
    ):
        self.intrinsics = intrinsics
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

    def _read(self, topics: list[str]):
        """Yield (topic, msgtype, index within its topic, deserialized message) in log order; a truncated
        or corrupt file becomes a RecordingError naming the topic of the message it broke on."""
        counts = {t: 0 for t in topics}
        topic = None
        try:
            with _reader(self.path) as reader:
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

    def run(self) -> Recording:
        topics = topics_of(self.path)
        for option, topic in (
            ("--rgb-topic", self.rgb_topic),
            ("--depth-topic", self.depth_topic),
            ("--camera-info-topic", self.info_topic),
        ):
            if topic is not None and topic not in topics:
                raise RecordingError(
                    f"{option} {topic}: no such topic in {self.path.name} ({describe_topics(topics)})"
                )
        expected = {
            self.rgb_topic: ("Image", "CompressedImage"),
            self.depth_topic: ("Image", "CompressedImage"),
            self.info_topic: ("CameraInfo",),
        }
        for topic, kinds in expected.items():
            if topic is not None and topics[topic].split("/")[-1] not in kinds:
                raise RecordingError(
                    f"{topic}: messages of type {topics[topic]}, expected "
                    f"{' or '.join('sensor_msgs/' + k for k in kinds)}"
                )
        self.rgb_compressed = _image_kind(topics[self.rgb_topic]) == "compressed"
        self.depth_compressed = _image_kind(topics[self.depth_topic]) == "compressed"
        pose_topics, self.tf_world, self.tf_frame = self._pose_topics(topics)

        rgb, depth = [], []  # (stamp, index)
        info = first_rgb = None
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
                if first_rgb is None:
                    first_rgb = msg
                rgb.append((stamp, index, int(getattr(msg, "width", 0)), int(getattr(msg, "height", 0))))
            elif topic == self.depth_topic:
                self._check_image(msg, topic, index, color=False)
                depth.append((stamp, index, int(getattr(msg, "width", 0)), int(getattr(msg, "height", 0))))
            elif topic == self.pose_source:
                pose_msg = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
                track_stamps.append(stamp)
                track_poses.append(pose_matrix(xyz(pose_msg.position), xyzw(pose_msg.orientation)))
                body_frame = getattr(msg, "child_frame_id", None) or body_frame
        if not rgb or not depth:
            raise RecordingError(f"{self.rgb_topic if not rgb else self.depth_topic}: no messages")
        if self.info_topic is None:  # --intrinsics instead: the size of the first colour image
            K = intrinsics_matrix(self.intrinsics)
            height, width = decode_color(first_rgb, self.rgb_topic, 0, self.rgb_compressed).shape[:2]
            rgb = [(s, i, w or width, h or height) for s, i, w, h in rgb]
            info, where = first_rgb, "--intrinsics"
        elif info is None:
            raise RecordingError(
                f"{self.info_topic}: no CameraInfo message in the recording (give the camera's --intrinsics "
                f"FX FY CX CY instead of --camera-info-topic)"
            )
        else:
            K = np.asarray(_field(info, "k", "K"), dtype=np.float64).reshape(3, 3)
            width, height = int(info.width), int(info.height)
            where = f"{self.info_topic}: message 0"
        check_intrinsics(K, width, height, where)
        self.width, self.height = width, height
        described = self.info_topic or "the first colour image"
        for topic, items in ((self.rgb_topic, rgb), (self.depth_topic, depth)):
            for _, index, w, h in items:
                if (w, h) != (width, height) and w:
                    raise RecordingError(
                        f"{topic}: message {index}: a {w}x{h} image, but {described} "
                        f"describes a {width}x{height} camera (depth must be registered to "
                        f"colour)"
                    )
        camera_frame = self.tf_frame or info.header.frame_id
        pairs, dropped = pair_nearest(
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

            def why(stamp):
                return tf.why_none(self.tf_world, camera_frame, stamp, self.max_gap_ns)
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

            def why(stamp):
                return track.why_none(stamp, self.max_gap_ns)

        stamps, poses, indices, unposed = [], [], [], 0
        for stamp, ri, di in pairs:
            T = lookup(stamp)
            if T is None:
                if self.skip_unposed:
                    unposed += 1
                    continue
                raise RecordingError(
                    f"{self.rgb_topic}: message {ri} (t={stamp / 1e9:.6f} s) has no pose from "
                    f"{source}: {why(stamp)} (pass --skip-unposed to drop such frames)"
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
        rec._frames = lambda only=None: self._stream(indices, only)
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
                f"--pose-source {src}: no such topic in {self.path.name} ({describe_topics(topics)})"
            )
        if topics[src] not in POSE_TYPES:
            raise RecordingError(
                f"{src}: messages of type {topics[src]}; a pose source is nav_msgs/Odometry, "
                f"geometry_msgs/PoseStamped or PoseWithCovarianceStamped, or tf:WORLD_FRAME"
            )
        return [src] + (["/tf_static"] if "/tf_static" in topics else []), None, None

    def _check_image(self, msg, topic: str, index: int, color: bool) -> None:
        if self.rgb_compressed if color else self.depth_compressed:
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

    def _sized(self, image: np.ndarray, topic: str, index: int) -> np.ndarray:
        """``image``, or a RecordingError when (a compressed one, whose size the scan could not check) is
        not of the camera's size."""
        if image.shape[:2] != (self.height, self.width):
            raise RecordingError(
                f"{topic}: message {index}: a {image.shape[1]}x{image.shape[0]} image, but the camera is "
                f"{self.width}x{self.height} (depth must be registered to colour)"
            )
        return image

    def _stream(self, indices: list[tuple[int, int]], only=None):
        """The frames of ``indices`` (colour, depth message indices) in order; ``only`` (sorted frame
        indices): just those, reading the bag no further than the last."""
        ks = list(range(len(indices))) if only is None else list(only)
        want_rgb = {indices[k][0]: k for k in ks}
        want_depth: dict[int, list[int]] = {}
        for k in ks:
            want_depth.setdefault(indices[k][1], []).append(k)
        got_rgb: dict[int, np.ndarray] = {}
        got_depth: dict[int, np.ndarray] = {}
        at = 0  # position in ks of the next frame to yield
        if not ks:
            return
        for topic, _, index, msg in self._read([self.rgb_topic, self.depth_topic]):
            if topic == self.rgb_topic and index in want_rgb:
                got_rgb[want_rgb[index]] = self._sized(
                    decode_color(msg, topic, index, self.rgb_compressed), topic, index
                )
            if topic == self.depth_topic and index in want_depth:
                d = self._sized(decode_depth(msg, topic, index, self.depth_compressed), topic, index)
                for k in want_depth[index]:
                    got_depth[k] = d
            while at < len(ks) and ks[at] in got_rgb and ks[at] in got_depth:
                yield ks[at], got_rgb.pop(ks[at]), got_depth.pop(ks[at])
                at += 1
            if at == len(ks):
                return
        raise RecordingError(f"{self.rgb_topic}: message {indices[ks[at]][0]} could not be read back")


def _reader(path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    return AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))


def topics_of(path) -> dict[str, str]:
    """{topic: message type} of a bag; RecordingError when it cannot be read."""
    try:
        with _reader(path) as reader:
            return {c.topic: c.msgtype for c in reader.connections}
    except Exception as exc:
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise RecordingError(f"{path}: truncated or corrupt recording: {text}") from None


def describe_topics(topics: dict[str, str]) -> str:
    """'topics: /a (sensor_msgs/msg/Image), ...' for a message that asks for a topic."""
    return "topics: " + (", ".join(f"{t} ({topics[t]})" for t in sorted(topics)) or "none")


def _body_transform(values) -> np.ndarray:
    v = [float(x) for x in values]
    if len(v) != 7:
        raise RecordingError(f"--camera-in-body expects 7 numbers (x y z qx qy qz qw), got {len(v)}")
    try:
        return pose_matrix(v[:3], v[3:])
    except ValueError as exc:
        raise RecordingError(f"--camera-in-body: {exc}") from None


__all__ = [
    "COLOR_ENCODINGS",
    "DEPTH_ENCODINGS",
    "POSE_TYPES",
    "BagScan",
    "decode_color",
    "decode_depth",
    "describe_topics",
    "topics_of",
]
