"""The explorer's own configuration (`ExplorerConfig`): the knobs of `planning.explorer.Explorer` and its
policies that are not the paper's planning constants (those are in `planning.config`), with the planning,
workspace and controller configs nested in it. Every field says where its value comes from. `GoalRules`
is the part of it that goal selection (`planning.goals`) reads."""

from __future__ import annotations

from dataclasses import dataclass, field

from activesplat.errors import InvalidInputError, check_fields
from activesplat.planning.config import PlanningConfig
from activesplat.planning.controller import ControllerConfig
from activesplat.workspace.config import WorkspaceConfig


@dataclass(frozen=True)
class ExplorerConfig:
    """The explorer's own knobs; the planning / workspace / controller configs hold the paper's numbers."""

    bootstrap_yaw_deg: float = 360.0
    """The look-around before departure turns left this far, one TURN_LEFT at a time (paper / release: a
    full circle, 36 turns of 10 deg)."""
    bootstrap_pitch_deg: float = 45.0
    """After each bootstrap turn one tilt, cycling down to -this and back up to level (release: 0 -> -45 deg
    in 15 deg tilts, down, down, down, up, up, up; 0 = no tilts)."""
    idle_yaw_deg: float = 60.0
    """With no goal to go to, the agent turns left this far on the spot before it replans (ours)."""
    max_rotation_views: int = 5
    """On-the-spot rotation targets at most per arrival (release: 5; MP3D 4)."""
    multi_stop_views: int = 5
    """Rotation targets at most at a multi-connected node stop on the way (ours; the release uses
    `max_rotation_views` there too)."""
    rotation_skip_radii: float = 3.0
    """No on-the-spot rotations within this many agent radii of a spot already rotated at (release)."""
    multi_stop_spacing_m: float = 2.5
    """No rotation stop at a multi-connected node within this of a spot already rotated at (the start's
    look-around included); 0 = the arrival rule above, as in the release (ours: in furnished rooms the
    Voronoi graph branches around every piece of furniture, so junctions lie ~1 m apart and the agent
    stopped at each; 1.5 m: medium-0..3 x 2 seeds, 59.7 -> 71.1 % of the ceiling at step 1000, rotations
    57.0 -> 46.8 %, final completion 83.92 -> 84.66 %, docs/benchmark.md "Tuning log"; 2.5 m since
    2026-11-29: tuning medium-0..3 seed 0 +0.51 points, fresh medium houses +0.6, docs/benchmark.md
    "Multi-connected stops 2.5 m apart")."""
    fewest_action_tour: bool = True
    """Visit the rotation targets of a stop in the order that takes the fewest turns and tilts, levelling
    included (ours: every order of the at most 5 targets is tried; False: counter-clockwise from the
    heading, the order this project used before, which often swept a full circle for targets on both
    sides of the heading)."""
    travel_pitch_deg: float = 0.0
    """Camera pitch while following a path, and the pitch the camera returns to after a stop's rotation
    targets (ours; 0 = level, as the paper and the release travel; negative = down, whole `look_deg` steps).
    A level camera at 1.25 m sees no floor within 1.25 m of the agent, and the floor and low furniture
    beside its path go unobserved although it passed within a metre or two of them. -15 on medium-0..3 x 2
    seeds: 86.49 -> 86.18 %, the floor's miss rate unchanged, so off (docs/benchmark.md "Where the
    completion came from")."""
    multi_node_radius_m: float = 0.3
    """Passing within this of a multi-connected node forces a short rotation stop there (ours)."""
    local_score_threshold: float = 5.0
    """Local planning keeps picking nodes of the current subregion while their information score
    w_o s_o + w_c s_c (eq. 12 without the unvisited / in-horizon flags) exceeds this (ours: 5 = a quarter of
    the best invisible share anywhere; with the flags counted an agent revisits a seen room node by node)."""
    local_near_m: float | None = 2.0
    """An open node this near the agent (graph travel) counts for the local stage whatever its subregion
    (ours; None: the agent's subregion only, as in the paper). A long corridor is one subregion, so an
    agent at a room's door went on down the corridor to a node of its own subregion that promised less
    than the room beside it (medium-2 seed 0: a node 1.2 m away behind the door, information 18.4, against
    one 3.1 m along the corridor, 11.5), and the room was never entered. With `retry_unreachable`:
    medium-0..3 x 2 seeds 86.20 -> 86.60 %, fresh medium-100..109 seed 0 85.69 -> 86.37 % (nine houses of
    ten up), docs/benchmark.md "A room beside the agent's subregion"."""
    global_distance_weight: float = 1.0
    """Global goal score = node score - this x path length in metres (ours; the paper names a distance
    cost without a value). 2 lost 2.4 points alone and was a tie with the two rules below (docs/benchmark.md
    "Tuning log")."""
    neck_margin_m: float | None = 0.2
    """When a ranked goal has no safe path on this replan's graph, look for one before skipping it: on the
    same map with the free floor grown this much into unknown pixels (`WorkspaceConfig.unknown_margin`,
    `workspace.plan.grown_plan`, built once per replan), and follow that path, checked ahead on the grown
    workspace (ours; None = off, the release). A room seen through its door at a slant leaves a neck of
    observed floor thinner than the agent: the door's far jamb hides a wedge of the floor inside, and a
    camera at 1.25 m looking level does not see the floor near its feet, so walking past the door does not
    close it. No graph edge crosses the neck and the room's nodes are skipped for "no path" (held-out
    medium-136: a room left at 13 % of its points for the last 1240 steps; 79.58 -> 85.40 % with 0.2).
    Growing every replan's floor the same way rescued a run and lost elsewhere (docs/benchmark.md "A door
    seen at a slant"); this grows only where no path was found, and a run in which every ranked goal has a
    path is the same as without it. Alone, 0.2 against None, seed 0, one thread
    per run: medium-0..3 x 2 seeds -0.12 points, fresh medium-100..109 +0.12, held-out medium-130..139
    +0.72 (two higher, one lower, seven never acting), fresh medium-140..149 -0.01 (acting in three of ten);
    no run lower by more than 0.6 points. The default since 2026-11-28 (docs/benchmark.md "A room lost
    behind its door")."""
    retry_unreachable: bool = True
    """A goal with no safe path on this replan's graph is skipped for this replan only instead of marked
    failed (ours; False = marked failed, i.e. closed until no goal is left, as in the release). A goal cut
    off for one replan (the floor of a doorway or a corridor not yet mapped) otherwise stays closed for the
    rest of the episode, and a whole room can be lost with it: three runs so far (medium-1 seed 0 with
    `--mapper.edge-band-px 2`, medium-105 with `--mapper.lr.scales 0.01`, medium-0 seed 1 with
    `local_near_m`). Neutral where no such goal decides the route (docs/benchmark.md "Failed goals that
    stay closed"). Goals refused on the way (a blocked path, a refused forward move) are still marked
    failed."""
    leave_when_cut_off: bool = True
    """When no goal worth a visit (information above `local_score_threshold`) has a path from here and the
    only goals with one promise nothing, the agent leaves the spot as when no goal has a path at all (its
    own steps back, `way_back_m`, else the escape) instead of walking to one of them (ours; False = it walks
    to the best of them, as before 2026-11-29). Standing on a scrap of the graph cut off from the rest, the
    agent otherwise shuttles between two nodes a few decimetres apart for the rest of the episode: fresh
    medium-102 seed 0 did so for its last 325 steps, 384 goals skipped for want of a path
    (docs/benchmark.md "Cut off on a scrap of the graph"). Acts in no replan where a goal worth a visit has
    a path."""
    global_in_horizon: bool = False
    """Count eq. 12's in-horizon flag in the global stage too (paper: one score for every node; this
    project's default until the change below). False (ours): the global stage ranks nodes without it. The
    flag marks a node in a straight line of sight, which is a local preference: down a corridor it gave a
    node 11 m away the same 10 points as one in the next room, and the agent crossed the house past rooms
    it had not entered."""
    local_in_horizon: bool = True
    """Count eq. 12's in-horizon flag in the local stage (paper). False (ours): the local stage ranks the
    nodes of the agent's subregion without it, by what they promise to see (with `global_in_horizon`
    False, the flag then counts nowhere; the flat `no-hp` ranking keeps it). Beside a door the flag's 10
    points let a corridor node in sight that promised little beat the door node that looked into a room:
    medium-162 seed 0 at step 185 took a node of information 6.6 over one of 13.5, and the room behind the
    door ended at 4 % of its points. Tuning medium-0..3 +0.67 points, held-out medium-130..139 and
    fresh medium-160..163 -0.66, so off (docs/benchmark.md "The in-horizon flag in the local stage")."""
    global_information_first: bool = True
    """In the global stage, rank the open nodes whose information score (as for `local_score_threshold`)
    exceeds the local threshold ahead of every other node, each group by score minus distance cost (ours;
    the paper ranks all nodes by one score). Without it the unvisited and in-horizon flags (20 of eq. 12's
    points) of a nearby node in a room already seen can outweigh a far node with unseen space behind a door
    once the distance cost is counted, and the agent goes from node to node of rooms it has seen. With
    this and no in-horizon flag on medium-0..3 x seeds 0, 1: completion 84.02 -> 85.36 %, share of the sweep
    ceiling 92.7 -> 94.2 %, at step 1000 74.4 -> 69.5 %; fresh medium-100..109: 85.33 -> 85.56 %
    (docs/benchmark.md "Tuning log")."""
    long_path_m: float = 13.0
    """Release: a goal path longer than 13 m (200 steps) is kept only if no closer node lies on the way."""
    on_the_way_m: float = 0.5
    """A node lies on the way of a long path when it is within this of the path (ours)."""
    detour_m: float | None = 5.0
    """In the global stage, go first to the nearest open node whose information exceeds `detour_min_info`, if
    it is nearer than the chosen goal and costs at most this many metres of extra travel on the way to it
    (graph lengths, `on_the_way.worth_a_detour`), instead of straight to the goal (ours; None = off, the
    paper's rule). The door of an unseen room shows little of the room in a panorama, so a node with a large
    unseen area behind it elsewhere outranks it and the agent walked past the door and never came back (fresh
    medium-104 and medium-109, seed 0). Measured with 5 m (docs/benchmark.md "Rooms passed on the way"):
    tuning houses 85.94 -> 86.21 % (with the mapper's colour detail, 86.49 %), fresh medium-100..109 seed 0
    84.76 -> 86.31 % (with the colour detail 85.03 %), held-out medium-110..119 seed 0 85.39 -> 86.45 % (with
    the colour detail); rotations rise from 44-46 % to 49-50 %."""
    detour_min_info: float = 10.0
    """The information a node must promise to be worth a detour (ours: a third of the best node's 30; a
    node just above `local_score_threshold` is a corner of a room already seen)."""
    max_panoramas: int = 24
    """Candidate nodes scored by panorama per replan, nearest first, on top of one per subregion (see
    `panorama_every_subregion`; ours: bounds the replan time)."""
    panorama_every_subregion: bool = True
    """Score the nearest open node of every subregion by panorama, however many subregions there are, plus
    the `max_panoramas` nearest open nodes (ours). False: `max_panoramas` in all, subregions nearest first,
    this project's rule before. Unscored nodes have no information part, so on a medium house (47
    subregions on medium-105 at step 1692) the 24 panoramas all went to the agent's half of the house, the
    rooms at the far end looked empty of anything to see, and they were never entered."""
    escape_forward_steps: int = 3
    """Forward steps of a collision escape after turning to the clearest heading (ours); the headings probed
    are every turn of a full circle."""
    way_back_m: float | None = 3.0
    """With no goal that has a safe path, and the agent standing where the workspace is thinner than the
    path clearance (or gone), first walk its own steps back, at most this far, to the latest spot it
    stood on with the path clearance (`planning.explorer.retrace_actions`), then replan (ours; None = off:
    escape toward the clearest heading and turn on the spot). An agent that walks into a dead-end slot to
    look into it can find the slot's sides mapped thicker once it has looked: no graph vertex is then in
    line of sight, every goal has "no path", and the escape's headings all tie at zero clearance
    (small-101 seed 0: about 85 steps on one spot, in a slot that leaves the agent's centre 5 cm, so only
    the heading it came in on gets it out; 89.00 -> 89.57 % with the rule, which acted in no other run of
    33; docs/benchmark.md "A dead-end slot")."""
    start_blocks: int | None = 3
    """After this many paths in a row that the path-ahead check (`lookahead_m`) refuses before their first
    forward move, from one spot, the agent leaves the spot: its own steps back (`way_back_m`), else the
    escape toward the clearest heading, then it replans (ours; None = off: every ranked goal, failed ones
    too, is tried again from the same spot). Without it an agent that stood where the check refuses every
    first step turned toward one goal after another for the rest of the episode: a goal refused ahead is
    marked failed, but failed goals still come last in the ranking, and a replan that finds any goal with
    a path never reaches the escape (fresh medium-145 seed 0 with `multi_stop_spacing_m` 2.5: 533 steps
    with no forward move; docs/benchmark.md "Paths refused at their first step")."""
    lookahead_m: float = 0.65
    """Re-check this much of the path ahead at every step (release: 10 forward steps)."""
    ahead_tolerance_m: float = 0.05
    """The path-ahead check forgives this much clearance (ours: one workspace cell). The agent follows its
    path only to within the arrival radius, so the segment it checks starts up to ~0.1 m off the planned
    one, and clearance is quantised to cells: without it an agent beside a wall corner fails every goal at
    its first forward step and turns on the spot for hundreds of steps."""
    replan_log_top: int = 8
    """Each replan record of stops.json lists this many candidates as ranked (position, subregion, score,
    information, travel), best first: why the agent went where it went (ours; 0 = none)."""
    panorama_height_m: float = 1.25
    """Panoramas are rendered at the sensor height above the floor (docs/protocol.md §1)."""
    hierarchical: bool = True
    """Local-then-global goal selection over subregions (paper sec. III-C); off for `no-hp`."""
    rotations: bool = True
    """On-the-spot rotations toward panorama / high-loss targets on arrival (paper sec. III-B); off for
    `position`."""
    multi_stops: bool = True
    """Rotation stops at multi-connected nodes (paper sec. III-C); off for `position` and `viewpoint`."""
    random_goals: bool = False
    """Choose goal nodes uniformly at random (the `random` ablation of the paper's Tab. III)."""
    seed: int = 0
    """Seed of the random choices (random goals; ours)."""
    planning: PlanningConfig = field(default_factory=PlanningConfig)
    workspace: WorkspaceConfig = field(default_factory=WorkspaceConfig)
    controller: ControllerConfig = field(default_factory=ControllerConfig)

    def __post_init__(self) -> None:
        check_fields(self, non_negative=("bootstrap_yaw_deg", "idle_yaw_deg",
                                         "max_rotation_views", "multi_stop_views", "rotation_skip_radii",
                                         "multi_stop_spacing_m",
                                         "multi_node_radius_m", "local_score_threshold",
                                         "global_distance_weight", "long_path_m", "on_the_way_m",
                                         "escape_forward_steps", "lookahead_m", "ahead_tolerance_m",
                                         "detour_min_info", "replan_log_top", "panorama_height_m"),
                     positive=("local_near_m", "neck_margin_m", "way_back_m"),
                     at_least_one=("max_panoramas", "start_blocks"),
                     optional=("local_near_m", "neck_margin_m", "way_back_m", "start_blocks"))
        if not 0 <= self.bootstrap_pitch_deg <= 90:
            raise InvalidInputError(f"ExplorerConfig.bootstrap_pitch_deg must be in [0, 90] degrees (the "
                                    f"look-around tilts down to -this and back to level), got "
                                    f"{self.bootstrap_pitch_deg}")
        if not -90 < self.travel_pitch_deg < 90:
            raise InvalidInputError(f"ExplorerConfig.travel_pitch_deg must be in (-90, 90) degrees, got "
                                    f"{self.travel_pitch_deg}")


@dataclass(frozen=True)
class GoalRules:
    """The explorer's goal-selection knobs (see `ExplorerConfig` for their meaning and origin)."""

    local_score_threshold: float
    global_distance_weight: float
    max_panoramas: int
    panorama_height_m: float
    hierarchical: bool
    random_goals: bool
    long_path_m: float
    on_the_way_m: float
    global_in_horizon: bool = False
    local_in_horizon: bool = True
    global_information_first: bool = True
    panorama_every_subregion: bool = True
    local_near_m: float | None = None
