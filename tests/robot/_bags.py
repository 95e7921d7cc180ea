"""Recordings written from our simulator's frames, for the `activesplat map` tests: ROS 1 / ROS 2 / MCAP
bags (rosbags writers, messages serialised by its typestores) and a TUM RGB-D folder."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from activesplat.geometry import K_to_opencv
from activesplat.robot.mapping import WORLD_UP
from activesplat.robot.transforms import matrix_tq

T0 = 1_700_000_000 * 10**9
DT = 100_000_000  # 10 Hz


def sim_frames(n: int = 12, size: int = 48):
    """(K, [(rgb, depth, pose)]) of a look-around in the box room, y-up world."""
    from activesplat.sim import SimConfig, Simulator, box_room

    sim = Simulator(box_room(), seed=0, config=SimConfig(width=size, height=size))
    obs = sim.reset()
    frames = [(obs.rgb, obs.depth, obs.pose)]
    actions = ["turn_left", "turn_left", "move_forward", "look_down", "turn_left", "look_up"]
    while len(frames) < n:
        obs = sim.step(actions[len(frames) % len(actions)])
        frames.append((obs.rgb, obs.depth, obs.pose))
    return sim.K, frames


def walk_frames(n: int = 8, size: int = 48, step: float = 0.07):
    """(K, [(rgb, depth, pose)]) of a walk along the box room's long axis, ``step`` metres a frame (0: a
    camera that turns on the spot), y-up world."""
    from activesplat.geometry import camera_pose
    from activesplat.sim import SimConfig, Simulator, box_room

    sim = Simulator(box_room(), seed=0, config=SimConfig(width=size, height=size))
    frames = []
    for k in range(n):
        pose = camera_pose([0.8 + step * k, 1.25, 1.4], np.pi / 2 + 0.05 * np.sin(k), -0.1)
        frames.append((*sim.render(pose), pose))
    return sim.K, frames


def to_zup(pose: np.ndarray) -> np.ndarray:
    """A y-up world pose as the pose in the z-up ROS world the recording stores."""
    return np.linalg.inv(WORLD_UP["z"]) @ pose


def _header(store, stamp: int, frame: str):
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    extra = {"seq": 0} if "seq" in Header.__dataclass_fields__ else {}
    return Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id=frame, **extra)


def image_msg(store, stamp, frame, array, encoding, ros1=False):
    Image = store.types["sensor_msgs/msg/Image"]
    h, w = array.shape[:2]
    data = np.ascontiguousarray(array).view(np.uint8).reshape(-1)
    return Image(
        header=_header(store, stamp, frame),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=0,
        step=data.size // h,
        data=data,
    )


def camera_info_msg(store, stamp, frame, K, w, h):
    """A CameraInfo of the camera of this project's `K`, in ROS's convention (as a driver writes it)."""
    K = K_to_opencv(K)
    Info = store.types["sensor_msgs/msg/CameraInfo"]
    Roi = store.types["sensor_msgs/msg/RegionOfInterest"]
    kwargs = dict(
        header=_header(store, stamp, frame),
        height=h,
        width=w,
        distortion_model="plumb_bob",
        binning_x=0,
        binning_y=0,
        roi=Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )
    fields = Info.__dataclass_fields__
    P = np.zeros(12)
    P[[0, 1, 2, 4, 5, 6, 10]] = [K[0, 0], 0, K[0, 2], K[1, 1], K[1, 2], 0, 1]
    if "k" in fields:
        kwargs.update(d=np.zeros(5), k=K.reshape(9).astype(np.float64), r=np.eye(3).reshape(9), p=P)
    else:
        kwargs.update(D=np.zeros(5), K=K.reshape(9).astype(np.float64), R=np.eye(3).reshape(9), P=P)
    return Info(**kwargs)


def pose_stamped_msg(store, stamp, frame, T):
    PS = store.types["geometry_msgs/msg/PoseStamped"]
    Pose = store.types["geometry_msgs/msg/Pose"]
    Point = store.types["geometry_msgs/msg/Point"]
    Quat = store.types["geometry_msgs/msg/Quaternion"]
    t, q = matrix_tq(T)
    return PS(
        header=_header(store, stamp, frame),
        pose=Pose(position=Point(x=t[0], y=t[1], z=t[2]), orientation=Quat(x=q[0], y=q[1], z=q[2], w=q[3])),
    )


BODY_T_CAMERA = np.array([[0.0, 0, 1, 0.2], [-1, 0, 0, 0.0], [0, -1, 0, 1.1], [0, 0, 0, 1]])
"""An optical frame looking along the base's x axis, 1.1 m up, 0.2 m forward (REP 103 base, z up)."""


def odometry_msg(store, stamp, T):
    Odom = store.types["nav_msgs/msg/Odometry"]
    PWC = store.types["geometry_msgs/msg/PoseWithCovariance"]
    TWC = store.types["geometry_msgs/msg/TwistWithCovariance"]
    Twist = store.types["geometry_msgs/msg/Twist"]
    V = store.types["geometry_msgs/msg/Vector3"]
    zero = V(x=0.0, y=0.0, z=0.0)
    pose = pose_stamped_msg(store, stamp, "map", T).pose
    return Odom(
        header=_header(store, stamp, "map"),
        child_frame_id="base_link",
        pose=PWC(pose=pose, covariance=np.zeros(36)),
        twist=TWC(twist=Twist(linear=zero, angular=zero), covariance=np.zeros(36)),
    )


def tf_msg(store, stamp, parent, child, T):
    TFM = store.types["tf2_msgs/msg/TFMessage"]
    TS = store.types["geometry_msgs/msg/TransformStamped"]
    Tr = store.types["geometry_msgs/msg/Transform"]
    V = store.types["geometry_msgs/msg/Vector3"]
    Quat = store.types["geometry_msgs/msg/Quaternion"]
    t, q = matrix_tq(T)
    ts = TS(
        header=_header(store, stamp, parent),
        child_frame_id=child,
        transform=Tr(translation=V(x=t[0], y=t[1], z=t[2]), rotation=Quat(x=q[0], y=q[1], z=q[2], w=q[3])),
    )
    return TFM(transforms=[ts])


def compressed_depth_msg(store, stamp, frame, depth, encoding):
    """image_transport's compressedDepth: ``compressedDepth16`` (16UC1, mm) or ``compressedDepth32``
    (32FC1, quantised inverse depth A / d + B with its default A = 100, depth_max = 10 m)."""
    if encoding == "compressedDepth16":
        fmt, a, b, img = "16UC1; compressedDepth png", 0.0, 0.0, np.round(depth * 1000).astype(np.uint16)
    else:
        a, fmt = 100.0, "32FC1; compressedDepth png"
        b = 1.0 - a / 10.0
        with np.errstate(divide="ignore"):
            img = np.where(depth > 0, np.round(a / depth + b), 0).astype(np.uint16)
    header = np.frombuffer(np.int32(0).tobytes() + np.array([a, b], "<f4").tobytes(), np.uint8)
    png = np.frombuffer(cv2.imencode(".png", img)[1].tobytes(), np.uint8)
    return store.types["sensor_msgs/msg/CompressedImage"](
        header=_header(store, stamp, frame), format=fmt, data=np.concatenate([header, png])
    )


def write_bag(
    path: Path,
    K,
    frames,
    fmt: str = "mcap",
    depth_encoding: str = "32FC1",
    rgb_encoding="rgb8",
    pose: str = "pose",
    stamps=None,
    drop_pose_after: int | None = None,
    skip_topic: str | None = None,
    rename: dict[str, str] | None = None,
):
    """Write frames (logged at 10 Hz, header stamps ``stamps``) as /camera/color/image_raw,
    /camera/depth/image_raw, /camera/color/camera_info and a pose source (/camera_pose PoseStamped, or
    /tf map -> camera_color_optical_frame). ``fmt``: ros1 (a .bag file), ros2 (a sqlite3 bag folder),
    mcap (a ROS 2 bag folder with MCAP storage). ``rename``: other names for some of those topics in the
    bag (e.g. a camera driver's own)."""
    from rosbags.typesys import Stores, get_typestore

    ros1 = fmt == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        from rosbags.rosbag1 import Writer

        writer = Writer(path)
        ser = store.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        writer = Writer(
            path, version=9, storage_plugin=StoragePlugin.MCAP if fmt == "mcap" else StoragePlugin.SQLITE3
        )
        ser = store.serialize_cdr
    frame = "camera_color_optical_frame"
    stamps = stamps if stamps is not None else [T0 + i * DT for i in range(len(frames))]
    h, w = frames[0][1].shape
    topics = {
        "/camera/color/image_raw": "sensor_msgs/msg/CompressedImage"
        if rgb_encoding == "png"
        else "sensor_msgs/msg/Image",
        "/camera/depth/image_raw": "sensor_msgs/msg/CompressedImage"
        if depth_encoding.startswith("compressedDepth")
        else "sensor_msgs/msg/Image",
        "/camera/color/camera_info": "sensor_msgs/msg/CameraInfo",
    }
    topics.update(
        {
            "pose": {"/camera_pose": "geometry_msgs/msg/PoseStamped"},
            "tf": {"/tf": "tf2_msgs/msg/TFMessage"},
            "odom": {"/odom": "nav_msgs/msg/Odometry", "/tf_static": "tf2_msgs/msg/TFMessage"},
        }[pose]
    )
    with writer:
        conns = {}
        for topic, typ in topics.items():
            if topic == skip_topic:
                continue
            conns[topic] = writer.add_connection((rename or {}).get(topic, topic), typ, typestore=store)

        def put(topic, stamp, msg):  # logged in order; the header stamps may go back
            if topic in conns:
                writer.write(conns[topic], T0 + i * DT, ser(msg, topics[topic]))

        for i, ((rgb, depth, T), stamp) in enumerate(zip(frames, stamps, strict=True)):
            if drop_pose_after is None or i < drop_pose_after:
                if pose == "pose":
                    put("/camera_pose", stamp, pose_stamped_msg(store, stamp, "map", to_zup(T)))
                elif pose == "odom":  # the base's pose; the camera sits at BODY_T_CAMERA on it
                    if i == 0:
                        put("/tf_static", stamp, tf_msg(store, stamp, "base_link", frame, BODY_T_CAMERA))
                    base = to_zup(T) @ np.linalg.inv(BODY_T_CAMERA)
                    put("/odom", stamp, odometry_msg(store, stamp, base))
                else:
                    put("/tf", stamp, tf_msg(store, stamp, "map", frame, to_zup(T)))
            put("/camera/color/camera_info", stamp, camera_info_msg(store, stamp, frame, K, w, h))
            color = rgb[..., ::-1] if rgb_encoding == "bgr8" else rgb
            if rgb_encoding == "png":  # sensor_msgs/CompressedImage, lossless
                png = np.frombuffer(cv2.imencode(".png", rgb[..., ::-1])[1].tobytes(), np.uint8)
                msg = store.types["sensor_msgs/msg/CompressedImage"](
                    header=_header(store, stamp, frame), format="rgb8; png compressed bgr8", data=png
                )
                put("/camera/color/image_raw", stamp, msg)
            else:
                put("/camera/color/image_raw", stamp, image_msg(store, stamp, frame, color, rgb_encoding))
            if depth_encoding.startswith("compressedDepth"):
                msg = compressed_depth_msg(store, stamp, frame, depth, depth_encoding)
                put("/camera/depth/image_raw", stamp, msg)
                continue
            d = (
                depth.astype(np.float32)
                if depth_encoding == "32FC1"
                else np.round(depth * 1000).astype(np.uint16)
            )
            put("/camera/depth/image_raw", stamp, image_msg(store, stamp, frame, d, depth_encoding))
    return path


ARGS = [
    "--rgb-topic",
    "/camera/color/image_raw",
    "--depth-topic",
    "/camera/depth/image_raw",
    "--camera-info-topic",
    "/camera/color/camera_info",
]


def ros_intrinsics(K) -> list[float]:
    """fx fy cx cy of the camera of this project's `K`, as ROS / OpenCV / TUM give them (`--intrinsics`)."""
    k = K_to_opencv(K)
    return [k[0, 0], k[1, 1], k[0, 2], k[1, 2]]


def write_tum(folder: Path, K, frames, depth_scale: float = 5000.0) -> Path:
    """A TUM RGB-D folder (rgb/, depth/, rgb.txt, depth.txt, groundtruth.txt) in the z-up world."""
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    rgb_lines, depth_lines, gt = ["# color images"], ["# depth images"], ["# timestamp tx ty tz qx qy qz qw"]
    for i, (rgb, depth, T) in enumerate(frames):
        s = (T0 + i * DT) / 1e9
        cv2.imwrite(str(folder / f"rgb/{s:.6f}.png"), rgb[..., ::-1])
        cv2.imwrite(str(folder / f"depth/{s:.6f}.png"), np.round(depth * depth_scale).astype(np.uint16))
        rgb_lines.append(f"{s:.6f} rgb/{s:.6f}.png")
        depth_lines.append(f"{s:.6f} depth/{s:.6f}.png")
        t, q = matrix_tq(to_zup(T))
        gt.append(f"{s:.6f} " + " ".join(f"{v:.12g}" for v in (*t, *q)))
    for name, lines in (("rgb.txt", rgb_lines), ("depth.txt", depth_lines), ("groundtruth.txt", gt)):
        (folder / name).write_text("\n".join(lines) + "\n")
    return folder
