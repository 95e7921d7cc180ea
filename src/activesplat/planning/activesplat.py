"""The ActiveSplat policy (paper sec. III-B, III-C, III-D) and its ablations, by configuration: Voronoi-node
goals ranked by eq. 12 scores from rendered panoramas (`planning.goals`), local-then-global over UPGMA
subregions, on-the-spot rotations toward panorama and high-loss targets on arrival, rotation stops at
multi-connected nodes. The shared behaviour (bootstrap, path following, escapes) is `planning.explorer`'s.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from activesplat.geometry import pose_yaw_pitch
from activesplat.planning.candidates import node_xz, worth_a_visit
from activesplat.planning.controller import floor_xz, yaw_toward
from activesplat.planning.explorer import Explorer, WorldModel, snapshot_render
from activesplat.planning.explorer_config import ExplorerConfig, GoalRules
from activesplat.planning.goals import rank_goals
from activesplat.planning.on_the_way import closer_on_the_way, worth_a_detour
from activesplat.planning.panorama import render_panorama
from activesplat.planning.viewpoints import RotationTarget, rotation_candidates, select_rotation_targets
from activesplat.timing import Timers
from activesplat.workspace.paths import path_length, plan_safe_path
from activesplat.workspace.plan import Plan, build_plan, grown_plan


@dataclasses.dataclass
class _Choice:
    """Where a replan sends the agent: the ranked `node` it chose, and the `goal` and `path` followed
    there, the node's own or another node's on the way to it."""

    node: int
    goal: np.ndarray
    path: np.ndarray
    grown: bool = False
    """The path lies on the floor grown into unknown (`neck_margin_m`), not on the observed floor."""
    on_the_way: bool = False
    """`goal` is a stop on the way to the node (`detour_m`, the release's long-path rule)."""


class _Floors:
    """Safe paths from the agent for one replan (sec. III-D3: Dijkstra on the Voronoi graph, `plan_safe_path`,
    timed as planner): on the observed floor of `plan`, or on the floor grown into unknown through narrow
    necks (ours, `neck_margin_m`; docs/protocol.md §3), built the first time it is asked for."""

    def __init__(self, plan: Plan, here: np.ndarray, cfg: ExplorerConfig, timers: Timers):
        self.plan, self.here, self.cfg, self.timers = plan, here, cfg, timers
        self._grown: Plan | None = None

    def grown(self) -> Plan:
        """The floor grown into unknown."""
        if self._grown is None:
            self._grown = grown_plan(self.plan, self.here, self.cfg.workspace, self.cfg.neck_margin_m,
                                     self.timers)
        return self._grown

    def path(self, goal: np.ndarray, on: Plan | None = None) -> np.ndarray | None:
        """A safe path to `goal` on the observed floor, or `on` another plan; None where there is none."""
        on = self.plan if on is None else on
        return self.timers.time("planner", plan_safe_path, on.graph, on.workspace, self.here, goal,
                                self.cfg.workspace)


class ActiveSplatExplorer(Explorer):
    """The full method and its ablations (by configuration): Voronoi-node goals ranked by eq. 12 scores from
    rendered panoramas, local-then-global over UPGMA subregions (sec. III-C), on-the-spot rotations toward
    panorama and high-loss targets on arrival (sec. III-B3), rotation stops at multi-connected nodes."""

    name = "activesplat"

    def __init__(self, world: WorldModel, floor_height: float, cfg: ExplorerConfig | None = None,
                 timers: Timers | None = None):
        super().__init__(world, floor_height, cfg, timers)
        self.rotated_at: list[np.ndarray] = []
        self.stopped_multi: list[np.ndarray] = []
        self.stops: list[dict] = []
        """Every rotation stop: step, cause (arrival / multi_stop), floor position, the targets chosen
        (source, yaw / pitch in degrees, weight) and how many candidates each source offered (the
        episode's stops.json)."""
        self._ranked: list = []  # the best candidates of the current replan, for its record
        self.replans: list[dict] = []
        """Every replan: step, floor position, stage (local / global, `Plan.stage`), the goal (None: idle),
        its eq. 12 score and information part, the path length, and how many candidates promised something
        to see (the episode's stops.json, under "replans")."""

    def replan(self, pose: np.ndarray) -> None:
        """Rebuild the workspace and graph, rank the nodes, go to the best one with a safe path:

        1. the workspace and its Voronoi graph from the map (sec. III-A), cut into UPGMA subregions (sec.
           III-C1; `build_plan`);
        2. the candidate nodes best first (`_rank_goals`): eq. 12 scores from panoramas rendered at them
           (sec. III-B2, III-D3), the agent's own subregion first, then the others (sec. III-C2);
        3. the best of them the agent can set out for on a safe path (sec. III-D3; `_first_reachable`),
           and on the way to one far away a stop at a node worth a visit (`_with_a_stop_on_the_way`);
        4. none: look around on the spot (`_no_goal`).

        The rotations toward the panorama and high-loss targets (sec. III-B3) come on arrival (`arrive`).
        Where this project departs from the paper and the release: docs/protocol.md §4, §5, and the
        measurements behind each option in docs/exploration.md and docs/benchmark.md."""
        here = floor_xz(pose)
        plan = self.plan = build_plan(self.world.gaussians, self.floor_height, here, self.cfg.workspace,
                                      self.timers)
        floors = _Floors(plan, here, self.cfg, self.timers)
        rules = goal_rules(self.cfg)
        order = self._rank_goals(plan, here, rules)
        self._ranked = order[:self.cfg.replan_log_top]
        choice, skipped = self._first_reachable(plan, here, order, floors)
        if choice is None:
            self._no_goal(pose, here, skipped)
            return
        if not choice.grown:
            choice = self._with_a_stop_on_the_way(plan, choice, rules, floors)
        self.go_to(choice.goal, choice.path)
        self._record_replan(here, choice)
        if choice.grown:  # followed and checked ahead on the grown floor
            plan.workspace = floors.grown().workspace

    def _rank_goals(self, plan: Plan, here: np.ndarray, rules: GoalRules) -> list[int]:
        """Step 2 of `replan`: the candidate nodes best first (`planning.goals.rank_goals`, timed as position
        selection), scored on panoramas of a coarser snapshot of the map (ours, `score_lod_voxel_m`;
        docs/protocol.md §4)."""
        cfg = self.cfg
        pano = cfg.planning.panorama
        render = snapshot_render(self.world, pano.score_lod_voxel_m, pano.score_lod_inflate)
        return self.timers.time("position_selection", rank_goals, plan, here, render, self.floor_height,
                                self.visited, self.failed, cfg.planning, cfg.workspace, rules, self.rng)

    def _first_reachable(self, plan: Plan, here: np.ndarray, order: list[int],
                         floors: _Floors) -> tuple[_Choice | None, bool]:
        """Step 3 of `replan`: the first goal of `order` with a safe path from the agent (sec. III-D3), and
        whether a goal with no path was skipped for this replan. A goal within the arrival radius is passed
        over: arriving again would end in a replan at once, every step (a `hull-only` agent spun on the
        spot for 200 steps that way, replanning four times per step).

        A goal with no path on the observed floor (this project's handling; docs/protocol.md §3, §5):
        a path on the floor grown into unknown (`neck_margin_m`, on), else it is skipped for this replan
        (`retry_unreachable`, on; the release marks it failed). Once every goal worth a visit is cut off
        so, the rest, which promise nothing, are left too (`leave_when_cut_off`, on): no goal, counted as
        skipped."""
        cfg = self.cfg
        info = np.array([plan.info.get(n, 0.0) for n in order])
        worth = worth_a_visit(info, True, cfg.local_score_threshold)
        last_worth = int(np.flatnonzero(worth)[-1]) if worth.any() else -1
        skipped = cut_off = False
        for k, node in enumerate(order):
            if cfg.leave_when_cut_off and cut_off and k > last_worth:
                return None, True  # every goal worth a visit is cut off; the rest promise nothing: leave
            goal = node_xz(plan.graph, node)
            if np.hypot(*(goal - here)) <= cfg.controller.arrive_radius:
                continue
            path = floors.path(goal)
            if path is not None:
                return _Choice(node, goal, path), skipped
            if cfg.neck_margin_m is not None:
                path = floors.path(goal, floors.grown())
                if path is not None:
                    return _Choice(node, goal, path, grown=True), skipped
            cut_off = cut_off or bool(worth[k])
            if cfg.retry_unreachable:
                self._log_failure(goal, "no path, skipped")
                skipped = True
            else:
                self._mark_failed(goal, "no path")
        return None, skipped

    def _with_a_stop_on_the_way(self, plan: Plan, choice: _Choice, rules: GoalRules,
                                floors: _Floors) -> _Choice:
        """Step 3 of `replan`, for a goal with a path on the observed floor: go there, or first to a node
        worth a visit on the way (docs/protocol.md §5): a room passed on the way to a global goal (ours,
        `detour_m`, on; `worth_a_detour`), and the release's long-path rule for a path longer than
        `long_path_m` (`closer_on_the_way`)."""
        cfg = self.cfg
        radius = cfg.planning.score.unvisited_radius_m
        goal, path, on_the_way = choice.goal, choice.path, False
        if cfg.detour_m is not None and plan.stage == "global":
            stop = worth_a_detour(plan, choice.node, self.visited, self.failed, radius, cfg.detour_m,
                                  cfg.detour_min_info)
            stop_pos = None if stop is None else node_xz(plan.graph, stop)
            detour = None if stop_pos is None else floors.path(stop_pos)
            if detour is not None:
                goal, path, on_the_way = stop_pos, detour, True
        if path_length(path) > cfg.long_path_m:
            way_goal = goal
            goal, path = closer_on_the_way(plan, goal, path, self.visited, self.failed, radius, rules,
                                           floors.path)
            on_the_way = on_the_way or goal is not way_goal
        return dataclasses.replace(choice, goal=goal, path=path, on_the_way=on_the_way)

    def _no_goal(self, pose: np.ndarray, here: np.ndarray, skipped: bool) -> None:
        """Step 4 of `replan`: no goal with a path. The release's fallback: forget the failed goals (the next
        replan gives every goal a second chance) and look around on the spot. Where goals exist but none
        has a path from here, escape first, as when they were all marked failed: with skipped goals alone,
        turning on the spot would find the same graph at every replan."""
        self._record_replan(here, None)
        self.plan.goal, self.plan.path = None, None
        stuck = bool(self.failed) or skipped
        self.forget_failures()
        self.idle(pose, stuck)

    def _record_replan(self, here: np.ndarray, choice: _Choice | None) -> None:
        plan, thr = self.plan, self.cfg.local_score_threshold
        rec = {"step": len(self.visited) - 1, "xz": rounded(here), "stage": plan.stage,
               "candidates": len(plan.scores), "promising": sum(v > thr for v in plan.info.values()),
               "max_invisible": round(plan.max_invisible, 4), "goal": None}
        if choice is not None:
            node = choice.node
            rec.update(goal=rounded(plan.goal), on_the_way=choice.on_the_way,
                       score=round(plan.scores.get(node, float("nan")), 2),
                       info=round(plan.info.get(node, float("nan")), 2),
                       path_m=round(path_length(choice.path), 2))
            if choice.grown:  # no path on the observed floor, one on the floor grown into unknown
                rec["grown"] = True
        rec["ranked"] = [ranked_entry(plan, n) for n in self._ranked]
        self.replans.append(rec)

    def arrive(self, pose: np.ndarray, max_views: int | None = None, cause: str = "arrival") -> None:
        """On-the-spot rotations toward the panorama and high-loss targets (sec. III-B3), at most
        `max_views` (default `max_rotation_views`); `cause` names them in `last_cause`."""
        if not self.cfg.rotations:
            return
        here = floor_xz(pose)
        skip = self.cfg.rotation_skip_radii * self.cfg.workspace.agent_radius
        if cause == "multi_stop" and self.cfg.multi_stop_spacing_m > 0:
            skip = self.cfg.multi_stop_spacing_m
            start = self.visited[:1] if self.cfg.bootstrap_yaw_deg > 0 else []  # the look-around turned there
            spots = self.rotated_at + start
        else:
            spots = self.rotated_at
        if any(np.hypot(*(here - p)) < skip for p in spots):
            return
        self.rotated_at.append(here)
        self.rotation_cause = cause
        views = self.cfg.max_rotation_views if max_views is None else max_views
        self.rotation_targets = self.timers.time("rotation_selection", self._rotation_targets, pose, views)

    def stop_on_the_way(self, pose: np.ndarray) -> bool:
        """Passing a multi-connected node: a short rotation stop there (paper sec. III-D3)."""
        if not self.cfg.multi_stops:
            return False
        here = floor_xz(pose)
        for _, data in self.plan.graph.nodes(data=True):
            if not data.get("multi"):
                continue
            pos = np.asarray(data["pos"])
            if np.hypot(*(pos - here)) > self.cfg.multi_node_radius_m:
                continue
            if any(np.hypot(*(pos - p)) < self.cfg.multi_node_radius_m for p in self.stopped_multi):
                continue
            self.stopped_multi.append(pos)
            self.arrive(pose, self.cfg.multi_stop_views, cause="multi_stop")
            return bool(self.rotation_targets)
        return False

    def _rotation_targets(self, pose: np.ndarray, max_views: int) -> list[RotationTarget]:
        pcfg = self.cfg.planning
        origin = pose[:3, 3]
        pano = self.last_panorama = render_panorama(self.world.render, origin, pcfg.panorama,
                                                    pcfg.panorama.front_faces_targets)
        targets = rotation_candidates(pano, pcfg.rotation) + self.high_loss.targets(origin, max_distance=4.0)
        yaw, pitch = pose_yaw_pitch(pose)
        ctrl = self.cfg.controller if self.cfg.fewest_action_tour else None
        resume = None  # a stop on the way turns back toward the path afterwards: count those turns too
        if self.follower is not None and not self.follower.done:
            resume = yaw_toward(floor_xz(pose), self.follower.waypoints[0])
        sources = ("panorama", "high_loss")
        chosen = select_rotation_targets(targets, yaw, pcfg, max_views, pitch, ctrl, resume)
        self.stops.append({
            "step": len(self.visited) - 1, "cause": self.rotation_cause,
            "xz": rounded(floor_xz(pose)),
            "candidates": {src: sum(t.source == src for t in targets) for src in sources},
            "targets": [target_record(t) for t in chosen]})
        return chosen


def goal_rules(cfg: ExplorerConfig) -> GoalRules:
    """The goal-selection knobs of an explorer configuration (its fields of the same names)."""
    return GoalRules(**{f.name: getattr(cfg, f.name) for f in dataclasses.fields(GoalRules)})


def rounded(xz, digits: int = 3) -> list[float]:
    """A floor position (or any vector) for stops.json, rounded to `digits`."""
    return [round(float(v), digits) for v in xz]


def target_record(t: RotationTarget) -> dict:
    """One rotation target of a stop for stops.json: source, yaw / pitch in degrees, weight."""
    return {"source": t.source, "yaw_deg": round(math.degrees(t.yaw), 1),
            "pitch_deg": round(math.degrees(t.pitch), 1), "weight": round(float(t.weight), 1)}


def ranked_entry(plan: Plan, node: int) -> dict:
    """One ranked candidate of a replan for stops.json: floor position, subregion, eq. 12 score, its
    information part (0 without a panorama) and the graph travel to it."""
    return {"xz": rounded(plan.graph.nodes[node]["pos"], 2),
            "subregion": plan.subregions.get(node), "score": round(plan.scores.get(node, float("nan")), 2),
            "info": round(plan.info.get(node, float("nan")), 2),
            "travel_m": round(plan.travel.get(node, float("nan")), 2)}


__all__ = ["ActiveSplatExplorer", "goal_rules"]

