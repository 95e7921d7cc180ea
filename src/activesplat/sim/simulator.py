"""The simulated agent: Habitat-style discrete actions, collision against the navigability map, and
posed RGB-D observations from the Embree sensor (docs/protocol.md §1).

Yaw and pitch follow `activesplat.geometry`: yaw 0 looks along +z, TURN_LEFT adds `turn_deg`
(counter-clockwise seen from +y); pitch > 0 looks up. Camera pose: 4x4 camera-to-world with OpenCV axes
(x right, y down, z forward), `geometry.camera_pose` of the camera `sensor_height` above the agent.
"""

from __future__ import annotations

import numbers
import os
from dataclasses import dataclass, replace

import numpy as np

from activesplat.env import ACTIONS, Observation
from activesplat.errors import InvalidActionError, InvalidInputError
from activesplat.geometry import camera_pose, intrinsics
from activesplat.sim.config import SimConfig
from activesplat.sim.scene import Scene


@dataclass(frozen=True)
class AgentState:
    """Agent on the floor: position (x, floor_y, z) of the cylinder axis, yaw and pitch in radians."""

    position: np.ndarray
    yaw: float
    pitch: float


def state_from_pose(pose: np.ndarray, floor_height: float) -> AgentState:
    """The agent state of a roll-free camera pose: floor position, yaw and pitch (`geometry.yaw_pitch_of`)."""
    pose = np.asarray(pose, dtype=np.float64)
    if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
        raise InvalidInputError(f"start pose must be a finite 4x4 matrix, got shape {pose.shape}")
    forward = pose[:3, 2]
    pitch = float(np.arcsin(np.clip(forward[1], -1.0, 1.0)))
    yaw = float(np.arctan2(forward[0], forward[2]))
    position = np.array([pose[0, 3], floor_height, pose[2, 3]])
    return AgentState(position, yaw, pitch)


class Simulator:
    """Habitat-protocol agent in a Scene, an `activesplat.env.Environment`. `reset()` returns to the start
    (seeded random navigable point of the largest free component with random yaw, unless `start` is given
    as a 4x4 camera pose); every `step(action)` costs one step, blocked moves and pitch-limit no-ops
    included."""

    def __init__(self, scene: Scene, seed: int = 0, start: np.ndarray | None = None,
                 config: SimConfig | None = None):
        if not hasattr(scene, "navmap_for"):
            hint = f": load_scene({str(scene)!r}) first" if isinstance(scene, (str, os.PathLike)) else ""
            raise InvalidInputError(f"Simulator takes a Scene, got {type(scene).__name__}{hint}")
        self.scene = scene
        if isinstance(seed, bool) or not isinstance(seed, numbers.Real) or int(seed) != seed or seed < 0:
            raise InvalidInputError(f"Simulator seed must be an integer >= 0, got {seed!r}")
        self.seed = int(seed)
        self.config = config = config or SimConfig()
        self.width, self.height = int(config.width), int(config.height)
        if self.width <= 0 or self.height <= 0 or not 0.0 < config.hfov_deg < 180.0:
            raise InvalidInputError(f"bad sensor size {self.width}x{self.height} or hfov {config.hfov_deg}")
        self.K = intrinsics(self.width, self.height, config.hfov_deg)
        self.navmap = scene.navmap_for(config)
        self.sensor = scene.sensor_for(config)
        self.start = self._start_state(start)
        self.state = self.start
        self.step_count = 0

    def _start_state(self, start) -> AgentState:
        floor = self.scene.floor_height
        if start is None:
            rng = np.random.default_rng(self.seed)
            x, z = self.navmap.sample_navigable(rng)
            # a uniform heading, drawn as (-sin u, 0, -cos u) for u uniform: every seed starts as it did
            # before the yaw convention was unified
            u = float(rng.uniform(-np.pi, np.pi))
            return AgentState(np.array([x, floor, z]), float(np.arctan2(-np.sin(u), -np.cos(u))), 0.0)
        state = state_from_pose(start, floor)
        if not self.navmap.is_navigable(state.position[0], state.position[2]):
            raise InvalidInputError(f"start position ({state.position[0]:.3f}, {state.position[2]:.3f}) "
                                    f"is not navigable in {self.scene.name}")
        return state

    def sensor_pose(self, state: AgentState) -> np.ndarray:
        """4x4 camera-to-world pose (OpenCV axes) of the sensor of an agent in `state`."""
        position = state.position + [0.0, self.config.sensor_height, 0.0]
        return camera_pose(position, state.yaw, state.pitch)

    @property
    def pose(self) -> np.ndarray:
        """Current 4x4 camera-to-world pose (OpenCV axes)."""
        return self.sensor_pose(self.state)

    @property
    def start_pose(self) -> np.ndarray:
        return self.sensor_pose(self.start)

    def render(self, pose: np.ndarray, width: int | None = None, height: int | None = None):
        """(rgb uint8, depth float32) seen from an arbitrary camera pose, same hfov as the agent."""
        width, height = width or self.width, height or self.height
        K = intrinsics(width, height, self.config.hfov_deg)
        return self.sensor.render(np.asarray(pose, dtype=np.float64), K, width, height)

    def depth(self, pose: np.ndarray, width: int, height: int) -> np.ndarray:
        """The depth of `render` alone (no colour): float32 (height, width) z-depth metres."""
        K = intrinsics(width, height, self.config.hfov_deg)
        return self.sensor.depth(np.asarray(pose, dtype=np.float64), K, width, height)

    def observe(self, collided: bool = False) -> Observation:
        pose = self.pose
        rgb, depth = self.render(pose)
        return Observation(rgb=rgb, depth=depth, pose=pose, step=self.step_count, collided=collided)

    def reset(self) -> Observation:
        self.state = self.start
        self.step_count = 0
        return self.observe()

    def step(self, action: str) -> Observation:
        """Apply one action (docs/protocol.md §1) and observe; unknown names raise InvalidActionError."""
        return self.observe(self.act(action))

    def act(self, action: str) -> bool:
        """Apply one action without rendering (replays, planning); returns whether a forward move was
        refused. Counts as a step exactly like `step`."""
        if action not in ACTIONS:
            raise InvalidActionError(f"unknown action {action!r}: expected one of {', '.join(ACTIONS)}")
        self.step_count += 1
        collided = False
        if action == "move_forward":
            collided = not self._move_forward()
        elif action in ("turn_left", "turn_right"):
            sign = 1.0 if action == "turn_left" else -1.0
            yaw = self.state.yaw + sign * np.deg2rad(self.config.turn_deg)
            self.state = replace(self.state, yaw=float(np.arctan2(np.sin(yaw), np.cos(yaw))))
        elif action in ("look_up", "look_down"):
            self._look(1.0 if action == "look_up" else -1.0)
        return collided

    def _move_forward(self) -> bool:
        """Move forward_step along the heading (on the floor, pitch ignored) if the whole segment is
        navigable; otherwise leave the pose unchanged (no sliding) and return False."""
        yaw = self.state.yaw
        delta = self.config.forward_step * np.array([np.sin(yaw), 0.0, np.cos(yaw)])
        target = self.state.position + delta
        if not self.navmap.segment_free(self.state.position[[0, 2]], target[[0, 2]]):
            return False
        self.state = replace(self.state, position=target)
        return True

    def _look(self, sign: float) -> None:
        """Pitch by look_deg within [pitch_min_deg, pitch_max_deg]; beyond the limit nothing moves."""
        pitch = np.rad2deg(self.state.pitch) + sign * self.config.look_deg
        if self.config.pitch_min_deg - 1e-6 <= pitch <= self.config.pitch_max_deg + 1e-6:
            self.state = replace(self.state, pitch=float(np.deg2rad(pitch)))
