"""A live robot as an :class:`activesplat.env.Environment`, over rosbridge (no ROS install on our side).

On the robot runs ROS (1 or 2) with ``rosbridge_server`` (``rosbridge_websocket``, port 9090), the camera
driver, the SLAM / odometry that gives the camera pose, and a small action executor (docs/robots.md): it
executes each ``std_msgs/String`` on ``/activesplat/action`` (``move_forward`` 0.065 m, ``turn_left`` /
``turn_right`` 10 deg, ``look_up`` / ``look_down`` 15 deg, ``stop``; or the sizes the run is configured with)
and then publishes the action's name on ``/activesplat/action_done``.

This side speaks the rosbridge v2 JSON protocol over a websocket (``websockets``, already a dependency of
the viewer): it subscribes to the colour, depth, camera-info and pose topics and advertises the action topic.
``step(action)`` publishes the action, waits for ``action_done`` and returns the first colour + depth + pose
received after it. Images arrive as rosbridge sends them (``data`` base64), in the encodings that
``activesplat map`` reads; the pose topic is a ``geometry_msgs/PoseStamped`` or ``nav_msgs/Odometry`` of the
camera's optical frame in a z-up world (``world_up="z"``, turned to y-up as in ``activesplat map``). A
``move_forward`` that moved the camera less than half a step is reported as a collision.

:func:`serve_simulator` is the other end for tests and demos: a scripted fake robot, served by our
simulator, that speaks the same protocol on a local port.
"""

from __future__ import annotations

import base64
import json
import queue
import threading
import time
from types import SimpleNamespace

import numpy as np

from activesplat.env import ACTIONS, Observation
from activesplat.errors import InvalidInputError, interrupted
from activesplat.geometry import K_from_opencv, K_to_opencv
from activesplat.robot.bags import decode_color, decode_depth
from activesplat.robot.mapping import WORLD_UP
from activesplat.robot.transforms import matrix_tq, pose_matrix

ACTION_TOPIC = "/activesplat/action"
WAYPOINT_TOPIC = "/activesplat/waypoint"
DONE_TOPIC = "/activesplat/action_done"


def _image(msg: dict) -> SimpleNamespace:
    """A rosbridge JSON image as the attribute object the recording decoders take."""
    data = msg["data"]
    raw = base64.b64decode(data) if isinstance(data, str) else bytes(data)
    return SimpleNamespace(
        encoding=msg["encoding"],
        height=msg["height"],
        width=msg["width"],
        step=msg["step"],
        is_bigendian=msg.get("is_bigendian", 0),
        data=np.frombuffer(raw, np.uint8),
    )


def check_url(url: str) -> str:
    """`url` if it is a websocket address (ws://HOST[:PORT][/PATH] or wss://...); an InvalidInputError that
    says what is expected otherwise."""
    from urllib.parse import urlsplit

    try:
        parts = urlsplit(url)
        ok = parts.scheme in ("ws", "wss") and bool(parts.hostname) and (parts.port is None or parts.port > 0)
    except ValueError:  # a port that is not a number
        ok = False
    if not ok:
        raise InvalidInputError(f"rosbridge URL {url!r}: expected a websocket address ws://HOST:PORT (or "
                                f"wss://HOST:PORT), e.g. ws://robot.local:9090 (rosbridge_websocket's port)")
    return url


def _pose(msg: dict) -> np.ndarray:
    p = msg["pose"]["pose"] if "pose" in msg["pose"] else msg["pose"]
    t, q = p["position"], p["orientation"]
    return pose_matrix([t["x"], t["y"], t["z"]], [q["x"], q["y"], q["z"], q["w"]])


class RosbridgeEnvironment:
    """The robot behind a rosbridge websocket as an Environment (module docstring)."""

    def __init__(
        self,
        url: str,
        rgb_topic: str,
        depth_topic: str,
        camera_info_topic: str,
        pose_topic: str,
        pose_type: str = "geometry_msgs/PoseStamped",
        world_up: str = "z",
        forward_step: float = 0.065,
        timeout_s: float = 30.0,
    ):
        from websockets.exceptions import WebSocketException
        from websockets.sync.client import connect

        check_url(url)
        if world_up not in WORLD_UP:
            raise InvalidInputError(f"world_up must be one of {', '.join(WORLD_UP)}, got {world_up!r}")
        self.topics = {"rgb": rgb_topic, "depth": depth_topic, "info": camera_info_topic, "pose": pose_topic}
        self.W, self.forward_step, self.timeout_s = WORLD_UP[world_up], forward_step, timeout_s
        try:
            self.ws = connect(url, open_timeout=timeout_s, max_size=None)
        except (OSError, TimeoutError, WebSocketException) as exc:  # refused, no such host, not a websocket
            raise InvalidInputError(f"rosbridge {url}: cannot connect ({exc})") from None
        self.inbox: queue.Queue = queue.Queue()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        types = {
            "rgb": "sensor_msgs/Image",
            "depth": "sensor_msgs/Image",
            "info": "sensor_msgs/CameraInfo",
            "pose": pose_type,
        }
        for key, topic in self.topics.items():
            self._send({"op": "subscribe", "topic": topic, "type": types[key]})
        self._send({"op": "subscribe", "topic": DONE_TOPIC, "type": "std_msgs/String"})
        self._send({"op": "advertise", "topic": ACTION_TOPIC, "type": "std_msgs/String"})
        self._send({"op": "advertise", "topic": WAYPOINT_TOPIC, "type": "geometry_msgs/PointStamped"})
        self._waypoint = None
        self.steps = 0
        self._first = self._act("stop")  # a no-op that makes the robot report where it is
        self.K, self.width, self.height = self._K, self._width, self._height

    # ------------------------------------------------------------------ transport
    def _send(self, op: dict) -> None:
        self.ws.send(json.dumps(op))

    def _read(self) -> None:
        try:
            for text in self.ws:
                op = json.loads(text)
                if op.get("op") == "publish":
                    self.inbox.put((op["topic"], op["msg"]))
        except Exception:  # connection closed: step() times out with a clear message
            pass

    def close(self) -> None:
        self.ws.close()

    # ------------------------------------------------------------------ the environment
    def _act(self, action: str) -> Observation:
        while not self.inbox.empty():  # what came before the action is stale
            self.inbox.get_nowait()
        self._send({"op": "publish", "topic": ACTION_TOPIC, "msg": {"data": action}})
        deadline = time.monotonic() + self.timeout_s
        done, latest = False, {}
        while not (done and {"rgb", "depth", "pose"} <= latest.keys()):
            left = deadline - time.monotonic()
            try:
                topic, msg = self.inbox.get(timeout=max(left, 0.0))
            except queue.Empty:
                missing = (
                    "action_done"
                    if not done
                    else ", ".join(self.topics[k] for k in ("rgb", "depth", "pose") if k not in latest)
                )
                raise InvalidInputError(
                    f"robot: no {missing} within {self.timeout_s} s of action {action!r}"
                ) from None
            if topic == DONE_TOPIC:
                done = True
                continue
            for key, name in self.topics.items():
                if topic == name and (done or key == "info"):
                    latest[key] = msg
            if "info" in latest and not hasattr(self, "_K"):
                info = latest["info"]
                self._K = K_from_opencv(np.asarray(info.get("k", info.get("K")), dtype=np.float64))
                self._width, self._height = int(info["width"]), int(info["height"])
        rgb = decode_color(_image(latest["rgb"]), self.topics["rgb"], self.steps, compressed=False)
        depth = decode_depth(_image(latest["depth"]), self.topics["depth"], self.steps)
        pose = self.W @ _pose(latest["pose"])
        return Observation(rgb, depth, pose, self.steps)

    def reset(self) -> Observation:
        self.steps = 0
        obs, self._first = self._first or self._act("stop"), None
        self._pose = obs.pose
        return obs

    def waypoint(self, xz) -> None:
        """Publish the planner's next waypoint (map x, z; at the camera's height) on ``WAYPOINT_TOPIC`` as a
        ``geometry_msgs/PointStamped`` in the robot's world, when it changes."""
        if xz is None or (self._waypoint is not None and np.allclose(xz, self._waypoint)):
            return
        self._waypoint = np.asarray(xz, dtype=np.float64)
        p = np.linalg.inv(self.W) @ np.array([xz[0], self._pose[1, 3], xz[1], 1.0])
        msg = {"header": {"frame_id": "map"}, "point": dict(zip("xyz", p[:3].tolist(), strict=True))}
        self._send({"op": "publish", "topic": WAYPOINT_TOPIC, "msg": msg})

    def step(self, action: str) -> Observation:
        if action not in ACTIONS:
            raise InvalidInputError(f"unknown action {action!r}: expected one of {', '.join(ACTIONS)}")
        self.steps += 1
        obs = self._act(action)
        obs.step = self.steps
        if action == "move_forward":
            obs.collided = bool(np.linalg.norm(obs.pose[:3, 3] - self._pose[:3, 3]) < 0.5 * self.forward_step)
        self._pose = obs.pose
        return obs


# --------------------------------------------------------------------------- the fake robot
def _stamp(step: int) -> dict:
    ns = (1_000_000_000 + step) * 100_000_000
    return {"sec": ns // 10**9, "nanosec": ns % 10**9}


def _image_json(array: np.ndarray, encoding: str, step: int) -> dict:
    h, w = array.shape[:2]
    data = np.ascontiguousarray(array).tobytes()
    return {
        "header": {"stamp": _stamp(step), "frame_id": "camera_color_optical_frame"},
        "height": h,
        "width": w,
        "encoding": encoding,
        "is_bigendian": 0,
        "step": len(data) // h,
        "data": base64.b64encode(data).decode(),
    }


def serve_simulator(sim, host: str = "127.0.0.1", port: int = 0, topics: dict | None = None):
    """A scripted fake robot on ``ws://host:port`` speaking rosbridge v2, served by ``sim`` (a Simulator):
    it executes every action published on ``/activesplat/action`` in the simulator, publishes
    ``action_done``, then the camera info, the camera pose (PoseStamped, z-up world) and the RGB-D images on
    the topics its client subscribed to; it ignores waypoints (kept in ``server.received``). Returns
    ``(server, url)``; ``server.shutdown()`` stops it."""
    from websockets.sync.server import serve

    topics = topics or {
        "rgb": "/camera/color/image_raw",
        "depth": "/camera/depth/image_raw",
        "info": "/camera/color/camera_info",
        "pose": "/camera_pose",
    }

    received = []

    def handler(ws):
        for text in ws:
            op = json.loads(text)
            if op.get("op") == "publish":
                received.append(op)
            if op.get("op") != "publish" or op.get("topic") != ACTION_TOPIC:
                continue  # subscribe / advertise: everything is published anyway
            obs = sim.step(op["msg"]["data"])
            step = obs.step

            def publish(topic, msg):
                ws.send(json.dumps({"op": "publish", "topic": topic, "msg": msg}))

            publish(DONE_TOPIC, {"data": op["msg"]["data"]})
            K = K_to_opencv(sim.K)  # CameraInfo: ROS's convention, as a camera driver publishes it
            publish(
                topics["info"],
                {
                    "header": {"stamp": _stamp(step), "frame_id": "camera_color_optical_frame"},
                    "width": sim.width,
                    "height": sim.height,
                    "k": K.reshape(9).tolist(),
                },
            )
            t, q = matrix_tq(np.linalg.inv(WORLD_UP["z"]) @ obs.pose)
            publish(
                topics["pose"],
                {
                    "header": {"stamp": _stamp(step), "frame_id": "map"},
                    "pose": {
                        "position": dict(zip("xyz", t.tolist(), strict=True)),
                        "orientation": dict(zip("xyzw", q.tolist(), strict=True)),
                    },
                },
            )
            publish(topics["rgb"], _image_json(obs.rgb, "rgb8", step))
            publish(topics["depth"], _image_json(obs.depth.astype(np.float32), "32FC1", step))

    server = serve(handler, host, port, max_size=None)
    server.received = received  # every published message, for tests
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"ws://{host}:{server.socket.getsockname()[1]}"


def robot_from_args(args) -> int:
    """The ``robot`` command: explore a live robot behind rosbridge and write the episode folder."""
    from dataclasses import replace
    from pathlib import Path

    from activesplat.config import RunConfig
    from activesplat.episode import check_episode_folder
    from activesplat.explore import explore_environment

    if args.steps <= 0:
        raise InvalidInputError(f"--steps must be > 0, got {args.steps}")
    run = RunConfig()  # the robot's action sizes: what the planner assumes (checked before connecting)
    run = run.replace(steps=args.steps, policy=args.policy, seed=args.seed,
                      sim=replace(run.sim, forward_step=args.forward_step, turn_deg=args.turn_deg,
                                  look_deg=args.look_deg))
    check_url(args.url)
    out = Path(args.out)
    check_episode_folder(out, args.overwrite)  # before connecting (waits up to --timeout per observation)
    try:
        env = RosbridgeEnvironment(
            args.url,
            args.rgb_topic,
            args.depth_topic,
            args.camera_info_topic,
            args.pose_topic,
            pose_type=args.pose_type,
            world_up=args.world_up,
            forward_step=args.forward_step,
            timeout_s=args.timeout,
        )
    except KeyboardInterrupt:
        raise interrupted(f"interrupted while connecting to {args.url}: nothing written to {out}") from None
    try:
        m = explore_environment(
            env, run, out, overwrite=args.overwrite, progress=not args.no_progress, name="robot"
        )
    finally:
        env.close()
    print(
        f"explored {m['steps']} steps on {args.url}: path {m['path_length_m']:.2f} m, "
        f"{m['n_gaussians']} Gaussians, {m['ms_per_step']:.0f} ms/step -> {out}"
    )
    return 0
