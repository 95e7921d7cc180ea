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
from activesplat.planning.controller import floor_xz, yaw_toward
from activesplat.planning.explorer import Explorer, WorldModel, snapshot_render
from activesplat.planning.explorer_config import ExplorerConfig
from activesplat.planning.goals import (
    GoalRules,
    bridge_toward,
    closer_on_the_way,
    last_call_first,
    rank_goals,
    reachable_first,
    select_rotation_targets,
    worth_a_detour,
    worth_a_visit,
)
from activesplat.planning.observed import unsampled_views
from activesplat.planning.panorama import render_panorama
from activesplat.planning.replan_memory import Commitment, Promises, RouteMemory
from activesplat.planning.travel import graph_travel
from activesplat.planning.viewpoints import RotationTarget, rotation_candidates
from activesplat.timing import Timers
from activesplat.workspace.paths import path_length, plan_safe_path
from activesplat.workspace.plan import Plan, build_plan, grown_plan


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
        self.promises = None if self.cfg.keep_promise_m is None else Promises(self.cfg.keep_promise_m)
        """What the nodes outside the agent's subregion promised at earlier replans (`keep_promise_m`)."""
        self.commitment = None if self.cfg.commit_global_m is None else Commitment(self.cfg.commit_global_m)
        """The goal of the last global choice, followed until reached or seen (`commit_global_m`)."""
        self.route_memory = (None if self.cfg.route_memory_m is None
                             else RouteMemory(self.cfg.route_memory_m, self.cfg.route_min_info))
        """The order of the last global route through the subregions (`route_memory_m`)."""
        self.cut_off: list[np.ndarray] = []
        """Goals worth a visit that a replan skipped for want of a path, not looked at yet
        (`cut_off_look_m`)."""
        self.looked: list[np.ndarray] = []  # the cut-off goals looked at
        self._put_off: np.ndarray | None = None  # the ranked goal the last replan put off (postpone_once_m)
        self._ranked: list = []  # the best candidates of the current replan, for its record
        self.replans: list[dict] = []
        """Every replan: step, floor position, stage (local / global, `Plan.stage`), the goal (None: idle),
        its eq. 12 score and information part, the path length, and how many candidates promised something
        to see (the episode's stops.json, under "replans")."""

    def replan(self, pose: np.ndarray) -> None:
        """Rebuild the workspace and graph, rank the nodes, go to the best one with a safe path."""
        cfg = self.cfg
        here = floor_xz(pose)
        plan = self.plan = build_plan(self.world.gaussians, self.floor_height, here, cfg.workspace,
                                      self.timers, **self.workspace_obstacles())
        rules = goal_rules(cfg)
        if cfg.flat_until_step is not None and len(self.visited) < cfg.flat_until_step:
            rules = dataclasses.replace(rules, hierarchical=False)
        grown: Plan | None = None  # the floor grown into unknown, built when a node first has no path

        def grown_floor(timers: Timers = self.timers) -> Plan:
            nonlocal grown
            if grown is None:
                grown = grown_plan(plan, here, cfg.workspace, cfg.neck_margin_m, timers)
            return grown

        def no_path_travel(pos: np.ndarray) -> np.ndarray:  # `neck_travel`; timed as position selection
            return graph_travel(grown_floor(Timers()).graph, here, pos)

        pano = cfg.planning.panorama  # scoring panoramas: a snapshot, coarser with score_lod_voxel_m
        render = snapshot_render(self.world, pano.score_lod_voxel_m, pano.score_lod_inflate)
        goal_order = self.timers.time("position_selection", rank_goals, plan, here, render, self.floor_height,
                                      self.visited, self.failed, cfg.planning, cfg.workspace, rules, self.rng,
                                      self.observed, self.promises, self.commitment, self.route_memory,
                                      no_path_travel if cfg.neck_travel else None)

        if cfg.last_call_steps is not None and self.steps_left is not None and plan.stage:
            goal_order = last_call_first(goal_order, plan, self.steps_left, self.visited, self.failed,
                                         cfg.planning.score.unvisited_radius_m, cfg.last_call_steps,
                                         cfg.last_call_min_info, cfg.last_call_steps_per_m)

        if cfg.out_of_reach_last and self.steps_left is not None and plan.stage:
            goal_order = reachable_first(goal_order, plan, self.steps_left, self.visited, self.failed,
                                         cfg.planning.score.unvisited_radius_m, cfg.last_call_steps_per_m,
                                         cfg.local_score_threshold)

        def find_path(goal: np.ndarray, on: Plan = plan) -> np.ndarray | None:
            return self.timers.time("planner", plan_safe_path, on.graph, on.workspace, here, goal,
                                    cfg.workspace)

        self._ranked = goal_order[:self.cfg.replan_log_top]
        skipped = False  # a goal with no path skipped for this replan (`retry_unreachable`)
        cut_off = False  # a goal worth a visit had no path (`leave_when_cut_off`)
        worth = worth_a_visit(np.array([plan.info.get(n, 0.0) for n in goal_order]), True,
                              cfg.local_score_threshold)
        last_worth = int(np.flatnonzero(worth)[-1]) if worth.any() else -1
        for k, node in enumerate(goal_order):
            goal = np.asarray(plan.graph.nodes[node]["pos"], float)
            if cfg.leave_when_cut_off and cut_off and k > last_worth:
                skipped = True  # every goal worth a visit is cut off; the rest promise nothing: leave
                break
            if np.hypot(*(goal - here)) <= cfg.controller.arrive_radius:
                # already there: arriving again would end in a replan at once, every step (a `hull-only`
                # agent spun on the spot for 200 steps that way, replanning four times per step)
                continue
            path = find_path(goal)
            if path is None and cfg.neck_margin_m is not None:
                path = find_path(goal, grown_floor())
                if path is not None:  # followed and checked ahead on the grown floor
                    self.go_to(goal, path)
                    self._commit(node)
                    self._record_replan(here, node, path, False, grown=True)
                    plan.workspace = grown_floor().workspace
                    return
            if path is None:
                self._remember_cut_off(plan, node, goal)
                bridge = self._bridge(plan, here, node, goal, find_path)
                if bridge is None:
                    cut_off = cut_off or bool(worth[k])
                    if cfg.retry_unreachable:
                        self._log_failure(goal, "no path, skipped")
                        skipped = True
                    else:
                        self._mark_failed(goal, "no path")
                    continue
                # not marked failed: from the bridge node it may have a path (each bridge is a node not yet
                # visited and nearer to the goal, so the bridges toward one goal end)
                self.go_to(*bridge)
                self._commit(node)
                self._record_replan(here, node, bridge[1], False, bridge=True)
                return
            on_the_way, ranked_pos = False, goal
            radius = cfg.planning.score.unvisited_radius_m
            straight = self._put_off_before(goal)  # put off once already: no stop on the way this time
            if not straight and cfg.detour_m is not None and plan.stage == "global":
                stop = worth_a_detour(plan, node, self.visited, self.failed, radius, cfg.detour_m,
                                      cfg.detour_min_info)
                stop_pos = None if stop is None else np.asarray(plan.graph.nodes[stop]["pos"], float)
                detour = None if stop_pos is None else find_path(stop_pos)
                if detour is not None:
                    goal, path, on_the_way = stop_pos, detour, True
            if not straight and path_length(path) > cfg.long_path_m:
                way_goal = goal
                goal, path = closer_on_the_way(plan, goal, path, self.visited, self.failed, radius, rules,
                                               find_path)
                on_the_way = on_the_way or goal is not way_goal
            self._put_off = ranked_pos if on_the_way else None
            self.go_to(goal, path)
            self._commit(node)
            self._record_replan(here, node, path, on_the_way, straight=straight)
            return
        self._record_replan(here, None, None, False)
        plan.goal, plan.path = None, None
        # goals exist but none has a path from here: escape first, as when they were all marked failed (with
        # skipped goals alone, turning on the spot would find the same graph at every replan)
        stuck = bool(self.failed) or skipped
        self.forget_failures()  # fallback: the next replan gives every goal a second chance
        self.idle(pose, stuck)

    def _put_off_before(self, goal: np.ndarray) -> bool:
        """Whether `goal` is the one the last replan put off for a stop on the way (`postpone_once_m`)."""
        limit = self.cfg.postpone_once_m
        return (limit is not None and self._put_off is not None
                and float(np.hypot(*(goal - self._put_off))) <= limit)

    def _commit(self, node: int) -> None:
        """Remember the goal of a global choice (`commit_global_m`): the ranked node, not a stop on the
        way or a bridge toward it."""
        if self.commitment is not None and self.plan.stage == "global":
            self.commitment.pos = np.asarray(self.plan.graph.nodes[node]["pos"], float).copy()

    def _remember_cut_off(self, plan: Plan, node: int, goal: np.ndarray) -> None:
        """Keep a goal with no path for a look when the agent passes it (`cut_off_look_m`): one worth a
        visit, not near a goal looked at already."""
        radius = self.cfg.cut_off_look_m
        if radius is None:
            return
        if not worth_a_visit(plan.info.get(node, 0.0), True, self.cfg.local_score_threshold):
            return
        if any(np.hypot(*(goal - g)) <= radius for g in self.looked):
            return
        if not any(np.hypot(*(goal - g)) < 1e-6 for g in self.cut_off):
            self.cut_off.append(goal.copy())

    def _look_at_cut_off(self, pose: np.ndarray) -> bool:
        """Passing within `cut_off_look_m` of a goal kept by :meth:`_remember_cut_off`: turn toward it with
        the camera one tilt down, then replan (the path is dropped). The goals within `cut_off_look_m` of it
        are dropped from the list, as looked at with it."""
        radius = self.cfg.cut_off_look_m
        if radius is None or not self.cut_off:
            return False
        here = floor_xz(pose)
        near = [g for g in self.cut_off if np.hypot(*(g - here)) <= radius]
        if not near:
            return False
        goal = min(near, key=lambda g: float(np.hypot(*(g - here))))
        self.looked.append(goal)
        self.cut_off = [g for g in self.cut_off if np.hypot(*(g - goal)) > radius]
        target = RotationTarget(yaw_toward(here, goal), -math.radians(self.cfg.controller.look_deg), 0.0,
                                "cut_off")
        self.rotation_targets = [target]
        self.rotation_cause = "look_cut_off"
        self.follower = None  # replan once the look is done: the goal may have a path now
        self.stops.append({"step": len(self.visited) - 1, "cause": self.rotation_cause,
                           "xz": [round(float(v), 3) for v in here], "candidates": {},
                           "toward": [round(float(v), 3) for v in goal],
                           "targets": [target_record(target)]})
        return True

    def _bridge(self, plan: Plan, here: np.ndarray, node: int, goal: np.ndarray,
                find_path) -> tuple[np.ndarray, np.ndarray] | None:
        """Where to go instead of a goal worth a visit that has no safe path (`bridge_gain_m`)."""
        cfg = self.cfg
        if cfg.bridge_gain_m is None:
            return None
        if not worth_a_visit(plan.info.get(node, 0.0), True, cfg.local_score_threshold):
            return None
        radius = cfg.planning.score.unvisited_radius_m
        return bridge_toward(plan, here, goal, self.visited, self.failed, radius, cfg.workspace,
                             cfg.bridge_gain_m, find_path)

    def _record_replan(self, here: np.ndarray, node: int | None, path: np.ndarray | None,
                       on_the_way: bool, bridge: bool = False, straight: bool = False, grown: bool = False
                       ) -> None:
        plan, thr = self.plan, self.cfg.local_score_threshold
        rec = {"step": len(self.visited) - 1, "xz": [round(float(v), 3) for v in here], "stage": plan.stage,
               "candidates": len(plan.scores), "promising": sum(v > thr for v in plan.info.values()),
               "max_invisible": round(plan.max_invisible, 4), "goal": None}
        if node is not None and path is not None:
            rec.update(goal=[round(float(v), 3) for v in self.plan.goal], on_the_way=on_the_way,
                       committed=plan.committed,
                       score=round(plan.scores.get(node, float("nan")), 2),
                       info=round(plan.info.get(node, float("nan")), 2), path_m=round(path_length(path), 2))
            if bridge:  # the goal ranked first had no safe path: `plan.goal` is a node on the way to it
                rec["bridge_to"] = [round(float(v), 3) for v in plan.graph.nodes[node]["pos"]]
            if straight:  # put off once for a stop on the way already (`postpone_once_m`): no stop now
                rec["put_off_before"] = True
            if grown:  # no path on the observed floor, one on the floor grown into unknown (`neck_margin_m`)
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
        """Passing a multi-connected node: a short rotation stop there (paper sec. III-D3); passing a goal
        that had no path: a look toward it (`cut_off_look_m`)."""
        if self._look_at_cut_off(pose):
            return True
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
        if self.sampled is not None:
            c, e = self.cfg.controller, self.cfg
            targets += unsampled_views(pano, self.sampled, e.unsampled_radius_m, e.unsampled_views,
                                       e.unsampled_min_weight, turn_deg=c.turn_deg, look_deg=c.look_deg,
                                       max_pitch_deg=c.max_pitch_deg)
        yaw, pitch = pose_yaw_pitch(pose)
        ctrl = self.cfg.controller if self.cfg.fewest_action_tour else None
        resume = None  # a stop on the way turns back toward the path afterwards: count those turns too
        if self.follower is not None and not self.follower.done:
            resume = yaw_toward(floor_xz(pose), self.follower.waypoints[0])
        sources = ("panorama", "high_loss", *(("unsampled",) if self.sampled is not None else ()))
        chosen = select_rotation_targets(targets, yaw, pcfg, max_views, pitch, ctrl, resume,
                                         self.cfg.tilt_within_deg)
        self.stops.append({
            "step": len(self.visited) - 1, "cause": self.rotation_cause,
            "xz": [round(float(v), 3) for v in floor_xz(pose)],
            "candidates": {src: sum(t.source == src for t in targets) for src in sources},
            "targets": [target_record(t) for t in chosen]})
        return chosen


def goal_rules(cfg: ExplorerConfig) -> GoalRules:
    """The goal-selection knobs of an explorer configuration."""
    return GoalRules(local_score_threshold=cfg.local_score_threshold,
                     global_distance_weight=cfg.global_distance_weight, max_panoramas=cfg.max_panoramas,
                     panorama_height_m=cfg.panorama_height_m, hierarchical=cfg.hierarchical,
                     random_goals=cfg.random_goals, long_path_m=cfg.long_path_m,
                     on_the_way_m=cfg.on_the_way_m, global_in_horizon=cfg.global_in_horizon,
                     local_in_horizon=cfg.local_in_horizon,
                     global_information_first=cfg.global_information_first,
                     panorama_every_subregion=cfg.panorama_every_subregion,
                     global_halving_m=cfg.global_halving_m, global_tour=cfg.global_tour,
                     local_near_m=cfg.local_near_m, route_in_place=cfg.route_in_place)


def target_record(t: RotationTarget) -> dict:
    """One rotation target of a stop for stops.json: source, yaw / pitch in degrees, weight."""
    return {"source": t.source, "yaw_deg": round(math.degrees(t.yaw), 1),
            "pitch_deg": round(math.degrees(t.pitch), 1), "weight": round(float(t.weight), 1)}


def ranked_entry(plan: Plan, node: int) -> dict:
    """One ranked candidate of a replan for stops.json: floor position, subregion, eq. 12 score, its
    information part (0 without a panorama), the graph travel to it and, with the sampled-surface term
    on, its poorly sampled share."""
    entry = {"xz": [round(float(v), 2) for v in plan.graph.nodes[node]["pos"]],
             "subregion": plan.subregions.get(node), "score": round(plan.scores.get(node, float("nan")), 2),
             "info": round(plan.info.get(node, float("nan")), 2),
             "travel_m": round(plan.travel.get(node, float("nan")), 2)}
    if node in plan.poor:  # the sampled-surface term is on
        entry["poor"] = round(plan.poor[node], 4)
    return entry


__all__ = ["ActiveSplatExplorer", "goal_rules"]

