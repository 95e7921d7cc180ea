"""The explorers' shared behaviour (paper sec. III-C, III-D) and their configuration.

`Explorer` is what every policy does the same way: the bootstrap look-around, path following with a
re-check of the path ahead, on-the-spot rotations toward targets, and the escape after a collision. A
policy subclasses it and decides where to go (`replan`), what to do on arrival (`arrive`) and where to stop
on the way (`stop_on_the_way`): `planning.activesplat.ActiveSplatExplorer` goes to Voronoi nodes ranked by
`planning.goals` (eq. 12 scores, local-then-global, the long-path rule) and turns toward panorama and
high-loss targets on arrival; `planning.frontier.FrontierExplorer` goes to the nearest frontier.

The policy sees the world only through the online map (`WorldModel`: the Gaussians, a renderer and the
latest high-loss mask) and its own observations; it never reads the ground-truth mesh.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from activesplat.errors import InvalidInputError, check_fields
from activesplat.geometry import pose_yaw_pitch, wrap_angle
from activesplat.planning.config import PlanningConfig
from activesplat.planning.controller import (
    ControllerConfig,
    PathFollower,
    floor_xz,
    level_actions,
    rotation_actions,
)
from activesplat.planning.observed import ObservedSurface
from activesplat.planning.panorama import Panorama
from activesplat.planning.viewpoints import HighLossTracker, RotationTarget
from activesplat.timing import Timers
from activesplat.workspace.clean import Workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.paths import path_ahead_clear
from activesplat.workspace.plan import Plan


class WorldModel(Protocol):
    """What the planner may use of the online map (the Mapper satisfies it)."""

    gaussians: Any
    high_loss_mask: Any

    def render(self, pose: np.ndarray, K: np.ndarray | None = None, width: int | None = None,
               height: int | None = None) -> Any: ...


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
    multi_stop_spacing_m: float = 1.5
    """No rotation stop at a multi-connected node within this of a spot already rotated at (the start's
    look-around included); 0 = the arrival rule above, as in the release (ours: in furnished rooms the
    Voronoi graph branches around every piece of furniture, so junctions lie ~1 m apart and the agent
    stopped at each; 1.5 m: medium-0..3 x 2 seeds, 59.7 -> 71.1 % of the ceiling at step 1000, rotations
    57.0 -> 46.8 %, final completion 83.92 -> 84.66 %, docs/benchmark.md "Tuning log")."""
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
    retry_unreachable: bool = False
    """A goal with no safe path on this replan's graph is skipped for this replan only instead of marked
    failed (ours; False = marked failed, i.e. closed until no goal is left, as in the release). A goal cut
    off for one replan (the floor of a doorway or a corridor not yet mapped) otherwise stays closed for the
    rest of the episode (medium-1 seed 0 with `--mapper.edge-band-px 2`, README "Mapping at house
    scale"). Goals refused on the way (a blocked path, a refused forward move) are still marked failed."""
    global_tour: bool = False
    """In the global stage, go first to the subregion that comes first on the shortest open route from the
    agent through every subregion with a node worth a visit (information above `local_score_threshold`;
    each subregion's best such node stands for it, graph path lengths; `goals.tour_first`), instead of to
    the best score minus distance (ours; the paper names a distance cost, not a route). medium-0..3 x 2
    seeds: 86.02 -> 85.75 %, at step 1000 71.0 -> 65.3 % of the ceiling, so off (docs/benchmark.md "A route
    through the subregions")."""
    global_in_horizon: bool = False
    """Count eq. 12's in-horizon flag in the global stage too (paper: one score for every node; this
    project's default until the change below). False (ours): the global stage ranks nodes without it. The
    flag marks a node in a straight line of sight, which is a local preference: down a corridor it gave a
    node 11 m away the same 10 points as one in the next room, and the agent crossed the house past rooms
    it had not entered."""
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
    """In the global stage, go first to the nearest open node whose information exceeds
    `detour_min_info`, if it is nearer than the chosen goal and costs at most this many metres of extra
    travel on the way to it (graph lengths, `goals.worth_a_detour`), instead of straight to the goal (ours;
    None = off, the paper's rule). The door of an unseen room shows little of the room in a panorama, so a
    node with a large unseen area behind it elsewhere outranks it and the agent walked past the door and
    never came back (fresh medium-104 and medium-109, seed 0). Measured with 5 m (docs/benchmark.md "Rooms
    passed on the way"): tuning houses 85.94 -> 86.21 % (with the mapper's colour detail, 86.49 %), fresh
    medium-100..109 seed 0 84.76 -> 86.31 % (with the colour detail 85.03 %), held-out medium-110..119
    seed 0 85.39 -> 86.45 % (with the colour detail); rotations rise from 44-46 % to 49-50 %."""
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
    lookahead_m: float = 0.65
    """Re-check this much of the path ahead at every step (release: 10 forward steps)."""
    ahead_tolerance_m: float = 0.05
    """The path-ahead check forgives this much clearance (ours: one workspace cell). The agent follows its
    path only to within the arrival radius, so the segment it checks starts up to ~0.1 m off the planned
    one, and clearance is quantised to cells: without it an agent beside a wall corner fails every goal at
    its first forward step and turns on the spot for hundreds of steps."""
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
        check_fields(self, non_negative=("bootstrap_yaw_deg", "bootstrap_pitch_deg", "idle_yaw_deg",
                                         "max_rotation_views", "multi_stop_views", "rotation_skip_radii",
                                         "multi_stop_spacing_m",
                                         "multi_node_radius_m", "local_score_threshold",
                                         "global_distance_weight", "long_path_m", "on_the_way_m",
                                         "escape_forward_steps", "lookahead_m", "ahead_tolerance_m",
                                         "unsampled_views", "unsampled_min_weight",
                                         "detour_min_info",
                                         "panorama_height_m"),
                     positive=("unsampled_radius_m", "unsampled_voxel_m"), at_least_one=("max_panoramas",))
        if self.tilt_within_deg is not None and not 0 <= self.tilt_within_deg <= 90:
            raise InvalidInputError(f"ExplorerConfig.tilt_within_deg must be in [0, 90] (or None = off), got "
                                    f"{self.tilt_within_deg}")
        if not -90 < self.travel_pitch_deg < 90:
            raise InvalidInputError(f"ExplorerConfig.travel_pitch_deg must be in (-90, 90) degrees, got "
                                    f"{self.travel_pitch_deg}")
        if self.bridge_gain_m is not None and self.bridge_gain_m < 0:
            raise InvalidInputError(f"ExplorerConfig.bridge_gain_m must be >= 0 (or None = off), got "
                                    f"{self.bridge_gain_m}")
        if self.global_halving_m is not None and self.global_halving_m <= 0:
            raise InvalidInputError(f"ExplorerConfig.global_halving_m must be > 0 (or None = the distance "
                                    f"weight's difference), got {self.global_halving_m}")


@dataclass(frozen=True)
class ExplorerView:
    """A read-only snapshot of the explorer's state for viewers (`ActiveSplatExplorer.view_state`). The
    objects are the explorer's own, shared not copied: look, do not modify."""

    name: str
    floor_height: float
    plan: Plan
    """The latest plan (a new object after every replan): graph, subregions, scores, goal, path, grids."""
    panorama: Panorama | None
    """The latest on-arrival panorama the rotation targets were chosen from (None before the first)."""
    rotation_targets: tuple[RotationTarget, ...]
    """Rotation targets still to visit at the current spot."""


def turns_for(angle_deg: float, ctrl: ControllerConfig) -> int:
    """How many TURN_LEFT / TURN_RIGHT actions make `angle_deg` (nearest whole number)."""
    return int(round(angle_deg / ctrl.turn_deg))


def bootstrap_actions(cfg: ExplorerConfig) -> list[str]:
    """The look-around before departure: `bootstrap_yaw_deg` in left turns, each followed by one tilt of the
    cycle down to -`bootstrap_pitch_deg` and back to level."""
    ctrl = cfg.controller
    tilts = int(round(cfg.bootstrap_pitch_deg / ctrl.look_deg))
    cycle = ["look_down"] * tilts + ["look_up"] * tilts
    actions: list[str] = []
    for i in range(turns_for(cfg.bootstrap_yaw_deg, ctrl)):
        actions.append("turn_left")
        if cycle:
            actions.append(cycle[i % len(cycle)])
    return actions


def escape_actions(pose: np.ndarray, workspace: Workspace | None, ctrl: ControllerConfig,
                   forward_steps: int, blocked: Sequence[float] = ()) -> list[str]:
    """After a collision: turn to the heading of a full circle of turns whose next 0.3 m has the most
    clearance on the workspace (the shorter way round on ties), then move forward `forward_steps` times.
    Headings within half a turn of a `blocked` yaw (radians: forward moves refused from this spot) are
    not taken while another is left. Without a workspace: a quarter turn left."""
    yaw, _ = pose_yaw_pitch(pose)
    here = floor_xz(pose)
    full = turns_for(360.0, ctrl)
    half_turn = math.radians(0.5 * ctrl.turn_deg)
    best_turns, best_clear = full // 2, -1.0
    for k in range(1, full):
        turns = k if k <= full // 2 else k - full  # positive: left
        if workspace is None or workspace.empty:
            best_turns = turns_for(90.0, ctrl)
            break
        h = yaw + math.radians(ctrl.turn_deg * turns)
        if any(abs(float(wrap_angle(h - b))) < half_turn for b in blocked):
            continue
        ahead = here + 0.3 * np.array([math.sin(h), math.cos(h)])
        clear = float(workspace.segments_clearance(here[None], ahead[None])[0])
        if clear > best_clear + 1e-6:
            best_turns, best_clear = turns, clear
    turn = ["turn_left" if best_turns > 0 else "turn_right"] * abs(best_turns)
    return turn + ["move_forward"] * forward_steps


class Explorer:
    """One object per episode. `act(obs)` returns the next action name; `dense_mapping` tells the loop to
    map with the denser schedule (bootstrap, on-the-spot rotations, escapes: whenever it is not travelling).

    Each step it takes, in this order: the next queued action (bootstrap, look-arounds, escapes), a turn or
    tilt toward the next rotation target, the next action along the current path, else a replan. Policies
    implement `replan` (set a goal with `go_to`, or `idle`) and may override `arrive` and
    `stop_on_the_way`."""

    name = "explorer"

    def __init__(self, world: WorldModel, floor_height: float, cfg: ExplorerConfig | None = None,
                 timers: Timers | None = None):
        self.world = world
        self.floor_height = float(floor_height)
        self.cfg = cfg or ExplorerConfig()
        self.timers = timers or Timers()
        self.rng = np.random.default_rng(self.cfg.seed)
        self.high_loss = HighLossTracker(self.cfg.planning.high_loss)
        score_cfg = self.cfg.planning.score
        self.observed = ObservedSurface(score_cfg.quality_voxel_m) if score_cfg.w_q > 0 else None
        """The voxels the agent's own depth frames have sampled (only with the w_q score term)."""
        self.sampled = ObservedSurface(self.cfg.unsampled_voxel_m) if self.cfg.unsampled_views > 0 else None
        """The same at `unsampled_voxel_m`, for the rotation targets toward unsampled surface."""
        self.plan = Plan()
        self.follower: PathFollower | None = None
        self.rotation_targets: list[RotationTarget] = []
        self.visited: list[np.ndarray] = []
        self.failed: list[np.ndarray] = []
        self.failures: list[dict] = []
        """Every goal marked failed: step, goal (x, z), why ("no path" to it on the graph, or the path was
        "blocked" ahead / a forward move refused) and the failed list's size then (the episode's
        stops.json, under "failures"). A failed goal stays closed until no goal is left."""
        self.dense_mapping = True
        self.last_panorama: Panorama | None = None
        self.queue: list[str] = []
        self.queue_causes: list[str] = []
        self.refused: list[tuple[np.ndarray, float]] = []
        """(floor position, yaw) of the refused forward moves at the agent's spot (older spots are dropped
        at the next refusal): the escape does not try a refused heading from the same spot again."""
        self.rotation_cause = "arrival"
        self.last_cause = ""
        """Why the latest action was taken: bootstrap, idle, escape, level, look_around (queued actions),
        arrival / multi_stop (turns toward rotation targets), path (following a path) or fallback (nothing
        to do). The benchmark counts actions by cause (where the rotations go)."""
        self.enqueue(bootstrap_actions(self.cfg), "bootstrap")

    # ------------------------------------------------------------------ the loop's interface
    def observe_mapping(self, obs: Any, K: np.ndarray) -> None:
        """Called after the mapper processed `obs`: track its high-loss samples (eq. 10), and with the w_q
        score term the voxels its depth sampled. The world's mask is None when the mapper did not map this
        frame (its schedule maps every n-th frame): then only the samples this view looks at are
        forgotten."""
        if self.observed is not None:
            self.timers.time("position_selection", self.observed.add, obs.depth, obs.pose, K)
        if self.sampled is not None:
            self.timers.time("rotation_selection", self.sampled.add, obs.depth, obs.pose, K)
        mask = getattr(self.world, "high_loss_mask", None)
        if mask is None:
            self.high_loss.observe(np.asarray(obs.pose, dtype=np.float64))
            return
        m = mask.detach().cpu().numpy() if hasattr(mask, "detach") else np.asarray(mask)
        self.timers.time("rotation_selection", self.high_loss.update, m, obs.depth, obs.pose, K, obs.step)

    def act(self, obs: Any) -> str:
        """The next action after observation `obs` (its pose, and whether its forward move was refused)."""
        pose = np.asarray(obs.pose, dtype=np.float64)
        self.visited.append(floor_xz(pose))
        if getattr(obs, "collided", False):
            self._on_collision(pose)
        action = self._next(pose)
        # map densely whenever the agent is not travelling (docs/protocol.md §2)
        self.dense_mapping = self.follower is None
        return action

    def view_state(self) -> ExplorerView:
        """What a viewer may show (read-only, cheap: no copies)."""
        return ExplorerView(self.name, self.floor_height, self.plan, self.last_panorama,
                            tuple(self.rotation_targets))

    # ------------------------------------------------------------------ what a policy decides
    def replan(self, pose: np.ndarray) -> None:
        """Choose what to do next from `pose`: `go_to` a goal, or `idle`."""
        raise NotImplementedError

    def arrive(self, pose: np.ndarray) -> None:
        """Called when the current path's last waypoint is reached (default: nothing)."""

    def stop_on_the_way(self, pose: np.ndarray) -> bool:
        """Called before every step along a path: True interrupts it for the rotation targets just set
        (the path resumes afterwards). Default: never."""
        return False

    # ------------------------------------------------------------------ what a policy may use
    def enqueue(self, actions: list[str], cause: str) -> None:
        """Queue `actions` (taken before anything else), recording why (`last_cause`)."""
        self.queue.extend(actions)
        self.queue_causes.extend([cause] * len(actions))

    def go_to(self, goal: np.ndarray, path: np.ndarray) -> None:
        """Follow `path` (M, 2), which starts at the agent, to `goal`."""
        self.plan.goal, self.plan.path = goal, path
        self.follower = PathFollower(path[1:], self.cfg.controller)

    def idle(self, pose: np.ndarray, stuck: bool) -> None:
        """No goal to go to: look around on the spot (the map grows, the next replan may find goals). When
        goals exist but every one failed from here (`stuck`), first escape toward the clearest heading: from
        the same spot the same goals would fail again."""
        if stuck:
            self.enqueue(escape_actions(pose, self.plan.workspace, self.cfg.controller,
                                        self.cfg.escape_forward_steps), "escape")
        self.enqueue(["turn_left"] * turns_for(self.cfg.idle_yaw_deg, self.cfg.controller), "idle")

    # ------------------------------------------------------------------ behaviour
    def _next(self, pose: np.ndarray) -> str:
        for _ in range(4):  # a few state transitions per step at most
            if self.queue:
                self.last_cause = self.queue_causes.pop(0) if self.queue_causes else "queued"
                return self.queue.pop(0)
            if self.rotation_targets:
                action = self._rotation_action(pose)
                if action:
                    self.last_cause = self.rotation_cause
                    return action
                continue
            if self.follower is not None:
                action = self._follow(pose)
                if action:
                    self.last_cause = "path"
                    return action
                continue
            self.replan(pose)
            if self.follower is None and not self.queue and not self.rotation_targets:
                break
        # nothing to do: look around on the spot (the map grows, the next replan may find goals)
        self.last_cause = "fallback"
        return "turn_left"

    def _follow(self, pose: np.ndarray) -> str | None:
        assert self.follower is not None
        if self.stop_on_the_way(pose):
            return None  # rotation targets come first; the path resumes afterwards
        action = self.follower.next_action(pose)
        if action is None:  # arrived
            self.follower = None
            self.arrive(pose)
            return None
        if action == "move_forward" and not self._path_ahead_clear(pose):
            self._fail_goal()
            return None
        if action == "move_forward" and self.cfg.travel_pitch_deg:
            tilt = self._travel_tilt(pose)
            if tilt:
                return tilt[0]
        return action

    def _travel_tilt(self, pose: np.ndarray) -> list[str]:
        """Tilts that bring the camera to the travel pitch (`travel_pitch_deg`)."""
        return level_actions(pose, self.cfg.controller, math.radians(self.cfg.travel_pitch_deg))

    def _rotation_action(self, pose: np.ndarray) -> str | None:
        ctrl = self.cfg.controller
        target = self.rotation_targets[0]
        actions = rotation_actions(pose, target.yaw, target.pitch, ctrl)
        if actions:
            return actions[0]
        self.rotation_targets.pop(0)
        if not self.rotation_targets:
            self.enqueue(self._travel_tilt(pose), "level")
        return None

    def _path_ahead_clear(self, pose: np.ndarray) -> bool:
        """Re-check the next `lookahead_m` of the path (release) on the current workspace."""
        if self.follower is None or self.follower.done:
            return True
        return path_ahead_clear(self.plan.workspace, floor_xz(pose), self.follower.waypoints[0],
                                self.cfg.lookahead_m, self.cfg.ahead_tolerance_m, self.cfg.workspace,
                                segment_start=self.follower.passed)

    def _fail_goal(self) -> None:
        if self.plan.goal is not None:
            self._mark_failed(self.plan.goal, "blocked")
        self.follower = None

    def _mark_failed(self, goal: np.ndarray, why: str) -> None:
        self.failed.append(goal)
        self._log_failure(goal, why)

    def _log_failure(self, goal: np.ndarray, why: str) -> None:
        self.failures.append({"step": len(self.visited) - 1, "goal": [round(float(v), 3) for v in goal],
                              "why": why, "failed_now": len(self.failed)})

    def _on_collision(self, pose: np.ndarray) -> None:
        """A refused forward move: mark the goal failed and escape toward the clearest heading not yet
        refused from this spot. Where the map shows free space that the scene does not have (a chair leg,
        a door frame it has not mapped), the clearest heading on the map is refused every time: without
        the memory an agent tried the same three headings for 1300 steps (fresh medium-101, seed 2)."""
        self._fail_goal()
        self.rotation_targets = []
        self.queue, self.queue_causes = [], []
        here = floor_xz(pose)
        near = self.cfg.controller.forward_m * 0.5
        self.refused = [(p, y) for p, y in self.refused if np.hypot(*(p - here)) <= near]
        self.refused.append((here, pose_yaw_pitch(pose)[0]))
        blocked = [y for _, y in self.refused]
        if len(blocked) >= turns_for(360.0, self.cfg.controller):
            self.refused, blocked = [], []  # every heading refused once: start over
        self.enqueue(escape_actions(pose, self.plan.workspace, self.cfg.controller,
                                    self.cfg.escape_forward_steps, blocked), "escape")


__all__ = ["Explorer", "ExplorerConfig", "ExplorerView", "Plan", "Timers", "WorldModel", "bootstrap_actions",
           "escape_actions", "turns_for"]
