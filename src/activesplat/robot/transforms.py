"""Rigid transforms of recorded data: 4x4 matrices from translations and quaternions, time-stamped pose
tracks interpolated at a stamp (linear position, slerp rotation), and the /tf tree of a bag (static
links and dynamic tracks, chained from a world frame to a camera frame). Used by
`robot.recording` (bags and TUM folders) and `robot.bridge` (live ROS)."""

from __future__ import annotations

import numpy as np

from activesplat.errors import RecordingError


def stamp_ns(msg) -> int:
    """The header stamp of a ROS 1 or ROS 2 message in nanoseconds."""
    st = msg.header.stamp
    sec = getattr(st, "sec", None)
    if sec is None:
        sec = st.secs
    nsec = getattr(st, "nanosec", None)
    if nsec is None:
        nsec = st.nsecs
    return int(sec) * 1_000_000_000 + int(nsec)


def xyz(v) -> np.ndarray:
    """(3,) from a message's x, y, z fields."""
    return np.array([v.x, v.y, v.z], dtype=np.float64)


def xyzw(q) -> np.ndarray:
    """(4,) quaternion x y z w from a message's fields."""
    return np.array([q.x, q.y, q.z, q.w], dtype=np.float64)


def pose_matrix(t, q) -> np.ndarray:
    """4x4 from a translation (x, y, z) and a unit quaternion (x, y, z, w)."""
    from scipy.spatial.transform import Rotation

    q = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(q)
    if not np.isfinite(n) or n < 1e-9:
        raise ValueError(f"not a rotation quaternion: {q.tolist()}")
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(q / n).as_matrix()
    T[:3, 3] = t
    return T


def matrix_tq(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(translation, quaternion x y z w) of a 4x4 rigid transform."""
    from scipy.spatial.transform import Rotation

    return np.asarray(T[:3, 3], dtype=np.float64), Rotation.from_matrix(T[:3, :3]).as_quat()


class PoseTrack:
    """Time-stamped rigid transforms (ns, 4x4), interpolated: linear position, slerp rotation."""

    def __init__(self, stamps: list[int], poses: list[np.ndarray], name: str):
        self.name = name
        self.stamps = np.asarray(stamps, dtype=np.int64)
        self.poses = np.stack(poses) if poses else np.zeros((0, 4, 4))

    def at(self, stamp: int, max_gap_ns: int) -> np.ndarray | None:
        """The transform at ``stamp``, None when no sample lies within ``max_gap_ns`` on both sides (before
        the first or after the last sample: that sample if within a tenth of ``max_gap_ns``)."""
        from scipy.spatial.transform import Rotation, Slerp

        s = self.stamps
        if len(s) == 0:
            return None
        i = int(np.searchsorted(s, stamp))
        if i < len(s) and s[i] == stamp:
            return self.poses[i]
        if i == 0 or i == len(s):
            j = 0 if i == 0 else len(s) - 1
            return self.poses[j] if abs(int(s[j]) - stamp) <= max_gap_ns // 10 else None
        a, b = i - 1, i
        if stamp - s[a] > max_gap_ns or s[b] - stamp > max_gap_ns:
            return None
        w = (stamp - s[a]) / float(s[b] - s[a])
        T = np.eye(4)
        T[:3, 3] = (1 - w) * self.poses[a][:3, 3] + w * self.poses[b][:3, 3]
        rots = Rotation.from_matrix(np.stack([self.poses[a][:3, :3], self.poses[b][:3, :3]]))
        T[:3, :3] = Slerp([0.0, 1.0], rots)([w]).as_matrix()[0]
        return T

    def why_none(self, stamp: int, max_gap_ns: int) -> str:
        """Why :meth:`at` gives no transform at ``stamp``, in words for a message."""
        s = self.stamps
        if len(s) == 0:
            return f"{self.name} has no sample"
        i = int(np.searchsorted(s, stamp))
        if i == 0 or i == len(s):
            end, j = ("before the first", 0) if i == 0 else ("after the last", len(s) - 1)
            return (f"it is {abs(int(s[j]) - stamp) / 1e9:.3f} s {end} pose of {self.name} "
                    f"(t={s[j] / 1e9:.6f} s), and poses are extrapolated over at most a tenth of "
                    f"--max-pose-gap, {max_gap_ns / 1e10:.3f} s")
        gap = (int(s[i]) - int(s[i - 1])) / 1e9
        return (f"it falls in a gap of {gap:.3f} s between poses of {self.name} "
                f"(t={s[i - 1] / 1e9:.6f} s and {s[i] / 1e9:.6f} s), and poses are interpolated only within "
                f"--max-pose-gap, {max_gap_ns / 1e9:.3f} s, of a sample on either side")


class TfTree:
    """/tf and /tf_static: per child frame its parent and (static) transform or (dynamic) pose track."""

    def __init__(self):
        self.parent: dict[str, str] = {}
        self.static: dict[str, np.ndarray] = {}
        self.dynamic: dict[str, tuple[list[int], list[np.ndarray]]] = {}
        self._tracks: dict[str, PoseTrack] = {}

    def add(self, tr, static: bool, topic: str, index: int) -> None:
        parent, child = tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/")
        T = pose_matrix(xyz(tr.transform.translation), xyzw(tr.transform.rotation))
        self.parent[child] = parent
        if static:
            self.static[child] = T
            return
        stamps, poses = self.dynamic.setdefault(child, ([], []))
        stamp = stamp_ns(tr)
        if stamps and stamp < stamps[-1]:
            raise RecordingError(
                f"{topic}: message {index}: transform {parent} -> {child} at {stamp / 1e9:.6f} s "
                f"goes back in time (non-monotonic)"
            )
        stamps.append(stamp)
        poses.append(T)

    def frames(self) -> set[str]:
        return set(self.parent) | set(self.parent.values())

    def _chain(self, frame: str) -> list[str]:
        chain = [frame]
        while chain[-1] in self.parent and len(chain) < 100:
            chain.append(self.parent[chain[-1]])
        return chain

    def connected(self, world: str, frame: str) -> bool:
        return world.lstrip("/") in self._chain(frame.lstrip("/"))

    def lookup(self, world: str, frame: str, stamp: int, max_gap_ns: int, static_only: bool = False):
        """world_T_frame at ``stamp`` by walking up from ``frame``; None when a dynamic link has no sample
        within the gap (or is dynamic and ``static_only``)."""
        world, T, f = world.lstrip("/"), np.eye(4), frame.lstrip("/")
        while f != world:
            if f not in self.parent:
                return None
            if f in self.static:
                link = self.static[f]
            elif static_only:
                return None
            else:
                if f not in self._tracks:
                    self._tracks[f] = PoseTrack(*self.dynamic[f], name=f"{self.parent[f]} -> {f}")
                link = self._tracks[f]
                link = link.at(stamp, max_gap_ns)
                if link is None:
                    return None
            T = link @ T
            f = self.parent[f]
        return T

    def why_none(self, world: str, frame: str, stamp: int, max_gap_ns: int) -> str:
        """Why :meth:`lookup` gives no transform: the first dynamic link of the chain without a sample."""
        f = frame.lstrip("/")
        while f != world.lstrip("/") and f in self.parent:
            if f not in self.static and self.lookup(self.parent[f], f, stamp, max_gap_ns) is None:
                return self._tracks[f].why_none(stamp, max_gap_ns)
            f = self.parent[f]
        return f"no chain of transforms from {world!r} to {frame!r}"

    def static_chain(self, body: str, camera: str) -> np.ndarray | None:
        """body_T_camera from /tf_static alone, None when there is no such chain."""
        body, camera = body.lstrip("/"), camera.lstrip("/")
        if not camera or body == camera or not self.connected(body, camera):
            return None
        return self.lookup(body, camera, 0, 0, static_only=True)


__all__ = ["PoseTrack", "TfTree", "matrix_tq", "pose_matrix", "stamp_ns", "xyz", "xyzw"]
