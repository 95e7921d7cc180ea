"""From goals to discrete actions (paper sec. III-C; docs/protocol.md §5, "Path to actions").

Turn while the heading error to the next waypoint exceeds 10 deg, otherwise move forward; a waypoint is
reached within 1.5 forward steps. Rotation targets (yaw, pitch) become turns then tilts, pitch kept within
+-45 deg, and the camera is levelled again afterwards.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from activesplat.errors import InvalidInputError, check_fields
from activesplat.geometry import pose_yaw_pitch, wrap_angle


@dataclass(frozen=True)
class ControllerConfig:
    """Action geometry and the release's path-following thresholds. In a run the action sizes come from the
    simulator's (`activesplat.config.RunConfig`)."""

    turn_deg: float = 10.0
    """TURN_LEFT / TURN_RIGHT angle (Habitat protocol, docs/protocol.md §1)."""
    look_deg: float = 15.0
    """LOOK_UP / LOOK_DOWN angle (docs/protocol.md §1)."""
    forward_m: float = 0.065
    """MOVE_FORWARD distance (docs/protocol.md §1)."""
    heading_tolerance_deg: float = 10.0
    """Turn while the heading error exceeds this, else move forward (release)."""
    arrive_steps: float = 1.5
    """A waypoint is reached within this many forward steps (~0.1 m, release)."""
    max_pitch_deg: float = 45.0
    """The pitch the planner's on-the-spot rotations aim within, +-45 deg (paper / release); the simulator's
    own limit (--sim.pitch-min-deg / --sim.pitch-max-deg) still bounds what a tilt does."""

    def __post_init__(self) -> None:
        check_fields(self, positive=("turn_deg", "look_deg", "forward_m", "heading_tolerance_deg",
                                     "arrive_steps"))
        if not 0 <= self.max_pitch_deg <= 90:
            raise InvalidInputError(f"ControllerConfig.max_pitch_deg must be in [0, 90] degrees, got "
                                    f"{self.max_pitch_deg}")

    @property
    def arrive_radius(self) -> float:
        return self.arrive_steps * self.forward_m


def turn_toward(current_yaw: float, target_yaw: float, cfg: ControllerConfig) -> list[str]:
    """The shortest sequence of turns that brings the heading within half a turn of `target_yaw`."""
    err = math.degrees(float(wrap_angle(target_yaw - current_yaw)))
    n = int(round(abs(err) / cfg.turn_deg))
    return ["turn_left" if err > 0 else "turn_right"] * n


def tilt_toward(current_pitch: float, target_pitch: float, cfg: ControllerConfig) -> list[str]:
    """Tilts that bring the pitch to the multiple of `look_deg` nearest `target_pitch`, clamped to
    +-max_pitch_deg."""
    limit = cfg.max_pitch_deg
    target = float(np.clip(math.degrees(target_pitch), -limit, limit))
    n = int(round((target - math.degrees(current_pitch)) / cfg.look_deg))
    return ["look_up" if n > 0 else "look_down"] * abs(n)


def rotation_actions(pose: np.ndarray, target_yaw: float, target_pitch: float,
                     cfg: ControllerConfig) -> list[str]:
    """Turn to a rotation target, then tilt to its pitch."""
    yaw, pitch = pose_yaw_pitch(pose)
    return turn_toward(yaw, target_yaw, cfg) + tilt_toward(pitch, target_pitch, cfg)


def tour_actions(yaw: float, pitch: float, stops: Sequence[tuple[float, float]], cfg: ControllerConfig,
                 final_yaw: float | None = None) -> int:
    """How many actions visiting the (yaw, pitch) `stops` in the given order takes from heading `yaw` and
    pitch `pitch` (radians), with `rotation_actions` toward each in turn, the levelling tilts at the end and,
    given `final_yaw`, the turns back to it. Turns and tilts are quantised as the simulator does them
    (whole 10 / 15 deg steps)."""
    turn, look = math.radians(cfg.turn_deg), math.radians(cfg.look_deg)
    count = 0
    for target_yaw, target_pitch in stops:
        turns = turn_toward(yaw, target_yaw, cfg)
        tilts = tilt_toward(pitch, target_pitch, cfg)
        count += len(turns) + len(tilts)
        yaw += turn * len(turns) * (1 if turns and turns[0] == "turn_left" else -1)
        pitch += look * len(tilts) * (1 if tilts and tilts[0] == "look_up" else -1)
    count += len(tilt_toward(pitch, 0.0, cfg))
    return count if final_yaw is None else count + len(turn_toward(yaw, final_yaw, cfg))


def fewest_actions_order(yaw: float, pitch: float, stops: Sequence[tuple[float, float]],
                         cfg: ControllerConfig, final_yaw: float | None = None, max_exhaustive: int = 7
                         ) -> list[int]:
    """The order of the (yaw, pitch) `stops` that visits them all in the fewest actions (`tour_actions`,
    ending at `final_yaw` when given):
    every order is tried for up to `max_exhaustive` stops (5! = 120 for the release's 5 views); beyond,
    the input order is kept. Ties keep the earlier order in `itertools.permutations`, i.e. the input order
    first."""
    n = len(stops)
    if n <= 1 or n > max_exhaustive:
        return list(range(n))
    best, best_cost = list(range(n)), None
    for order in itertools.permutations(range(n)):
        cost = tour_actions(yaw, pitch, [stops[i] for i in order], cfg, final_yaw)
        if best_cost is None or cost < best_cost:
            best, best_cost = list(order), cost
    return best


def level_actions(pose: np.ndarray, cfg: ControllerConfig, pitch: float = 0.0) -> list[str]:
    """Tilts back to a level camera, or to `pitch` (radians) when given."""
    return tilt_toward(pose_yaw_pitch(pose)[1], pitch, cfg)


def floor_xz(pose: np.ndarray) -> np.ndarray:
    """The camera's position projected on the floor plane, as (x, z)."""
    return np.asarray(pose)[[0, 2], 3].astype(float)


def yaw_toward(here_xz: np.ndarray, target_xz: np.ndarray) -> float:
    """The yaw (radians, about +y) of the floor direction from `here_xz` to `target_xz`, both (x, z)."""
    delta = np.asarray(target_xz, float) - np.asarray(here_xz, float)
    return math.atan2(delta[0], delta[1])


def follow_action(pose: np.ndarray, waypoint_xz: np.ndarray, cfg: ControllerConfig) -> str | None:
    """One step of path following toward a waypoint: None once within the arrival radius."""
    pos = floor_xz(pose)
    if np.hypot(*(np.asarray(waypoint_xz, float) - pos)) <= cfg.arrive_radius:
        return None
    yaw, _ = pose_yaw_pitch(pose)
    err = math.degrees(float(wrap_angle(yaw_toward(pos, waypoint_xz) - yaw)))
    if abs(err) > cfg.heading_tolerance_deg:
        return "turn_left" if err > 0 else "turn_right"
    return "move_forward"


class PathFollower:
    """Follows world-space waypoints (M, 2) in (x, z) one action at a time."""

    def __init__(self, waypoints: np.ndarray, cfg: ControllerConfig | None = None):
        self.cfg = cfg or ControllerConfig()
        self.waypoints = [np.asarray(w, float) for w in np.asarray(waypoints, float).reshape(-1, 2)]
        self.passed: np.ndarray | None = None
        """The waypoint reached last (None before the first): the start of the segment being followed."""

    @property
    def done(self) -> bool:
        return not self.waypoints

    def next_action(self, pose: np.ndarray) -> str | None:
        """The next action, or None when the last waypoint is reached."""
        while self.waypoints:
            action = follow_action(pose, self.waypoints[0], self.cfg)
            if action is not None:
                return action
            self.passed = self.waypoints.pop(0)
        return None
