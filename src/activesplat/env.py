"""The environment interface the exploration loop runs against (README, "Your own environment").

An environment is anything with a pinhole RGB-D camera on a mobile base that takes the planner's discrete
actions. :class:`activesplat.sim.Simulator` is one; a robot bridge or a user's own simulator is another.
The loop (:func:`activesplat.explore.explore_environment`) needs only this:

- ``K`` (3x3 intrinsics), ``width``, ``height``: the camera, fixed for the whole run; pixel (u, v)'s centre
  lies at (u + 0.5, v + 0.5) as in the simulator (a ROS / OpenCV K: ``geometry.K_from_opencv``);
- ``reset() -> Observation``: the first observation (the loop maps it before choosing an action);
- ``step(action) -> Observation``: apply one of :data:`ACTIONS` and observe. An action costs one step
  whatever happens; a ``move_forward`` that did not move sets ``collided`` (the planner then marks its goal
  failed and escapes).

An observation has ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 z-depth in metres (0 = no reading),
``pose`` the 4x4 camera-to-world matrix (OpenCV optical axes: x right, y down, z forward; world y up,
metres), ``step`` (actions so far) and ``collided``. The action sizes the planner assumes come from the run
configuration's ``sim`` group (``--sim.turn-deg``, ``--sim.forward-step``, ``--sim.look-deg``,
``--sim.sensor-height``, ...): an environment should honour them, or the run should be configured with the
environment's own sizes. The loop checks the poses against them (`ActionSizeCheck`): in an environment
other than the run's own simulator it warns when an action kind's median move is off by more than 25 %, and
metrics.json records the measured sizes (``measured_action_sizes``) and the path length from the poses
(``path_length_poses_m``: the camera's horizontal path over the forward moves).

Optionally, an environment may have ``waypoint(xz)``: the loop calls it before every ``step`` with the
world (x, z) point the planner's path follower heads for (None while it follows no path: look-around,
rotations), for a base with its own controller.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

ACTIONS = ("move_forward", "turn_left", "turn_right", "look_up", "look_down", "stop")
"""The discrete actions (docs/protocol.md §1)."""


@dataclass
class Observation:
    """One posed RGB-D frame (see the module docstring for units and axes)."""

    rgb: np.ndarray
    depth: np.ndarray
    pose: np.ndarray
    step: int
    collided: bool = False


@runtime_checkable
class Environment(Protocol):
    """What the exploration loop drives: a camera (``K``, ``width``, ``height``), ``reset`` and ``step``."""

    K: np.ndarray
    width: int
    height: int

    def reset(self) -> Observation: ...

    def step(self, action: str) -> Observation: ...


def check_observation(obs, width: int, height: int, where: str = "environment") -> None:
    """Raise InvalidInputError (naming ``where``) when an observation does not follow the interface."""
    from activesplat.errors import InvalidInputError

    for name in ("rgb", "depth", "pose"):
        if not hasattr(obs, name):
            raise InvalidInputError(f"{where}: observation has no {name!r}")
    rgb, depth, pose = np.asarray(obs.rgb), np.asarray(obs.depth), np.asarray(obs.pose)
    if rgb.shape != (height, width, 3) or depth.shape != (height, width):
        raise InvalidInputError(f"{where}: observation of rgb {rgb.shape} / depth {depth.shape}, expected "
                                f"{(height, width, 3)} / {(height, width)} (its width and height)")
    if pose.shape != (4, 4) or not np.isfinite(pose).all():
        raise InvalidInputError(f"{where}: observation pose must be a finite 4x4 matrix, got {pose.shape}")


# --------------------------------------------------------------------------- action sizes
ACTION_SIZE_TOLERANCE = 0.25
"""How far (a fraction of the configured size) the median measured size of an action kind may be from the
configured one before `ActionSizeCheck` warns."""
ACTION_SIZE_MIN_MOVES = 5
"""Moves of a kind measured before `ActionSizeCheck` judges that kind."""
ACTION_STILL_FRACTION = 0.1
"""A move of less than this fraction of its configured size did not happen (blocked by an obstacle, a tilt
at the pitch limit, a base without a tilt unit): left out of the measurement."""

ACTION_KINDS = {
    # kind: (the actions, the SimConfig field, its option, unit)
    "forward_step": (("move_forward",), "forward_step", "--sim.forward-step", "m"),
    "turn_deg": (("turn_left", "turn_right"), "turn_deg", "--sim.turn-deg", "deg"),
    "look_deg": (("look_up", "look_down"), "look_deg", "--sim.look-deg", "deg"),
}
"""The action kinds whose size the planner assumes (the run configuration's ``sim`` group)."""


class ActionSizeCheck:
    """Whether an environment moves the camera by the action sizes the planner assumes (``sim.forward_step``,
    ``sim.turn_deg``, ``sim.look_deg``): every action's pose before and after it are compared (`observe`).
    A forward move is the camera's horizontal (x, z) translation, a turn or tilt the angle of its rotation.
    Forward moves the environment reports as collisions, and moves of less than a tenth of their size (a
    blocked move, a tilt at the pitch limit or of a base without one), are left out; the median of the
    others, from `ACTION_SIZE_MIN_MOVES` moves of a kind on, more than `ACTION_SIZE_TOLERANCE` off the
    configured size is warned about once per kind (the measured and configured sizes, the option to set).
    Forward moves reported as collisions that still moved the camera are counted apart: when they are most
    of the forward moves (`ACTION_SIZE_MIN_MOVES` of them or more), the robot's steps may be shorter than
    the configured one (a bridge reports a move of under half a step as a collision), and that is warned
    about once too. `path_length_m` sums the camera's horizontal path over the forward moves (each
    ``move_forward``'s translation, collisions included), what the run's ``path_length_m`` counts with the
    configured step: a camera mounted off the robot's turning axis also moves sideways in a turn on the
    spot, which is no path walked."""

    def __init__(self, sim_config):
        self.configured = {kind: float(getattr(sim_config, field))
                           for kind, (_, field, _, _) in ACTION_KINDS.items()}
        self.sizes: dict[str, list[float]] = {kind: [] for kind in ACTION_KINDS}
        self.ignored = dict.fromkeys(ACTION_KINDS, 0)
        self.collided_moving: list[float] = []
        """The distances of forward moves reported as collisions that still moved the camera."""
        self.warned: set[str] = set()
        self.path_length_m = 0.0

    def observe(self, action: str, before, after, collided: bool = False) -> None:
        """Action `action` took the camera from pose `before` to pose `after` (4x4 camera-to-world)."""
        before, after = np.asarray(before, dtype=np.float64), np.asarray(after, dtype=np.float64)
        moved = float(np.hypot(*(after[[0, 2], 3] - before[[0, 2], 3])))
        kind = next((k for k, (actions, *_) in ACTION_KINDS.items() if action in actions), None)
        if kind is None:
            return
        if kind == "forward_step":
            self.path_length_m += moved
            size = moved
        else:
            cos = (np.trace(before[:3, :3].T @ after[:3, :3]) - 1.0) / 2.0
            size = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
        still = size < ACTION_STILL_FRACTION * self.configured[kind]
        if (collided and kind == "forward_step") or still:
            self.ignored[kind] += 1
            if collided and kind == "forward_step" and not still:
                self.collided_moving.append(size)
                self._judge_collisions()
            return
        self.sizes[kind].append(size)
        self._judge(kind)

    def median(self, kind: str) -> float | None:
        """The median measured size of `kind` (metres or degrees), None before any move of it."""
        return float(np.median(self.sizes[kind])) if self.sizes[kind] else None

    def _judge(self, kind: str) -> None:
        import warnings

        if kind in self.warned or len(self.sizes[kind]) < ACTION_SIZE_MIN_MOVES:
            return
        measured, configured = self.median(kind), self.configured[kind]
        if abs(measured - configured) <= ACTION_SIZE_TOLERANCE * configured:
            return
        self.warned.add(kind)
        actions, field, option, unit = ACTION_KINDS[kind]
        fmt = ".3f" if unit == "m" else ".1f"
        warnings.warn(
            f"the environment's {' / '.join(actions)} moved the camera by {measured:{fmt}} {unit} (median of "
            f"{len(self.sizes[kind])}), not the configured {configured:g} {unit} the planner assumes (and "
            f"path_length_m counts): configure the run with the environment's own, {option} {measured:.3g} "
            f"(SimConfig.{field})",
            stacklevel=4)

    def _judge_collisions(self) -> None:
        import warnings

        n, forward = len(self.collided_moving), len(self.sizes["forward_step"]) + self.ignored["forward_step"]
        if "collisions" in self.warned or n < ACTION_SIZE_MIN_MOVES or 2 * n <= forward:
            return
        self.warned.add("collisions")
        warnings.warn(
            f"{n} of the environment's {forward} move_forward actions were reported as collisions though the "
            f"camera moved (median {float(np.median(self.collided_moving)):.3f} m): its steps may be shorter "
            f"than the configured {self.configured['forward_step']:g} m the planner assumes; if so, "
            f"configure the run with the environment's own, --sim.forward-step (SimConfig.forward_step)",
            stacklevel=4)

    def metrics(self) -> dict:
        """metrics.json's ``measured_action_sizes``: per kind, the median measured size (None without a
        move), the configured one, the moves measured and those left out."""
        return {kind: {"measured": self.median(kind), "configured": self.configured[kind],
                       "moves": len(self.sizes[kind]), "ignored": self.ignored[kind]}
                for kind in ACTION_KINDS}
