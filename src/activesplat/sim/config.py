"""Documented constants of the simulated robot (docs/protocol.md §1: the Habitat protocol)."""

from __future__ import annotations

from dataclasses import dataclass

from activesplat.errors import InvalidInputError, check_fields


@dataclass(frozen=True)
class SimConfig:
    """Sensor, agent and action settings. Defaults follow docs/protocol.md §1 (Habitat protocol)."""

    width: int = 256
    """Image width in pixels (docs/protocol.md §1: RGB-D 256x256; the paper's refinement uses 512x512)."""
    height: int = 256
    """Image height in pixels (docs/protocol.md §1)."""
    hfov_deg: float = 90.0
    """Horizontal field of view; square pixels, so vfov is 90 deg at 256x256 too (docs/protocol.md §1)."""
    sensor_height: float = 1.25
    """Camera height above the floor in metres (docs/protocol.md §1)."""
    max_depth: float = 10.0
    """Depth range in metres (paper: 10); farther hits and misses read 0 (docs/protocol.md §1)."""
    agent_radius: float = 0.1
    """Agent cylinder radius in metres (docs/protocol.md §1)."""
    agent_height: float = 1.5
    """Agent cylinder height in metres (docs/protocol.md §1)."""
    forward_step: float = 0.065
    """MOVE_FORWARD distance in metres (docs/protocol.md §1)."""
    turn_deg: float = 10.0
    """TURN_LEFT / TURN_RIGHT angle (docs/protocol.md §1)."""
    look_deg: float = 15.0
    """LOOK_UP / LOOK_DOWN angle (docs/protocol.md §1)."""
    pitch_min_deg: float = -45.0
    """Lowest pitch; a LOOK_DOWN beyond it is a no-op that still costs a step. docs/protocol.md §1 (bootstrap
    pitches between 0 and -45 deg) and docs/protocol.md §5 (on-the-spot rotations within +-45 deg)."""
    pitch_max_deg: float = 45.0
    """Highest pitch; a LOOK_UP beyond it is a no-op that still costs a step (+-45 deg,
    docs/protocol.md §5)."""
    step_margin: float = 0.1
    """Geometry lower than this above the floor does not block the agent (thresholds, rugs). Our
    choice; Habitat's navmesh climbs 0.2 m."""
    nav_cell: float = 0.025
    """Navigability grid cell in metres (ours). A cell is navigable when its clearance exceeds
    agent_radius + one cell diagonal, so the continuous camera position always keeps agent_radius."""
    floor_hole_cells: int = 2
    """Floor gaps up to this many nav cells wide (scanned meshes) are closed before the agent disc
    is required to stand on floor. Our choice."""
    ambient: float = 0.55
    """View-independent shading (ours): colour = albedo * (ambient + (1 - ambient) * |n . light|)."""
    light_dir: tuple[float, float, float] = (0.3, 0.8, 0.5)
    """Fixed world-space directional light (normalised in the sensor); no headlight, no specular, so
    colours do not depend on the viewpoint."""
    texture_filter: str = "area"
    """"area": a pixel's colour is its texture integrated over the pixel's footprint on the surface
    (anisotropic mip-mapping, as Habitat's OpenGL renderer and a real camera pixel do); "nearest": the one
    texel under the pixel centre (the project's renderer before; textures finer than a pixel alias).
    docs/protocol.md §1, "Texture filtering"."""
    texture_max_anisotropy: int = 16
    """Most texture taps along a footprint's long axis with the "area" filter (ours; 16 is a common GPU
    maximum). Beyond this ratio of its long to its short axis, the footprint is blurred along the short
    axis too."""

    def __post_init__(self) -> None:
        check_fields(self, positive=("width", "height", "hfov_deg", "sensor_height", "max_depth",
                                     "agent_radius", "agent_height", "forward_step", "turn_deg", "look_deg",
                                     "nav_cell", "texture_max_anisotropy"),
                     non_negative=("step_margin", "floor_hole_cells"), unit=("ambient",))
        if self.texture_filter not in ("area", "nearest"):
            raise InvalidInputError(f"SimConfig.texture_filter must be 'area' or 'nearest', got "
                                    f"{self.texture_filter!r}")
        if not self.hfov_deg < 180:
            raise InvalidInputError(f"SimConfig.hfov_deg must be < 180, got {self.hfov_deg}")
        if not -90 <= self.pitch_min_deg <= 0 <= self.pitch_max_deg <= 90:
            raise InvalidInputError(f"SimConfig.pitch_min_deg / pitch_max_deg must satisfy -90 <= min <= 0 "
                                    f"<= max <= 90, got {self.pitch_min_deg} / {self.pitch_max_deg}")

