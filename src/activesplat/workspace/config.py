"""Workspace and topology constants (paper sec. III-A "hybrid map updating", sec. III-C; docs/protocol.md
sections 1, 3 and 5). Every field names its source; "ours" marks a value the paper and release do not fix."""

from __future__ import annotations

from dataclasses import dataclass

from activesplat.errors import InvalidInputError


@dataclass(frozen=True)
class WorkspaceConfig:
    """Top-down rendering, workspace polish, Voronoi graph, subregions and safe paths."""

    # --- agent (docs/protocol.md §1, Habitat protocol) ---
    agent_radius: float = 0.1
    """Agent radius in metres (docs/protocol.md §1)."""
    agent_height: float = 1.5
    """Agent height in metres: top of the obstacle band (docs/protocol.md §1 and §3)."""

    # --- top-down render (docs/protocol.md §3) ---
    resolution: float = 0.05
    """Metres per top-down pixel. Ours: the release spans ~360 px over the map's longest side (its
    resolution changes as the map grows); a fixed metric resolution keeps every threshold in pixels
    stable over an episode. 0.05 m = half an agent radius."""
    floor_margin: float = 0.1
    """Foot margin in metres: Gaussians centred below floor + margin are ground, above are obstacles
    (docs/protocol.md §3: floor plus a foot margin; value ours)."""
    ground_depth: float = 0.3
    """Gaussians centred down to this far below the floor still count as ground (ours: absorbs
    floor noise; anything lower is ignored)."""
    camera_height: float = 1000.0
    """Top-down camera height above the floor in metres: orthographic in effect (docs/protocol.md §3)."""
    scale_modifier: float = 0.01
    """Gaussian scales are multiplied by this for the top-down render so each covers ~1 px
    (docs/protocol.md §3, release)."""
    obstacle_opacity: float = 0.4
    """A pixel is an obstacle where the obstacle-band opacity exceeds this (docs/protocol.md §3, release)."""
    ground_opacity: float = 0.4
    """A pixel is observed ground where the ground-band opacity exceeds this (ours, mirrors the
    release's obstacle threshold; release: 'not white' on a white background)."""
    ground_closing: float = 0.65
    """Side in metres of the square kernel of a morphological closing of the observed-ground mask (ours;
    0 = release rule). With the release's 0.01 scale modifier each floor Gaussian covers ~1 px, and the
    floor far from the agent, seen at a grazing angle, is sampled more sparsely than the grid: it renders
    as free/unknown stripes that the workspace opening then discards. A 13 px closing fills gaps up to
    0.6 m without growing the observed area outwards (a blur or a larger scale modifier would); obstacles
    are never closed over. Measured: on a 300-step medium-0 map the workspace is 11.6k px with the release
    rule, 15.8k with 0.15 m, 18.0k with 0.25 m; on a 2000-step medium-2 map a corridor seen only from 4-8 m
    down its length joins the workspace with 0.65 m (with 0.25 m it stopped 4 m short, so three rooms off
    it were never entered); over medium-0..3 x seeds 0, 1 (2000 steps, with `fewest_action_tour`) the
    completion rose from 80.1 to 81.8 % on average, medium-2 from 63.6 to 69.5 % (docs/benchmark.md)."""
    unknown_margin: float = 0.0
    """Metres by which the observed free region grows into unknown (never obstacle) pixels before the
    workspace polish (ours; 0 = the release: only observed floor is free). A door seen from the corridor at
    a grazing angle shows a strip of the room's floor beyond it, bounded by unobserved floor on one side
    and the door jamb on the other; that neck can be thinner than the agent although the door is 0.8 m
    wide, so the Voronoi graph has no edge through it and the room's nodes have no path (docs/benchmark.md
    "Goals with no path"). Measured at 0.1 (medium-0..3 x seeds 0, 1): 85.79 -> 86.13 %, all of it one run
    whose unentered room became reachable; the other seven lost 0.63 points, with twice the goals skipped
    for "no path" and nine "blocked" instead of one, because grown floor can be furniture or wall. Off
    (docs/benchmark.md, "A door seen at a slant")."""
    bounds_padding: float = 0.5
    """Metres added around the Gaussian means when growing the map bounds (ours)."""
    max_grid_pixels: int = 2048
    """Largest grid side in pixels; bounds beyond it are clipped around the agent (ours, guards
    against stray far-away Gaussians)."""

    # --- workspace polish (docs/protocol.md §3, release) ---
    open_kernel: int = 4
    """Morphological opening kernel (px, square), release 4x4."""
    dilate_kernel: int = 3
    """Dilation kernel after the opening (px, square), release 3x3."""
    polygon_epsilon: float = 0.225
    """cv2.approxPolyDP tolerance in metres (release 0.225 m)."""
    min_hole_area: float = 0.0
    """Inner contours (obstacles) with a smaller area in m^2 are dropped (ours, 0 keeps all)."""

    # --- Voronoi graph (docs/protocol.md §3, release) ---
    boundary_sample_spacing: float = 0.2
    """Spacing in metres of the points sampled along the contour edges (ours; release samples the
    edges of the simplified polygon)."""
    sites_from_mask: bool = True
    """Sample the Voronoi sites along the workspace mask's own contours (ours) instead of the 0.225 m
    simplified polygons (release): a simplified polygon cuts thin walls down to spikes, so the graph
    crosses a door on one long ridge with no vertex in it; the mask's contours give a door vertex."""
    site_epsilon_px: float = 1.0
    """approxPolyDP tolerance in pixels for the mask contours used as Voronoi sites (ours: removes the
    pixel staircase of diagonal walls, whose spurs would otherwise need pruning)."""
    min_site_hole_area: float = 0.04
    """Holes of the mask smaller than this (m^2; 0.2 m x 0.2 m, 2 agent radii square) give no Voronoi
    sites (ours: a one-pixel unobserved speck would put a loop in the graph; the mask and its clearance
    still keep them out of every path)."""
    prune_length: float = 0.25
    """Dangling leaf chains that reach less than this (metres) beyond the clearance disc of the junction
    they hang off are pruned, repeatedly (ours: the release prunes dangling chains; measuring the reach
    beyond the junction's disc drops corner spurs and keeps corridors and dead ends; a spur into a right
    angle corner reaches ~0.41 x the junction clearance - 0.04 m, so 0.25 m cleans the ends of corridors
    up to ~1.4 m wide and keeps the corner spurs of rooms, which lead to good view positions)."""
    merge_distance: float = 1e-3
    """Voronoi vertices closer than this (metres) are merged (ours: qhull duplicates on co-circular sites)."""

    # --- subregions (paper sec. III-C, docs/protocol.md §5) ---
    subregion_cut: float = 2.0
    """UPGMA dendrogram cut distance in metres (paper sec. III-C: 'fixed distance threshold of 2 m'). 4 m
    (room-sized subregions) was measured: tuning medium-0..3 +0.53 points, fresh medium-100..107 -3.33, the
    far end of a house never reached; 3 m: +0.29 and -0.05, level (docs/benchmark.md "Subregions cut at 4 m
    instead of 2 m")."""
    path_weight: float = 0.5
    """Weight of the graph shortest-path length in the UPGMA distance (docs/protocol.md §5)."""
    euclidean_weight: float = 0.5
    """Weight of the Euclidean distance in the UPGMA distance (docs/protocol.md §5)."""

    # --- safe paths (docs/protocol.md §5) ---
    path_clearance_radii: float = 2.0
    """Line-of-sight checks require this many agent radii of clearance (docs/protocol.md §5)."""
    entry_candidates: int = 32
    """Nearest graph vertices tried as path entry / exit points (ours)."""

    def __post_init__(self) -> None:
        positive = ("agent_radius", "agent_height", "resolution", "camera_height", "scale_modifier",
                    "polygon_epsilon", "boundary_sample_spacing", "subregion_cut", "merge_distance")
        for name in positive:
            if not getattr(self, name) > 0:
                raise InvalidInputError(f"WorkspaceConfig.{name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.floor_margin < self.agent_height:
            raise InvalidInputError(f"WorkspaceConfig.floor_margin must be in [0, agent_height), "
                                    f"got {self.floor_margin}")
        if self.site_epsilon_px < 0 or self.min_site_hole_area < 0:
            raise InvalidInputError("WorkspaceConfig.site_epsilon_px and min_site_hole_area must be >= 0")
        if self.unknown_margin < 0:
            raise InvalidInputError(f"WorkspaceConfig.unknown_margin must be >= 0, got {self.unknown_margin}")
        if self.ground_closing < 0:
            raise InvalidInputError(f"WorkspaceConfig.ground_closing must be >= 0, got {self.ground_closing}")
        for name in ("obstacle_opacity", "ground_opacity"):
            value = getattr(self, name)
            if not 0 < value < 1:
                raise InvalidInputError(f"WorkspaceConfig.{name} must be in (0, 1), got {value}")

    @property
    def ground_closing_px(self) -> int:
        """Closing kernel side in pixels (odd, so the closing does not shift the mask); 1 = no closing."""
        return 2 * int(round(0.5 * self.ground_closing / self.resolution)) + 1

    @property
    def path_clearance(self) -> float:
        """Clearance in metres required along safe-path segments (2 agent radii)."""
        return self.path_clearance_radii * self.agent_radius
