"""The explorers' shared behaviour (paper sec. III-C, III-D); their configuration is
`planning.explorer_config.ExplorerConfig` (imported here too).

`Explorer` is what every policy does the same way: the bootstrap look-around, path following with a
re-check of the path ahead, on-the-spot rotations toward targets, and the escape after a collision. A
policy subclasses it and decides where to go (`replan`), what to do on arrival (`arrive`) and where to stop
on the way (`stop_on_the_way`): `planning.activesplat.ActiveSplatExplorer` goes to Voronoi nodes ranked by
`planning.goals` (eq. 12 scores, local-then-global), with the release's long-path rule
(`planning.on_the_way`), and turns toward panorama and high-loss targets on arrival;
`planning.frontier.FrontierExplorer` goes to the nearest frontier.

The policy sees the world only through the online map (`WorldModel`: the Gaussians, a renderer and the
latest high-loss mask) and its own observations; it never reads the ground-truth mesh.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from activesplat.geometry import pose_yaw_pitch, wrap_angle
from activesplat.planning.controller import (
    ControllerConfig,
    PathFollower,
    floor_xz,
    level_actions,
    rotation_actions,
    turn_toward,
)
from activesplat.planning.explorer_config import ExplorerConfig
from activesplat.planning.panorama import Panorama
from activesplat.planning.viewpoints import HighLossTracker, RotationTarget
from activesplat.splat.lod import LOD_INFLATE
from activesplat.timing import Timers
from activesplat.workspace.clean import Workspace, clearance_map
from activesplat.workspace.paths import path_ahead_clear
from activesplat.workspace.plan import Plan


class WorldModel(Protocol):
    """What the planner may use of the online map (the Mapper satisfies it)."""

    gaussians: Any
    high_loss_mask: Any

    def render(self, pose: np.ndarray, K: np.ndarray | None = None, width: int | None = None,
               height: int | None = None, front_alpha: bool = False, behind_margin_deg: float = 0.0) -> Any:
        """``alpha`` and ``median_depth`` of a view; with ``front_alpha`` the opacity of surfaces seen from
        the side that observed them (`Mapper.render`). A world without ``front_alpha`` gives the plain
        opacity to the panoramas (`planning.panorama.render_panorama`)."""


def snapshot_render(world: WorldModel, lod_voxel_m: float | None = None,
                    lod_inflate: float = LOD_INFLATE) -> Any:
    """The world's render for many views of a map that does not change meanwhile (a replan's panoramas):
    its ``snapshot()`` where it has one (`Mapper.snapshot`: the same images, the per-Gaussian work done
    once; with ``lod_voxel_m`` of a coarser copy of the map), else its ``render``."""
    snapshot = getattr(world, "snapshot", None)
    if not callable(snapshot):
        return world.render
    return snapshot() if lod_voxel_m is None else snapshot(lod_voxel_m=lod_voxel_m, lod_inflate=lod_inflate)


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


def retrace_actions(visited: Sequence[np.ndarray], yaw: float, workspace: Workspace, clearance: float,
                    max_m: float, ctrl: ControllerConfig) -> list[str]:
    """Turns and forward moves that walk the agent's own steps backwards (`visited`: its floor positions,
    the latest last; `yaw`: its heading now) to the latest position where the workspace has at least
    `clearance`, or none when it stands at such a clearance already or none lies within `max_m` of
    walking back (ours). Each move is a forward move the simulator accepted, taken the other way: turns
    come in whole steps, so the heading reversed is the heading it came in on, to within float error; the
    map's free floor is too coarse for that in a slot a few centimetres wider than the agent."""
    if not visited or float(workspace.clearance_at(np.asarray(visited[-1], float))) >= clearance:
        return []
    headings, walked = [], 0.0
    for i in range(len(visited) - 1, 0, -1):
        step = np.asarray(visited[i - 1], float) - np.asarray(visited[i], float)
        length = float(np.hypot(*step))
        if length < 1e-9:  # a turn, a tilt or a refused move
            continue
        walked += length
        if walked > max_m:
            return []
        headings.append(math.atan2(step[0], step[1]))
        if float(workspace.clearance_at(np.asarray(visited[i - 1], float))) >= clearance:
            break
    else:
        return []
    turn = math.radians(ctrl.turn_deg)
    actions: list[str] = []
    for heading in headings:
        turns = turn_toward(yaw, heading, ctrl)
        yaw += turn * len(turns) * (1 if turns and turns[0] == "turn_left" else -1)
        actions += turns + ["move_forward"]
    return actions


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
        self.plan = Plan()
        self.follower: PathFollower | None = None
        self.rotation_targets: list[RotationTarget] = []
        self.visited: list[np.ndarray] = []
        self.failed: list[np.ndarray] = []
        self.failures: list[dict] = []
        """Every goal marked failed: step, goal (x, z), why ("no path" to it on the graph, or the path was
        "blocked" ahead / a forward move refused), the failed list's size then and whether the scene refused
        a forward move (`refused`; else the map blocked the path ahead) (the episode's stops.json, under
        "failures"). A failed goal stays closed until no goal is left."""
        self.dense_mapping = True
        self.last_panorama: Panorama | None = None
        self.queue: list[str] = []
        self.queue_causes: list[str] = []
        self.refused: list[tuple[np.ndarray, float]] = []
        """(floor position, yaw) of the refused forward moves at the agent's spot (older spots are dropped
        at the next refusal): the escape does not try a refused heading from the same spot again."""
        self._path_start: np.ndarray | None = None  # where the current path began (`go_to`)
        self.steps_left: int | None = None
        """Actions left in the episode's budget, counting the next one; the loop sets it before every `act`
        (None: unknown, e.g. a robot run without a budget)."""
        self._start_blocks: list[np.ndarray] = []
        """The spots of the latest paths refused ahead before their first forward move, in a row
        (`start_blocks`)."""
        self.rotation_cause = "arrival"
        self.last_cause = ""
        """Why the latest action was taken: bootstrap, idle, escape, way_back (its own steps back to open
        workspace, `way_back_m`), level, look_around (queued actions), arrival / multi_stop (turns toward
        rotation targets), path (following a path) or fallback (nothing to do). The benchmark counts
        actions by cause (where the rotations go)."""
        self.enqueue(bootstrap_actions(self.cfg), "bootstrap")

    # ------------------------------------------------------------------ the loop's interface
    def observe_mapping(self, obs: Any, K: np.ndarray) -> None:
        """Called after the mapper processed `obs`: track its high-loss samples (eq. 10). The world's mask
        is None when the mapper did not map this frame (its schedule maps every n-th frame): then only the
        samples this view looks at are forgotten."""
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
        self._path_start = np.asarray(path[0], float)

    def idle(self, pose: np.ndarray, stuck: bool) -> None:
        """No goal to go to: look around on the spot (the map grows, the next replan may find goals). When
        goals exist but every one failed from here (`stuck`), first escape toward the clearest heading: from
        the same spot the same goals would fail again."""
        if self._leave_spot(pose, escape=stuck):
            return
        self.enqueue(["turn_left"] * turns_for(self.cfg.idle_yaw_deg, self.cfg.controller), "idle")

    def _leave_spot(self, pose: np.ndarray, escape: bool = True) -> bool:
        """Queue the agent's own steps back to open workspace (`way_back_m`) and return True; where there is
        none, queue the escape toward the clearest heading if `escape`, and return False."""
        back = self._way_back(pose)
        if back:
            self.enqueue(back, "way_back")
            return True
        if escape:
            self.enqueue(escape_actions(pose, self.plan.workspace, self.cfg.controller,
                                        self.cfg.escape_forward_steps), "escape")
        return False

    def _way_back(self, pose: np.ndarray) -> list[str]:
        """The actions that retrace the agent's own steps to open workspace (`way_back_m`), or none. With
        no workspace left around the agent, the observed free floor stands in for it."""
        limit, workspace, grids = self.cfg.way_back_m, self.plan.workspace, self.plan.grids
        if limit is None:
            return []
        if (workspace is None or workspace.empty) and grids is not None:
            free = grids.free & ~grids.obstacle
            workspace = Workspace(grids.geometry, free, clearance_map(free, grids.geometry.resolution),
                                  np.zeros((0, 2)))
        if workspace is None or workspace.empty:
            return []
        return retrace_actions(self.visited, pose_yaw_pitch(pose)[0], workspace,
                               self.cfg.workspace.path_clearance, limit, self.cfg.controller)

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
        if action != "move_forward":
            return action
        if not self._path_ahead_clear(pose):
            self._fail_goal()
            self._leave_if_blocked_at_start(pose)
            return None
        self._start_blocks = []
        tilt = self._travel_tilt(pose) if self.cfg.travel_pitch_deg else []
        return tilt[0] if tilt else action

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

    def _leave_if_blocked_at_start(self, pose: np.ndarray) -> None:
        """A path refused ahead: when it is the `start_blocks`-th in a row refused before its first forward
        move from this spot, queue the way back (`way_back_m`) or else the escape. Otherwise the next
        replan tries the next goal from here, and, once the open goals have failed, the failed ones again."""
        limit = self.cfg.start_blocks
        here = floor_xz(pose)
        near = 0.5 * self.cfg.controller.forward_m
        if limit is None or self._path_start is None or np.hypot(*(here - self._path_start)) > near:
            self._start_blocks = []
            return
        self._start_blocks = [p for p in self._start_blocks if np.hypot(*(p - here)) <= near] + [here]
        if len(self._start_blocks) < limit:
            return
        self._start_blocks = []
        self._leave_spot(pose)

    def _fail_goal(self, refused: bool = False) -> None:
        if self.plan.goal is not None:
            self._mark_failed(self.plan.goal, "blocked", refused)
        self.follower = None

    def _mark_failed(self, goal: np.ndarray, why: str, refused: bool = False) -> None:
        self.failed.append(goal)
        self._log_failure(goal, why, refused)

    def _log_failure(self, goal: np.ndarray, why: str, refused: bool = False) -> None:
        self.failures.append({"step": len(self.visited) - 1, "goal": [round(float(v), 3) for v in goal],
                              "why": why, "failed_now": len(self.failed), "refused": refused})

    def forget_failures(self) -> None:
        """The fallback when no goal has a path: every failed goal gets a second chance."""
        self.failed.clear()

    def _on_collision(self, pose: np.ndarray) -> None:
        """A refused forward move: mark the goal failed and escape toward the clearest heading not yet
        refused from this spot. Where the map shows free space that the scene does not have (a chair leg, a
        door frame it has not mapped), the clearest heading on the map is refused every time: without the
        memory an agent tried the same three headings for 1300 steps (fresh medium-101, seed 2)."""
        self._fail_goal(refused=True)
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
           "escape_actions", "retrace_actions", "turns_for"]
