"""Viewpoint-selection and planning constants (paper sec. III-B, III-C; docs/protocol.md §4 and §5).

Where the paper and the authors' release disagree, the field comment names both and says which one is the
default here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from activesplat.errors import InvalidInputError, check_fields
from activesplat.splat.lod import LOD_INFLATE


def _check_heading_angles(config, *names: str) -> None:
    """Angles off the camera's heading lie in [0, 180] degrees."""
    for name in names:
        if not 0 <= getattr(config, name) <= 180:
            raise InvalidInputError(f"{type(config).__name__}.{name} must be in [0, 180] degrees (an angle "
                                    f"off the heading), got {getattr(config, name)}")


@dataclass(frozen=True)
class PanoramaConfig:
    """Panorama at a Voronoi node (paper sec. III-D2 "Panorama Rendering")."""

    n_cameras: int = 3
    """Pinhole cameras rotated 0/120/240 deg in yaw (paper: three 120 deg cameras)."""
    hfov_deg: float = 120.0
    """Horizontal field of view of each camera (paper: 120 deg)."""
    vfov_deg: float = 150.0
    """Vertical field of view of each camera (paper: 150 deg)."""
    width_per_camera: int = 120
    """Pixels per camera horizontally: 3 x 120 = 360 px, ~1 px per degree (paper: 360 x 150 panorama)."""
    height: int = 150
    """Panorama height in pixels (paper: 150)."""
    front_faces_targets: bool = True
    """The panorama a stop picks its rotation targets from counts as visible only surfaces seen from the
    side that observed them (ours; paper and release: the opacity of every Gaussian). A flat Gaussian seen
    from behind, such as the corridor face of a room's door wall seen from inside the room, occludes but
    reads as unseen (`Mapper.render`'s ``front_alpha``). With the paper's opacity the far face of a wall
    or an object counts as its near face, so a room seen only through its door looks complete from
    inside, and the agent inside never turns to the wall it came through. Completion neutral (medium-0..3
    x 2 seeds 86.20 -> 85.87 %, fresh medium-100..109 seed 0 85.87 -> 86.13 %), worst room of the fresh
    houses 84.0 -> 87.1 % of its ceiling (docs/benchmark.md "Front faces"). The panoramas that score
    candidate nodes keep the plain opacity: with front faces there too, every interior node promised the
    back faces around it (medium-0..3 x 2 seeds 85.87 -> 84.26 %)."""
    back_face_margin_deg: float = 15.0
    """With ``front_faces_targets``, a Gaussian is seen from behind only when the camera lies this far behind
    its plane (ours): walls and floors seen edge-on would otherwise flicker between seen and unseen."""
    score_lod_voxel_m: float | None = 0.05
    """The panoramas that score candidate nodes are rendered from a coarser copy of the map, its Gaussians
    merged per voxel of this size (ours; `splat.lod.voxel_lod`; None = the map itself, as the paper). A
    replan renders ~30 such panoramas of the whole map, and a final medium map's copy has ~3.4 times fewer
    Gaussians: position selection takes half the time (medium houses 111 -> 55 ms per step). Completion
    -0.07 points over eleven medium runs (standard error 0.08), -0.05 over four small ones; the on-arrival
    panorama keeps the full map (docs/exploration.md "Coarser panoramas")."""
    score_lod_inflate: float = LOD_INFLATE
    """With ``score_lod_voxel_m``, each merged Gaussian's covariance is scaled by this squared (ours): the
    Gaussian fit of a voxel's patch of surface leaves gaps between voxels that would read as unseen."""

    def __post_init__(self) -> None:
        check_fields(self, positive=("hfov_deg", "vfov_deg", "score_lod_voxel_m", "score_lod_inflate"),
                     at_least_one=("n_cameras", "width_per_camera", "height"),
                     optional=("score_lod_voxel_m",))
        if not 0 <= self.back_face_margin_deg < 90:
            raise InvalidInputError(f"PanoramaConfig.back_face_margin_deg must be in [0, 90) degrees (the "
                                    f"camera's angle behind a Gaussian's plane), got "
                                    f"{self.back_face_margin_deg}")
        if not (self.hfov_deg < 180 and self.vfov_deg < 180):
            raise InvalidInputError(f"PanoramaConfig fields of view must be < 180 deg, got {self.hfov_deg} / "
                                    f"{self.vfov_deg}")


@dataclass(frozen=True)
class RotationCandidateConfig:
    """Rotation candidates from DBSCAN over low-visibility pixels (sec. III-B2; release values)."""

    invisibility_threshold: float = 0.3
    """A pixel is low-visibility when 1 - opacity exceeds this (release: 0.3)."""
    downsample: int = 2
    """Cluster at half resolution (release)."""
    dbscan_eps: float = 5.0
    """DBSCAN neighbourhood radius in (downsampled) pixels (release: 5)."""
    dbscan_min_samples: int = 10
    """DBSCAN core-point size (release: 10)."""
    min_cluster_invisibility: float = 25.0
    """A cluster is kept when the sum of its invisibility exceeds this (release: 25)."""
    min_offset_deg: float = 15.0
    """A target is used only if more than this off the current heading (release: 15 deg)."""
    min_relative_weight: float = 0.0
    """A stop turns to a target only when its weight is at least this share of the heaviest target of the
    same source there (ours; 0: off, as paper and release). A look-around costs ~40 actions, most of the
    rotations. Share 0.05 on medium-0..3 x 2 seeds: rotations 48.8 -> 47.0 %, completion 85.87 -> 85.25 %
    (docs/benchmark.md "Light rotation targets skipped"): the small clusters are worth their turns."""

    def __post_init__(self) -> None:
        check_fields(self, unit=("invisibility_threshold", "min_relative_weight"), positive=("dbscan_eps",),
                     non_negative=("min_cluster_invisibility",),
                     at_least_one=("downsample", "dbscan_min_samples"))
        _check_heading_angles(self, "min_offset_deg")


@dataclass(frozen=True)
class HullConfig:
    """3D convex-hull volume of invisible regions (sec. III-B2, "back-projects contour pixels")."""

    invisibility_threshold: float = 0.8
    """Pixels counted as invisible for the hull (release: 0.8)."""
    downsample: int = 2
    """Cluster at half resolution, like the rotation candidates (release)."""
    dbscan_eps: float = 5.0
    """DBSCAN radius in pixels (release: 5)."""
    dbscan_min_samples: int = 25
    """DBSCAN core-point size (release: 25)."""
    dilate_px: int = 15
    """Elliptic dilation of each cluster before taking its outer contour (release: 15 x 15)."""

    def __post_init__(self) -> None:
        check_fields(self, unit=("invisibility_threshold",), positive=("dbscan_eps",),
                     non_negative=("dilate_px",), at_least_one=("downsample", "dbscan_min_samples"))


@dataclass(frozen=True)
class HighLossConfig:
    """High-loss samples of eq. 10, tracked over time (sec. III-B2). The eq. 10 thresholds themselves
    (tau_o2 = 0.8, epsilon_1 = 0.3 m) live in the mapper's config, which computes the mask."""

    grid: int = 90
    """The mask is downsampled to grid x grid before clustering (release: 90 x 90)."""
    min_pixels: int = 20
    """Fewer high-loss pixels than this: no sample (release: 20)."""
    dbscan_eps: float = 5.0
    """DBSCAN neighbourhood radius in grid pixels (release: 5)."""
    dbscan_min_samples: int = 10
    """DBSCAN core-point size (release: 10)."""
    min_cluster_sum: float = 25.0
    """Clusters smaller than this are ignored (release: 25)."""
    min_offset_deg: float = 5.0
    """A sample becomes a rotation target only if more than this off the heading (release: 5 deg)."""
    drop_within_deg: float = 5.0
    """A tracked sample is dropped once the camera heading is within this of it (release: 5 deg)."""
    max_samples: int = 32
    """Most samples kept; the oldest are forgotten first (ours)."""
    max_targets: int = 2
    """Most high-loss rotation targets offered per stop, the heaviest first; 0 = every tracked sample
    within reach, as in the release (ours: the samples of one cluster of frames lie a few degrees apart,
    and a stop spent its 5 views on them instead of on the panorama's unseen directions; medium-0..3 x
    2 seeds, 84.66 -> 85.37 % completion, 71.1 -> 75.8 % of the ceiling at step 1000, docs/benchmark.md
    "Tuning log")."""

    def __post_init__(self) -> None:
        check_fields(self, positive=("dbscan_eps",), non_negative=("min_pixels", "min_cluster_sum",
                                                                   "max_targets"),
                     at_least_one=("grid", "dbscan_min_samples", "max_samples"))
        _check_heading_angles(self, "min_offset_deg", "drop_within_deg")


@dataclass(frozen=True)
class ScoreConfig:
    """Node score of eq. 12: S = w_o s_o + w_c s_c + w_u s_u + w_h s_h (- failed penalty).

    Defaults follow the paper's weights (20/10/10/10); s_o and s_c are each node's invisible share and hull
    volume divided by the maximum over the candidate nodes. The release instead scores
    20*unvisited + 10*in_horizon + 2*ceil(10*inv/max) + 1*ceil(10*vol/max) - 60*failed:
    set `preset="release"`.
    """

    w_o: float = 20.0
    """Weight of the 2D invisible share of the node's panorama (paper eq. 12)."""
    w_c: float = 10.0
    """Weight of the 3D convex-hull share (paper eq. 12)."""
    w_u: float = 10.0
    """Weight of the unvisited flag (paper eq. 12)."""
    w_h: float = 10.0
    """Weight of the in-horizon flag (paper eq. 12)."""
    failed_penalty: float = 60.0
    """Subtracted from nodes whose goal failed before (release: 60)."""
    unvisited_radius_m: float = 0.65
    """A node is unvisited when farther than this from every past position (release: 10 x 0.065 m)."""
    preset: Literal["paper", "release"] = "paper"
    """"paper" (continuous shares, weights above) or "release" (the release's quantised formula)."""

    def __post_init__(self) -> None:
        check_fields(self, non_negative=("w_o", "w_c", "w_u", "w_h", "failed_penalty", "unvisited_radius_m"))
        if self.preset not in ("paper", "release"):
            raise InvalidInputError(f"ScoreConfig.preset must be 'paper' or 'release', got {self.preset!r}")


@dataclass(frozen=True)
class PlanningConfig:
    """Everything the viewpoint selection needs, grouped."""

    panorama: PanoramaConfig = field(default_factory=PanoramaConfig)
    rotation: RotationCandidateConfig = field(default_factory=RotationCandidateConfig)
    hull: HullConfig = field(default_factory=HullConfig)
    high_loss: HighLossConfig = field(default_factory=HighLossConfig)
    score: ScoreConfig = field(default_factory=ScoreConfig)
