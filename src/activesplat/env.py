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
environment's own sizes.

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
