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
    tilt_within_deg: float | None = None
    """Tilt toward a rotation target only until it lies within this many degrees of the image centre,
    vertically (ours; None: tilt to the target's pitch, as the paper and the release do). With the 90 deg
    vertical field of view, 30 leaves 15 deg between the target and the image border, and a target less
    than 30 deg off level needs no tilt at all. 30 on medium-0..3 x 2 seeds: 86.49 -> 85.88 % completion,
    rotations 49.3 -> 47.8 %, so off (docs/benchmark.md "Where the completion came from")."""
    travel_pitch_deg: float = 0.0
    """Camera pitch while following a path, and the pitch the camera returns to after a stop's rotation
    targets (ours; 0 = level, as the paper and the release travel; negative = down, whole `look_deg` steps).
    A level camera at 1.25 m sees no floor within 1.25 m of the agent, and the floor and low furniture
    beside its path go unobserved although it passed within a metre or two of them. -15 on medium-0..3 x 2
    seeds: 86.49 -> 86.18 %, the floor's miss rate unchanged, so off (docs/benchmark.md "Where the
    completion came from")."""
    unsampled_views: int = 0
    """Rotation targets at most per stop toward mapped surface within `unsampled_radius_m` that none of the
    agent's depth points has sampled (a `unsampled_voxel_m` voxel; `planning.observed.unsampled_views`),
    ranked with the panorama and high-loss targets by weight (ours; 0 = off, as the paper). The completion
    measure counts a surface point only where a depth point fell within 5 cm of it; the floor and low
    furniture beside the agent's route are mapped from afar and look seen to eq. 12, but most of what the
    exhaustive sweep observes and a run does not lies there. 2 on medium-0..3 x 2 seeds (6 runs): 86.46 ->
    84.76 %, so off (docs/benchmark.md "Where the completion came from")."""
    unsampled_radius_m: float = 2.5
    """Surface within this of the agent counts for `unsampled_views` (ours)."""
    unsampled_voxel_m: float = 0.1
    """Voxel size of the sampled-surface memory of `unsampled_views` (ours: twice the completion measure's
    5 cm, so that the map's depth error of a few cm does not flag surface the agent has sampled)."""
    unsampled_min_weight: float = 25.0
    """A view toward unsampled surface must cover at least this much of it, in half-resolution panorama
    pixels (ours: the rotation candidates' minimum cluster mass)."""
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
    global_halving_m: float | None = None
    """When set, the global stage ranks by node score / (1 + path length / this) instead of the difference
    above (ours): a score halves at this much travel, so a long trip must promise proportionally more
    whatever the scale of the scores. 5 m on medium-0..3 x 2 seeds: 86.02 -> 86.20 % (noise), so off
    (docs/benchmark.md "Score per way, and a bridge")."""
    bridge_gain_m: float | None = None
    """When a goal worth a visit (information above `local_score_threshold`) has no safe path, go instead to
    the open node of the agent's own graph component nearest to it, if that is at least this much nearer
    to it than the agent (ours; None = off: the goal is marked failed and the next one is tried, as in the
    release). The graph is cut where the floor was only seen from far away (a corridor looked down but not
    walked): the most promising nodes then lie in another component, every path to them fails, they are
    marked failed and the agent turns to what it can reach. Fresh medium-100 seed 1: 76.22 -> 81.97 %;
    medium-0..3 x 2 seeds 86.02 -> 86.00 %, fresh medium-100..109 seed 0 86.03 -> 85.43 %, so off
    (docs/benchmark.md "Score per way, and a bridge")."""
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
    behind its door"); with `neck_travel` see there."""
    neck_travel: bool = False
    """Rank the nodes this replan's graph gives no path to by their travel on the floor grown
    `neck_margin_m` into unknown (`planning.travel.graph_travel` on `workspace.plan.grown_plan`, built at
    the replan's ranking then), instead of three times their straight distance (ours; needs
    `neck_margin_m`). A room behind a neck of observed floor thinner than the agent otherwise ranks as if
    it were three times as far as it is: in medium-0 seed 1 the defaults leave room 4 (9.6 % of the house)
    at step 781 and never come back (79.67 %; with this and `neck_margin_m` 0.2: 86.82 %, room 4 at 73.9
    %). Both together, against both off: medium-0..3 x 2 seeds 85.79 -> 86.41 %, fresh medium-100..109
    seed 0 86.40 -> 86.73 %, held-out medium-110..112 seed 0 87.32 -> 82.09 %: medium-112 84.69 -> 69.01 %,
    a far node made near by the grown floor drew the agent across the house from two rooms it then left at
    0 and 21 %. Off (docs/benchmark.md "Nodes with no path ranked by their travel on grown floor")."""
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
    cut_off_look_m: float | None = None
    """Passing within this of a goal that a replan skipped for want of a path (information above
    `local_score_threshold`), turn toward it with the camera one tilt down, then replan (ours; None = off).
    Most such goals are rooms seen through a door only along the corridor, at a grazing angle: the strip
    of their floor in the map is thinner than the agent, so the graph has no edge through the door, and a
    look through it from in front closes the gap. One look per goal (and per goal within this of it).
    1.5 m on the ten tuning and fresh seed-0 runs whose defaults skipped a goal for want of a path: +0.15
    points (standard error 0.24, five higher, four lower), over all eighteen runs +0.08; within noise, off
    (docs/benchmark.md "A look through the door of a goal with no path")."""
    global_tour: bool = False
    """In the global stage, go first to the subregion that comes first on the shortest open route from the
    agent through every subregion with a node worth a visit (information above `local_score_threshold`;
    each subregion's best such node stands for it, graph path lengths; `hierarchical.tour_first`), instead
    of to the best score minus distance (ours; the paper names a distance cost, not a route). medium-0..3 x 2
    seeds: 86.02 -> 85.75 %, at step 1000 71.0 -> 65.3 % of the ceiling, so off (docs/benchmark.md "A route
    through the subregions"). With the later defaults: tuning 85.87 -> 86.42 %, fresh medium-100..109 seed
    0 86.13 -> 83.42 % (medium-103 58 %: the route is re-planned at every replan and its first stop keeps
    changing sides of the house; docs/benchmark.md "The route through the subregions, again")."""
    route_memory_m: float | None = None
    """Follow the route of `global_tour` with its order kept across replans (ours,
    `replan_memory.RouteMemory`; None = off): the stops of the last route still there (a subregion's
    representative within this many metres of a remembered stop) keep their order, new subregions are
    inserted where they lengthen the route least, and a fresh shortest route is planned only when none of
    the old stops is left. Without it the route is re-planned at every replan, and its first stop kept
    changing sides of the house. 2 m on medium-0..3 x 2 seeds: 86.60 -> 84.16 % (medium-2 seed 1 70.09 %:
    the route took every subregion still worth a visit in turn, 17-18 m trips for information 7); with
    `route_min_info` 20: 86.48 %, at step 1000 62.43 -> 63.47 %, rotations 50.2 -> 48.8 %, fresh
    medium-100..109 seed 0 86.37 -> 86.53 % (seven runs unchanged); so off
    (docs/benchmark.md "A route that keeps its order"). Held-out medium-150..159 x 2 seeds with
    `route_min_info` 20: 94.02 -> 94.82 % of the sweep ceiling, the two runs that never reached one end of
    the house rescued (72.3 -> 90.6, 81.9 -> 94.2) and two new ones (medium-153 s0 91.4 -> 86.0, medium-154
    s0 96.4 -> 91.2) (docs/benchmark.md "A route that keeps its order, on the houses whose far end was left
    for last")."""
    route_min_info: float = 0.0
    """With `route_memory_m`: only subregions whose best node promises more than this information part are
    stops of the route (ours; 0 = every subregion worth a visit)."""
    route_in_place: bool = False
    """With `global_tour` or `route_memory_m`: the route only reorders the stops among themselves, each taking
    the place of a stop in the global stage's own ranking, instead of putting every stop ahead of the rest
    (ours; `hierarchical.tour_first`). A near subregion that promises too little to be a stop
    (`route_min_info`) and that the ranking puts first stays first, rather than waiting behind stops across
    the house. With `route_memory_m` 2 and `route_min_info` 20 on held-out medium-150..159 x 2 seeds: 94.02 ->
    95.09 % of the sweep ceiling (standard error 1.14; both collapses rescued, medium-153 s0 91.4 -> 86.0, the
    other sixteen runs -0.23), shaped on these runs; fresh medium-100..109 seed 1: 95.13 -> 95.20 % (eight of
    ten runs the same); so off (docs/benchmark.md "A route that keeps its order, on the houses whose far end
    was left for last")."""
    last_call_steps: int | None = None
    """A node's last call: once the steps left after walking to an open node that promises at least
    `last_call_min_info` (its travel times `last_call_steps_per_m`) fall to this many, it goes first, over
    the local stage too, while at least 60 would be left to look around there (ours; None = off). The
    route leaves the far end of the house for last, and whether the steps still reach it depends on how
    long the stops before it take (held-out medium-153 and -154 seed 1, fresh medium-105 seed 0 with the
    arrival rule of `collision_arrive_m`: the east end 16 m away promised 24 at step 1387 while the
    local stage took nodes promising 5-8; it was chosen at step 1948, too late to reach)."""
    last_call_min_info: float = 20.0
    """The information part (of 30) a node must promise for its last call (`last_call_steps`; ours)."""
    last_call_steps_per_m: float = 20.0
    """Actions per metre of travel for the last call's estimate (`last_call_steps`): 15.4 forward moves of
    0.065 m and the turns on the way (paths in the medium houses take about 1.3 actions per forward move,
    stops on the way included; ours)."""
    out_of_reach_last: bool = False
    """A goal the steps left cannot reach goes behind those they can (ours; off = the paper, which has no
    step budget): once an open node's travel times `last_call_steps_per_m` exceeds the steps left, it
    moves behind every node that promises something to see and is within reach, keeping the ranking's
    order otherwise. Without it, a global replan late in the run can send the agent toward a node across
    the house that it cannot reach before the budget ends, past nearer nodes with less to show (medium-179
    seed 0: at step 1776, a node 19.5 m away with 224 steps left). On 17 medium runs (medium-0..3 seeds 0
    and 1, medium-179..187 seed 0) +0.014 points (paired standard error 0.013), 14 runs with the same
    actions, so off (docs/benchmark.md, "A goal the steps left cannot reach")."""
    keep_promise_m: float | None = None
    """Remember what each node outside the agent's subregion promised (its information part) across
    replans, by floor position within this many metres, and rank it by at least that until the agent has
    replanned inside its subregion or visited it (ours, `replan_memory.Promises`; None = off: every replan's
    panoramas alone, as in the paper). A room seen through its door looks half seen from the corridor, and
    the promise of its nodes drops as the agent walks past: on medium-2 seed 0 rooms 7-9 promised 12-13
    at step 769, 7-10 at step 869, and were never entered. 0.5 m on medium-0..3 x 2 seeds: 85.87 ->
    84.52 %, medium-2 seed 1 83.36 -> 71.69 % (the first panoramas promise the maximum everywhere and the
    memory keeps it), so off (docs/benchmark.md "Kept promises and a committed global goal")."""
    commit_global_m: float | None = None
    """Follow a global choice through to its subregion (ours, `replan_memory.Commitment`; None = off: every
    replan ranks anew, as in the paper): a global-stage replan puts first the best node worth a visit of the
    subregion holding the candidate nearest the last global goal (within this many metres), until none of
    it is worth a visit. A long trip has stops on the way (the detour rule, `long_path_m`), and with the map
    grown the best node at each could lie on the other side of the house: on fresh medium-103 the agent
    crossed it six times, 8-13 m each. 1 m on medium-0..3 x 2 seeds: 85.87 -> 85.71 %, at step 1000
    62.41 -> 64.09 %, worst room 71.1 -> 67.6 %; with `global_tour` 85.72 %; fresh medium-100..109 seed 0
    85.83 -> 85.82 %, at step 1000 67.07 -> 67.00 %; so off (docs/benchmark.md
    "Kept promises and a committed global goal")."""
    postpone_once_m: float | None = None
    """A goal is put off by a stop on the way once (ours; None = off: a stop on the way may be taken at every
    replan): when a replan's goal lies within this many metres of the goal the last replan put off for a
    stop on the way (the detour rule, `long_path_m`), the agent goes straight to it. On medium-2 seed 0 the
    best goal at steps 1625, 1693 and 1932 was room 7 (information 30, 11-19 m away); each replan took a
    detour to a nearer node of information 12-13 instead, and the agent never got there. 1 m on medium-0..3
    x 2 seeds: 85.87 -> 86.11 % (medium-2 s0 82.09 -> 83.95); fresh medium-100..109 seed 0: 86.13 -> 85.54 %,
    medium-109 87.05 -> 80.01 % (the second detour was the one that looked into room 1, now 0.3 %); so off
    (docs/benchmark.md "A goal put off once")."""
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
    collision_obstacle_m: float | None = None
    """A forward move the scene refuses marks a disc of this radius on the floor one agent radius and one
    forward step ahead of the agent as an obstacle in every later workspace, until the failures are
    forgotten (no goal left with a path), and the goal is kept open for `collision_fail_after` refusals on
    the way to it (ours; None = off: the paper's rule, a refused move marks the goal failed). The map can
    show floor where a door jamb or a thin piece of furniture stands; the next path then avoids the spot
    instead of giving up the goal (fresh medium-105 seed 0: a refusal in the corridor, 4.7 m short of room
    4's door, closed the room for the rest of the run). 0.05 on fresh medium-100..109 seed 0: 86.32 ->
    85.95 %; a spot marked in a narrow passage closes it (medium-104 -3.36), so off (docs/benchmark.md
    "A forward move the scene refuses")."""
    collision_arrive_m: float | None = None
    """A forward move the scene refuses this near the goal counts as the arrival there: the rotation targets
    are chosen from where the agent stands, and the goal is not marked failed (ours; None = off: the
    paper's rule fails the goal and escapes, so the look the goal was chosen for is never taken: 5 of the
    19 refusals in the seed-0 runs of fresh medium-100..109 came within 0.3 m of the goal). 0.5 on those
    runs: 86.32 -> 86.07 %, three runs +0.1 to +0.3, medium-105 -3.25 through a route change, so off
    (docs/benchmark.md "A forward move the scene refuses")."""
    collision_fail_after: int = 2
    """With `collision_obstacle_m`: the refused forward moves on the way to one goal (within 0.3 m) after
    which it is marked failed (ours)."""
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
    flat_until_step: int | None = None
    """With `hierarchical`, rank goals as `no-hp` does (score order over every node) until this many steps
    have been taken, and local-then-global after (ours; None = hierarchical from the start, as in the
    paper). `no-hp` crosses the house sooner and turns less, the hierarchy finishes rooms; 1000 on medium
    houses: tuning medium-0..3 seed 0 -1.27 points (86.47 -> 85.20 %, medium-2 -4.9), rotations 49.1 ->
    39.1 %; fresh medium-100..107 seed 0 +0.42 (85.32 -> 85.74 %, standard error 0.34), 69.8 -> 73.4 % of
    the ceiling at step 1000, rotations 46.7 -> 39.5 %; held-out medium-150..159 seed 0 -1.39 (86.08 ->
    84.70 %, two houses lose rooms), rotations 46.0 -> 39.2 %. Off (docs/benchmark.md "No-hp first, the
    hierarchy after")."""
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
                                         "unsampled_views", "unsampled_min_weight",
                                         "detour_min_info", "replan_log_top",
                                         "panorama_height_m", "bridge_gain_m", "route_min_info",
                                         "last_call_min_info"),
                     positive=("unsampled_radius_m", "unsampled_voxel_m", "commit_global_m", "route_memory_m",
                               "keep_promise_m", "postpone_once_m", "local_near_m", "neck_margin_m",
                               "cut_off_look_m", "way_back_m", "collision_obstacle_m",
                               "collision_arrive_m", "last_call_steps_per_m"),
                     at_least_one=("max_panoramas", "start_blocks", "collision_fail_after",
                                   "last_call_steps", "flat_until_step"),
                     optional=("bridge_gain_m", "commit_global_m", "route_memory_m", "keep_promise_m",
                               "postpone_once_m", "local_near_m", "neck_margin_m", "cut_off_look_m",
                               "way_back_m", "start_blocks", "collision_obstacle_m", "collision_arrive_m",
                               "last_call_steps", "flat_until_step"))
        if not 0 <= self.bootstrap_pitch_deg <= 90:
            raise InvalidInputError(f"ExplorerConfig.bootstrap_pitch_deg must be in [0, 90] degrees (the "
                                    f"look-around tilts down to -this and back to level), got "
                                    f"{self.bootstrap_pitch_deg}")
        if self.tilt_within_deg is not None and not 0 <= self.tilt_within_deg <= 90:
            raise InvalidInputError(f"ExplorerConfig.tilt_within_deg must be in [0, 90] (or None = off), got "
                                    f"{self.tilt_within_deg}")
        if not -90 < self.travel_pitch_deg < 90:
            raise InvalidInputError(f"ExplorerConfig.travel_pitch_deg must be in (-90, 90) degrees, got "
                                    f"{self.travel_pitch_deg}")
        if self.neck_travel and self.neck_margin_m is None:
            raise InvalidInputError("ExplorerConfig.neck_travel ranks nodes by their travel on the floor "
                                    "grown neck_margin_m into unknown: set neck_margin_m too (e.g. 0.2)")
        if self.global_halving_m is not None and self.global_halving_m <= 0:
            raise InvalidInputError(f"ExplorerConfig.global_halving_m must be > 0 (or None = the distance "
                                    f"weight's difference), got {self.global_halving_m}")


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
    global_halving_m: float | None = None
    global_tour: bool = False
    local_near_m: float | None = None
    route_in_place: bool = False
