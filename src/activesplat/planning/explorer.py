"""The ActiveSplat explorer (paper sec. III-B, III-C, III-D): bootstrap look-around, Voronoi-node
viewpoint selection from panoramas, local-then-global goals over UPGMA subregions, safe paths turned
into actions, on-the-spot rotations on arrival, collision recovery.

The policy sees the world only through the online map (`WorldModel`: the Gaussians, a renderer and the
latest high-loss mask) and its own observations; it never reads the ground-truth mesh.
"""

from __future__ import annotations

import math
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import networkx as nx
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
from activesplat.planning.panorama import Panorama, render_panorama
from activesplat.planning.viewpoints import (
    HighLossTracker,
    RotationTarget,
    hull_volume,
    information_scores,
    invisible_share,
    node_scores,
    rotation_candidates,
)
from activesplat.workspace.clean import Workspace, extract_workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.paths import line_of_sight, path_length, plan_safe_path
from activesplat.workspace.subregions import agent_subregion, partition_subregions
from activesplat.workspace.topdown import TopDownGrids, render_topdown
from activesplat.workspace.voronoi import build_voronoi_graph


class WorldModel(Protocol):
    """What the planner may use of the online map (the Mapper satisfies it)."""

    gaussians: Any
    high_loss_mask: Any

    def render(self, pose: np.ndarray, K: np.ndarray | None = None, width: int | None = None,
               height: int | None = None) -> Any: ...


@dataclass(frozen=True)
class ExplorerConfig:
    """The explorer's own knobs; the planning / workspace / controller configs hold the paper's numbers."""

    bootstrap_turns: int = 36
    """360 deg look-around in 10 deg turns before departure (REFERENCE.md section 1)."""
    bootstrap_tilts: tuple[str, ...] = ("look_down",) * 3 + ("look_up",) * 3
    """Tilt pattern cycled after each bootstrap turn: pitches 0 -> -45 deg and back (release)."""
    max_rotation_views: int = 5
    """On-the-spot rotation targets at most per arrival (release: 5; MP3D 4)."""
    rotation_skip_radii: float = 3.0
    """No on-the-spot rotations within this many agent radii of a spot already rotated at (release)."""
    multi_node_radius_m: float = 0.3
    """Passing within this of a multi-connected node forces a short rotation stop there (ours)."""
    local_score_threshold: float = 5.0
    """Local planning keeps picking nodes of the current subregion while their information score
    w_o s_o + w_c s_c (eq. 12 without the unvisited / in-horizon flags) exceeds this (ours: 5 = a quarter of
    the best invisible share anywhere; with the flags counted an agent revisits a seen room node by node)."""
    global_distance_weight: float = 1.0
    """Global goal score = node score - this x path length in metres (ours; the paper names a distance
    cost without a value)."""
    long_path_m: float = 13.0
    """Release: a goal path longer than 13 m (200 steps) is kept only if no closer node lies on the way."""
    on_the_way_m: float = 0.5
    """A node lies on the way of a long path when it is within this of the path (ours)."""
    max_panoramas: int = 24
    """Most candidate nodes scored by panorama per replan, nearest first (ours: bounds the replan time)."""
    escape_forward_steps: int = 3
    """Forward steps of a collision escape after turning to the clearest heading (ours)."""
    lookahead_m: float = 0.65
    """Re-check this much of the path ahead at every step (release: 10 forward steps)."""
    ahead_tolerance_m: float = 0.05
    """The path-ahead check forgives this much clearance (ours: one workspace cell). The agent follows its
    path only to within the arrival radius, so the segment it checks starts up to ~0.1 m off the planned
    one, and clearance is quantised to cells: without it an agent beside a wall corner fails every goal at
    its first forward step and turns on the spot for hundreds of steps."""
    panorama_height_m: float = 1.25
    """Panoramas are rendered at the sensor height above the floor (REFERENCE.md section 1)."""
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
        check_fields(self, non_negative=("bootstrap_turns", "max_rotation_views", "rotation_skip_radii",
                                         "multi_node_radius_m", "local_score_threshold",
                                         "global_distance_weight", "long_path_m", "on_the_way_m",
                                         "escape_forward_steps", "lookahead_m", "ahead_tolerance_m",
                                         "panorama_height_m"), at_least_one=("max_panoramas",))
        bad = [t for t in self.bootstrap_tilts if t not in ("look_up", "look_down")]
        if bad:
            raise InvalidInputError(f"ExplorerConfig.bootstrap_tilts takes look_up / look_down, "
                                    f"got {bad[0]!r}")


@dataclass
class Plan:
    """What the explorer currently knows of the workspace (for drawing and the viewer)."""

    grids: TopDownGrids | None = None
    workspace: Workspace | None = None
    graph: nx.Graph = field(default_factory=nx.Graph)
    subregions: dict[int, int] = field(default_factory=dict)
    scores: dict[int, float] = field(default_factory=dict)
    info: dict[int, float] = field(default_factory=dict)
    """The information part of each node's score (w_o s_o + w_c s_c), see `information_scores`."""
    goal: np.ndarray | None = None
    path: np.ndarray | None = None


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


def build_plan(gaussians: Any, floor_height: float, agent_xz: np.ndarray, wcfg: WorkspaceConfig,
               timers: Timers | None = None, graph: bool = True) -> Plan:
    """Top-down grids -> workspace -> Voronoi graph -> subregions of the current map (sec. III-A, III-C)."""
    timers = timers or Timers()
    plan = Plan()
    plan.grids = timers.time("workspace", render_topdown, gaussians, floor_height, wcfg, agent_xz)
    plan.workspace = timers.time("workspace", extract_workspace, plan.grids, agent_xz, wcfg)
    if graph:
        plan.graph = timers.time("voronoi", build_voronoi_graph, plan.workspace, wcfg)
        plan.subregions = timers.time("subregions", partition_subregions, plan.graph, wcfg)
    return plan


class Timers:
    """Mean milliseconds per step of each module (Tab. VI): totals divided by the step count."""

    def __init__(self) -> None:
        self.total_ms: dict[str, float] = defaultdict(float)

    def time(self, name: str, fn: Callable, *args, **kwargs):
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            self.total_ms[name] += 1000.0 * (time.perf_counter() - t0)

    def per_step(self, steps: int) -> dict[str, float]:
        return {k: v / max(steps, 1) for k, v in self.total_ms.items()}


class ActiveSplatExplorer:
    """One object per episode. `act(obs)` returns the next action name; `dense_mapping` tells the loop to
    map with the denser schedule (bootstrap and on-the-spot rotations)."""

    name = "activesplat"

    def __init__(self, world: WorldModel, floor_height: float, cfg: ExplorerConfig | None = None,
                 timers: Timers | None = None):
        self.world = world
        self.floor_height = float(floor_height)
        self.cfg = cfg or ExplorerConfig()
        self.timers = timers or Timers()
        self.rng = np.random.default_rng(self.cfg.seed)
        self.high_loss = HighLossTracker(self.cfg.planning.high_loss)
        self.plan = Plan()
        self.queue: list[str] = []
        self.follower: PathFollower | None = None
        self.rotation_targets: list[RotationTarget] = []
        self.visited: list[np.ndarray] = []
        self.failed: list[np.ndarray] = []
        self.rotated_at: list[np.ndarray] = []
        self.stopped_multi: list[np.ndarray] = []
        self.dense_mapping = True
        self.last_panorama: Panorama | None = None
        self._bootstrap()

    # ------------------------------------------------------------------ public
    def observe_mapping(self, obs: Any, K: np.ndarray) -> None:
        """Called after the mapper processed `obs`: track its high-loss samples (eq. 10)."""
        mask = getattr(self.world, "high_loss_mask", None)
        if mask is not None:
            m = mask.detach().cpu().numpy() if hasattr(mask, "detach") else np.asarray(mask)
            self.timers.time("rotation_selection", self.high_loss.update, m, obs.depth, obs.pose, K, obs.step)

    def act(self, obs: Any) -> str:
        pose = np.asarray(obs.pose, dtype=np.float64)
        self.visited.append(floor_xz(pose))
        if getattr(obs, "collided", False):
            self._on_collision(pose)
        action = self._next(pose)
        # map densely whenever the agent is not travelling: bootstrap, rotations, escapes (REFERENCE sec. 2)
        self.dense_mapping = self.follower is None
        return action

    def view_state(self) -> ExplorerView:
        """What a viewer may show (read-only, cheap: no copies)."""
        return ExplorerView(self.name, self.floor_height, self.plan, self.last_panorama,
                            tuple(self.rotation_targets))

    # ------------------------------------------------------------------ behaviour
    def _bootstrap(self) -> None:
        tilts = self.cfg.bootstrap_tilts
        for i in range(self.cfg.bootstrap_turns):
            self.queue.append("turn_left")
            if tilts:
                self.queue.append(tilts[i % len(tilts)])

    def _next(self, pose: np.ndarray) -> str:
        for _ in range(4):  # a few state transitions per step at most
            if self.queue:
                return self.queue.pop(0)
            if self.rotation_targets:
                action = self._rotation_action(pose)
                if action:
                    return action
                continue
            if self.follower is not None:
                action = self._follow(pose)
                if action:
                    return action
                continue
            self._replan(pose)
            if self.follower is None and not self.queue and not self.rotation_targets:
                break
        # nothing to do: look around on the spot (the map grows, the next replan may find goals)
        return "turn_left"

    def _follow(self, pose: np.ndarray) -> str | None:
        assert self.follower is not None
        if self.cfg.multi_stops and self._near_unstopped_multi_node(pose):
            return None  # rotation targets come first; the path resumes afterwards
        action = self.follower.next_action(pose)
        if action is None:  # arrived
            self.follower = None
            self._arrive(pose)
            return None
        if action == "move_forward" and not self._path_ahead_clear(pose):
            self._fail_goal()
            return None
        return action

    def _rotation_action(self, pose: np.ndarray) -> str | None:
        ctrl = self.cfg.controller
        target = self.rotation_targets[0]
        actions = rotation_actions(pose, target.yaw, target.pitch, ctrl)
        if actions:
            return actions[0]
        self.rotation_targets.pop(0)
        if not self.rotation_targets:
            self.queue.extend(level_actions(pose, ctrl))
        return None

    def _arrive(self, pose: np.ndarray) -> None:
        """On-the-spot rotations toward the panorama and high-loss targets (sec. III-B3)."""
        if not self.cfg.rotations:
            return
        here = floor_xz(pose)
        skip = self.cfg.rotation_skip_radii * self.cfg.workspace.agent_radius
        if any(np.hypot(*(here - p)) < skip for p in self.rotated_at):
            return
        self.rotated_at.append(here)
        self.rotation_targets = self.timers.time("rotation_selection", self._rotation_targets, pose)

    def _rotation_targets(self, pose: np.ndarray) -> list[RotationTarget]:
        pcfg = self.cfg.planning
        origin = pose[:3, 3]
        pano = self.last_panorama = render_panorama(self.world.render, origin, pcfg.panorama)
        targets = rotation_candidates(pano, pcfg.rotation) + self.high_loss.targets(origin, max_distance=4.0)
        yaw, _ = pose_yaw_pitch(pose)
        chosen: list[RotationTarget] = []
        for t in sorted(targets, key=lambda t: -t.weight):
            limit = pcfg.rotation.min_offset_deg if t.source == "panorama" else pcfg.high_loss.min_offset_deg
            if abs(math.degrees(float(wrap_angle(t.yaw - yaw)))) <= limit and abs(math.degrees(t.pitch)) < 20:
                continue
            if any(abs(float(wrap_angle(t.yaw - c.yaw))) < math.radians(20) for c in chosen):
                continue
            chosen.append(t)
            if len(chosen) >= self.cfg.max_rotation_views:
                break
        # visit them in angular order from the current heading (less turning)
        return sorted(chosen, key=lambda t: float(wrap_angle(t.yaw - yaw)) % (2 * math.pi))

    def _near_unstopped_multi_node(self, pose: np.ndarray) -> bool:
        """Passing a multi-connected node: a short rotation stop there (paper sec. III-D3)."""
        graph = self.plan.graph
        here = floor_xz(pose)
        for _, data in graph.nodes(data=True):
            if not data.get("multi"):
                continue
            pos = np.asarray(data["pos"])
            if np.hypot(*(pos - here)) > self.cfg.multi_node_radius_m:
                continue
            if any(np.hypot(*(pos - p)) < self.cfg.multi_node_radius_m for p in self.stopped_multi):
                continue
            self.stopped_multi.append(pos)
            self._arrive(pose)
            return bool(self.rotation_targets)
        return False

    # ------------------------------------------------------------------ replanning
    def _replan(self, pose: np.ndarray) -> None:
        cfg = self.cfg
        here = floor_xz(pose)
        plan = self.plan = build_plan(self.world.gaussians, self.floor_height, here, cfg.workspace,
                                      self.timers)
        goal_order = self.timers.time("position_selection", self._rank_goals, here)
        for node in goal_order:
            goal = np.asarray(plan.graph.nodes[node]["pos"], float)
            if np.hypot(*(goal - here)) <= cfg.controller.arrive_radius:
                # already there: arriving again would end in a replan at once, every step (a `hull-only`
                # agent spun on the spot for 200 steps that way, replanning four times per step)
                continue
            path = self.timers.time("planner", plan_safe_path, plan.graph, plan.workspace, here, goal,
                                    cfg.workspace)
            if path is None:
                self.failed.append(goal)
                continue
            if path_length(path) > cfg.long_path_m:
                goal, path = self._closer_on_the_way(here, goal, path)
            plan.goal, plan.path = goal, path
            self.follower = PathFollower(path[1:], cfg.controller)
            return
        plan.goal, plan.path = None, None
        stuck = bool(self.failed)
        self.failed.clear()  # fallback: forget failures, the next replan gives every goal a second chance
        self._idle(pose, stuck)

    def _idle(self, pose: np.ndarray, stuck: bool) -> None:
        """No goal to go to: look around on the spot (the map grows, the next replan may find goals). When
        goals exist but every one failed from here (`stuck`), first escape toward the clearest heading: from
        the same spot the same goals would fail again."""
        if stuck:
            self.queue.extend(self._escape_actions(pose))
        self.queue.extend(["turn_left"] * 6)

    def _closer_on_the_way(self, here: np.ndarray, goal: np.ndarray, path: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
        """The release's long-path rule: a goal more than `long_path_m` away is kept only if no closer,
        lower-scoring but still worthwhile node (scored above the local threshold, unvisited, not failed)
        lies on the way (within `on_the_way_m` of the path); otherwise the best such node is the goal."""
        plan, cfg = self.plan, self.cfg
        graph = plan.graph
        best, best_score = None, -np.inf
        for node, score in plan.scores.items():
            if plan.info.get(node, 0.0) <= cfg.local_score_threshold or score <= best_score:
                continue
            pos = np.asarray(graph.nodes[node]["pos"], float)
            unvisited, failed = self._node_state(pos)
            if not unvisited or failed or np.hypot(*(pos - goal)) < 1e-6:
                continue
            if _distance_to_polyline(pos, path) <= cfg.on_the_way_m:
                best, best_score = pos, score
        if best is None:
            return goal, path
        closer = self.timers.time("planner", plan_safe_path, graph, plan.workspace, here, best, cfg.workspace)
        if closer is None or path_length(closer) >= path_length(path):
            return goal, path
        return best, closer

    def _node_state(self, node_pos: np.ndarray) -> tuple[bool, bool]:
        r = self.cfg.planning.score.unvisited_radius_m
        unvisited = not any(np.hypot(*(node_pos - p)) <= r for p in self.visited[-2000:])
        failed = any(np.hypot(*(node_pos - p)) <= r for p in self.failed)
        return unvisited, failed

    def _rank_goals(self, here: np.ndarray) -> list[int]:
        """Candidate goal nodes, best first (eq. 12 scores; local-then-global, sec. III-C)."""
        plan, cfg = self.plan, self.cfg
        graph, ws = plan.graph, plan.workspace
        nodes = [n for n, d in graph.nodes(data=True) if d.get("view") or graph.degree[n] <= 1]
        if not nodes:
            nodes = list(graph.nodes)
        if not nodes:
            return []
        pos = np.stack([np.asarray(graph.nodes[n]["pos"], float) for n in nodes])
        state = [self._node_state(p) for p in pos]
        unvisited = np.array([s[0] for s in state])
        failed = np.array([s[1] for s in state])
        dist = np.hypot(*(pos - here).T)
        if cfg.random_goals:
            order = self.rng.permutation(len(nodes))
            return [nodes[i] for i in order if unvisited[i] and not failed[i]] + \
                   [nodes[i] for i in order if not (unvisited[i] and not failed[i])]
        inv = np.zeros(len(nodes))
        vol = np.zeros(len(nodes))
        pcfg = cfg.planning
        cand = self._panorama_candidates(nodes, dist, unvisited & ~failed)
        height = self.floor_height + cfg.panorama_height_m
        for i in cand:
            pano = render_panorama(self.world.render, [pos[i][0], height, pos[i][1]], pcfg.panorama)
            inv[i] = invisible_share(pano, pcfg.rotation)
            vol[i] = hull_volume(pano, pcfg.hull)
        in_horizon = np.array([line_of_sight(ws, here, p, cfg.workspace) for p in pos])
        scores = node_scores(inv, vol, unvisited, in_horizon, failed, pcfg.score)
        plan.scores = {n: float(s) for n, s in zip(nodes, scores, strict=True)}
        travel = _travel_lengths(graph, ws, here, nodes, pos, cfg.workspace)
        order = sorted(range(len(nodes)), key=lambda i: (-scores[i], travel[i]))
        # the information terms (w_o s_o + w_c s_c, shares relative to the best node anywhere): what keeps
        # planning local, and what makes a node worth a stop on a long path's way
        info = information_scores(inv, vol, pcfg.score)
        plan.info = {n: float(v) for n, v in zip(nodes, info, strict=True)}
        if cfg.hierarchical and plan.subregions:
            local = agent_subregion(graph, plan.subregions, here)
            # stay local while a node of this subregion promises something to see; the unvisited /
            # in-horizon flags alone do not keep the agent in a room it has seen
            local_best = [i for i in order if plan.subregions.get(nodes[i]) == local and unvisited[i]
                          and not failed[i] and info[i] > cfg.local_score_threshold]
            if local_best:
                rest = [i for i in order if i not in local_best]
                return [nodes[i] for i in local_best + rest]
            global_score = scores - cfg.global_distance_weight * travel
            order = sorted(range(len(nodes)), key=lambda i: (-global_score[i], travel[i]))
        return [nodes[i] for i in order]

    def _panorama_candidates(self, nodes: list[int], dist: np.ndarray, open_: np.ndarray) -> list[int]:
        """Indices of the nodes scored by panorama (at most `max_panoramas`): the nearest open node of every
        subregion first, so that rooms farther away are weighed too, then the nearest open nodes."""
        order = [int(i) for i in np.argsort(dist, kind="stable") if open_[i]]
        chosen: list[int] = []
        seen: set[int] = set()
        for i in order:
            region = self.plan.subregions.get(nodes[i])
            if region is not None and region not in seen:
                seen.add(region)
                chosen.append(i)
        chosen = chosen[: self.cfg.max_panoramas]
        taken = set(chosen)
        chosen += [i for i in order if i not in taken][: self.cfg.max_panoramas - len(chosen)]
        return chosen

    # ------------------------------------------------------------------ failures
    def _path_ahead_clear(self, pose: np.ndarray) -> bool:
        """Re-check the next `lookahead_m` of the path (release) on the current workspace: blocked when it
        gets narrower than the agent and narrower than where the agent already stands (the polished
        workspace can be thinner than the agent in a doorway it stands in; a path out of there is fine),
        give or take `ahead_tolerance_m`, and always when it leaves the workspace."""
        ws = self.plan.workspace
        if ws is None or ws.empty or self.follower is None or self.follower.done:
            return True
        here = floor_xz(pose)
        target = self.follower.waypoints[0]
        d = target - here
        n = float(np.hypot(*d))
        ahead = here + d * min(1.0, self.cfg.lookahead_m / max(n, 1e-9))
        need = max(self._needed_clearance(here) - self.cfg.ahead_tolerance_m, 1e-6)
        return bool(ws.segments_clearance(here[None], ahead[None])[0] >= need)

    def _needed_clearance(self, here: np.ndarray) -> float:
        """Clearance a path from `here` must keep: the agent's radius, or less where the agent already
        stands closer to the workspace border (shared by the path-ahead check and FBE's route search)."""
        return min(self.cfg.workspace.agent_radius, float(self.plan.workspace.clearance_at(here)) - 1e-6)

    def _fail_goal(self) -> None:
        if self.plan.goal is not None:
            self.failed.append(self.plan.goal)
        self.follower = None

    def _on_collision(self, pose: np.ndarray) -> None:
        """A refused forward move: mark the goal failed and escape toward the clearest heading."""
        self._fail_goal()
        self.rotation_targets = []
        self.queue = self._escape_actions(pose)

    def _escape_actions(self, pose: np.ndarray) -> list[str]:
        ctrl = self.cfg.controller
        yaw, _ = pose_yaw_pitch(pose)
        ws = self.plan.workspace
        here = floor_xz(pose)
        best_turns, best_clear = 18, -1.0
        for k in range(1, 36):
            turns = k if k <= 18 else k - 36  # positive: left
            if ws is None or ws.empty:
                best_turns = 9
                break
            h = yaw + math.radians(ctrl.turn_deg * turns)
            ahead = here + 0.3 * np.array([math.sin(h), math.cos(h)])
            clear = float(ws.segments_clearance(here[None], ahead[None])[0])
            if clear > best_clear + 1e-6:
                best_turns, best_clear = turns, clear
        turn = ["turn_left" if best_turns > 0 else "turn_right"] * abs(best_turns)
        return turn + ["move_forward"] * self.cfg.escape_forward_steps


def _distance_to_polyline(p: np.ndarray, path: np.ndarray) -> float:
    """Shortest distance from the point p (2,) to the polyline path (M,2)."""
    if len(path) == 1:
        return float(np.hypot(*(p - path[0])))
    a, b = path[:-1], path[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    return float(np.min(np.hypot(*(a + t[:, None] * ab - p).T)))


def _travel_lengths(graph: nx.Graph, ws: Workspace, here: np.ndarray, nodes: list[int], pos: np.ndarray,
                    wcfg: WorkspaceConfig) -> np.ndarray:
    """Approximate travel length to each node: from the graph node nearest the agent along the graph (plus
    the straight hop to it); Euclidean where the graph gives no path."""
    if graph.number_of_nodes() == 0:
        return np.hypot(*(pos - here).T)
    all_pos = np.stack([np.asarray(graph.nodes[n]["pos"], float) for n in graph.nodes])
    keys = list(graph.nodes)
    start = keys[int(np.argmin(np.hypot(*(all_pos - here).T)))]
    hop = float(np.hypot(*(np.asarray(graph.nodes[start]["pos"]) - here)))
    lengths = nx.single_source_dijkstra_path_length(graph, start, weight="weight")
    out = np.array([hop + lengths.get(n, np.inf) for n in nodes])
    eu = np.hypot(*(pos - here).T)
    return np.where(np.isfinite(out), out, eu * 3.0)


__all__ = ["ActiveSplatExplorer", "ExplorerConfig", "ExplorerView", "Plan", "Timers", "WorldModel",
           "build_plan"]
