"""How much of the sweep ceiling can a route that knows the house see within the step budget? A route
planned over the ground truth, walked in the simulator and counted like an episode.

    python benchmarks/greedy_oracle.py --scenes medium-100 --seeds 0 --ceilings ROOT --first-budget 1000

It is the explorer's budget question with the exploring taken out. The route knows, for each view of the
exhaustive sweep (``eval/sweep.py``: a 0.5 m grid of standing spots, 12 yaws x 3 pitches each), which
ground-truth points that view completes (within 5 cm, docs/protocol.md §6). It chooses spots by set
cover: the spot whose worthwhile views (each completing at least ``--min-gain`` points not completed yet)
complete the most per action of their looks, again and again, while the estimated cost of the shortest
open route through the chosen spots (forward steps, 6 turns per leg, the looks) fits the budget. It
walks that route in the simulator (a path follower on the navigability map, collisions refused as in an
episode) and at each spot turns and tilts to the views still worth it, in the cheapest of a few orders.
With ``--first-budget N`` the first tour is planned to fit N actions and a second one the rest; what is
left after the tours goes to greedy choices (``--greedy``: greedy choices only, the walk in the cost).
Every action's frame is counted with the episodes' coverage protocol, so the walk's own frames count too.

A set cover and a shortest route are a plain plan, so this is not an upper bound; it says what knowing
the house buys with the episode's actions. The per-view sets are cached (``--cache``, one ``.npz`` per
house, a few minutes to build each).

Columns: share of the sweep ceiling at each of ``--at`` steps and at the end, rotations (turns and tilts)
as a share of the actions, the walk in metres, the number of stops, and the worst room: the lowest share
of a room's own sweep ceiling at the end, as the benchmark ranks rooms (``relative_to_ceiling``).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from activesplat.eval.behaviour import relative_to_ceiling, room_behaviour
from activesplat.eval.coverage import CoverageAccumulator, CoverageConfig, _tree
from activesplat.eval.sweep import SweepConfig, sweep_poses
from activesplat.geometry import backproject, intrinsics, pose_yaw_pitch
from activesplat.planning.controller import (
    ControllerConfig,
    PathFollower,
    fewest_actions_order,
    tilt_toward,
    tour_actions,
    turn_toward,
)
from activesplat.planning.travel import shortest_tour
from activesplat.sim import SimConfig, Simulator, load_scene
from activesplat.sim.navmap import grid_graph


def view_sets(scene, sim: SimConfig, sweep: SweepConfig, cov: CoverageConfig, gt: np.ndarray,
              cache: Path | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sweep's camera poses (V, 4, 4) and, per view, the ground-truth points it completes, as CSR
    (indptr (V + 1,), indices): a point is completed by a view when one of the view's back-projected
    depth points lies within the threshold, exactly as the coverage protocol counts it. `cache`: an .npz
    file read when it holds the same scene and settings, else written."""
    poses = sweep_poses(scene, sim, sweep)
    settings = {"scene": scene.name, "sweep": asdict(sweep), "coverage": asdict(cov), "sim": asdict(sim)}
    key = json.dumps(settings, sort_keys=True, default=str)
    if cache is not None and cache.is_file():
        data = np.load(cache)
        if "key" in data.files and str(data["key"]) == key and len(data["indptr"]) == len(poses) + 1:
            return poses, data["indptr"], data["indices"]
    sensor = scene.sensor_for(sim)
    K = intrinsics(cov.resolution, cov.resolution, sim.hfov_deg)
    thr = cov.threshold_m
    parts, counts = [], []
    for pose in poses:
        pts = backproject(sensor.depth(pose, K, cov.resolution, cov.resolution), pose, K)
        hit = np.zeros(0, np.int32)
        if len(pts):
            lo, hi = pts.min(axis=0) - thr, pts.max(axis=0) + thr
            near = np.flatnonzero(np.all((gt >= lo) & (gt <= hi), axis=1))
            if len(near):
                dist, _ = _tree(pts).query(gt[near], k=1, distance_upper_bound=thr)
                hit = near[dist < thr].astype(np.int32)
        parts.append(hit)
        counts.append(len(hit))
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    indices = np.concatenate(parts) if parts else np.zeros(0, np.int32)
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        np.savez(cache, indptr=indptr, indices=indices, key=np.array(key))
    return poses, indptr, indices


def rotation_plan(yaw: float, pitch: float, targets: list[tuple[float, float]], ctl: ControllerConfig
                  ) -> list[tuple[float, float]]:
    """The order of (yaw, pitch) `targets` with the fewest actions among: every order (up to 5 targets),
    one sweep through the yaws per pitch row, and one sweep through the yaws visiting every pitch of a yaw
    before the next; each sweep in either direction, from either end of the widest gap between the yaws or
    from the yaw nearest the heading, whichever costs least (`tour_actions`)."""
    if len(targets) <= 5:
        order = fewest_actions_order(yaw, pitch, targets, ctl)
        return [targets[i] for i in order]
    candidates = []
    yaws = sorted({round(math.degrees(t[0]) % 360.0, 3) for t in targets})
    # start at either end of the largest gap between the yaws, or at the yaw nearest the heading
    gaps = [(yaws[(k + 1) % len(yaws)] - yaws[k]) % 360.0 for k in range(len(yaws))]
    widest = int(np.argmax(gaps))
    here = math.degrees(yaw) % 360.0
    nearest = int(np.argmin([min(abs(y - here), 360.0 - abs(y - here)) for y in yaws]))
    for start in {(widest + 1) % len(yaws), widest, nearest}:
        for sign in (1, -1):
            ring = [yaws[(start + sign * k) % len(yaws)] for k in range(len(yaws))]
            rank = {y: k for k, y in enumerate(ring)}

            def key(t, rank=rank):
                return rank[round(math.degrees(t[0]) % 360.0, 3)]

            candidates.append(sorted(targets, key=lambda t, key=key: (key(t), t[1])))
            rows = sorted({t[1] for t in targets}, key=lambda p: abs(p - pitch))
            snake = []
            for i, row in enumerate(rows):
                cells = sorted((t for t in targets if t[1] == row), key=key)
                snake += cells if i % 2 == 0 else cells[::-1]
            candidates.append(snake)
    return min(candidates, key=lambda c: tour_actions(yaw, pitch, c, ctl))


class OracleRoute:
    """The route of one episode start: the simulator, the coverage of its frames and the actions."""

    def __init__(self, scene, seed: int, sim: SimConfig, cov: CoverageConfig, gt: np.ndarray,
                 poses: np.ndarray, indptr: np.ndarray, indices: np.ndarray, views_per_spot: int,
                 min_gain: int, shortlist: int = 20):
        self.sim = Simulator(scene, seed=seed, config=sim)
        self.sim.reset()
        self.nav = self.sim.navmap
        self.graph, self.cells = grid_graph(self.nav.largest, self.nav.resolution)
        # paths keep off the walls: an edge costs up to 4x its length where the clearance is low
        clear = self.nav.clearance[self.cells[:, 0], self.cells[:, 1]]
        factor = 1.0 + 3.0 * np.clip((0.35 - clear) / 0.2, 0.0, 1.0)
        coo = self.graph.tocoo()
        weight = coo.data * 0.5 * (factor[coo.row] + factor[coo.col])
        self.walk_graph = coo_matrix((weight, (coo.row, coo.col)), shape=coo.shape).tocsr()
        self.node_of = -np.ones(self.nav.largest.shape, np.int64)
        self.node_of[self.cells[:, 0], self.cells[:, 1]] = np.arange(len(self.cells))
        self.ctl = ControllerConfig(turn_deg=sim.turn_deg, look_deg=sim.look_deg, forward_m=sim.forward_step)
        self.K = intrinsics(cov.resolution, cov.resolution, sim.hfov_deg)
        self.res = cov.resolution
        self.cov = CoverageAccumulator(gt, cov)
        self.poses, self.indptr, self.indices = poses, indptr, indices
        self.per = views_per_spot
        self.spots = poses[::views_per_spot, :3, 3][:, [0, 2]]
        cells = np.stack(self.nav.cell_of(self.spots[:, 0], self.spots[:, 1]), axis=1)
        self.spot_nodes = self.node_of[cells[:, 0], cells[:, 1]]
        """Per spot, the graph node of its cell (sweep spots stand on the largest navigable component)."""
        self.view_angles = [pose_yaw_pitch(p) for p in poses]
        self.owner = np.repeat(np.arange(len(poses)), np.diff(indptr))
        self.min_gain, self.shortlist = min_gain, shortlist
        self.actions: list[str] = []
        self._look_cost: dict[tuple[int, ...], int] = {}
        self.failed: set[int] = set()
        """Spots the last walks could not reach: not chosen again until the agent arrives somewhere."""
        self._frame()

    def _node(self, xz: np.ndarray) -> int:
        """The graph node of the navigable cell under (x, z), or of the nearest one."""
        ix, iz = (int(c) for c in self.nav.cell_of(*xz))
        if 0 <= ix < self.node_of.shape[0] and 0 <= iz < self.node_of.shape[1] and self.node_of[ix, iz] >= 0:
            return int(self.node_of[ix, iz])
        return int(np.argmin(np.hypot(self.cells[:, 0] - ix, self.cells[:, 1] - iz)))

    def _frame(self) -> None:
        pose = self.sim.pose
        self.cov.add_frame(self.sim.sensor.depth(pose, self.K, self.res, self.res), pose, self.K)

    def act(self, action: str) -> bool:
        blocked = self.sim.act(action)
        self.actions.append(action)
        self._frame()
        return blocked

    def gains(self, open_: np.ndarray | None = None) -> np.ndarray:
        """Per sweep view: the ground-truth points it would complete that are still `open_` (default: that
        no frame has completed yet)."""
        open_ = ~self.cov.completed() if open_ is None else open_
        counts = np.bincount(self.owner, weights=open_[self.indices], minlength=len(self.poses))
        return counts.astype(np.int64)

    def _targets(self, spot: int, gains: np.ndarray) -> list[int]:
        views = np.arange(spot * self.per, (spot + 1) * self.per)
        return [int(v) for v in views[gains[views] >= self.min_gain]]

    def _union(self, views: list[int], open_: np.ndarray) -> int:
        if not views:
            return 0
        idx = np.concatenate([self.indices[self.indptr[v]:self.indptr[v + 1]] for v in views])
        return int(open_[np.unique(idx)].sum())

    def next_spot(self) -> tuple[int, list[int]] | None:
        """The spot completing the most per action (walk + turns toward it + its views), and its views."""
        open_ = ~self.cov.completed()
        gains = self.gains(open_)
        here = self.sim.state.position[[0, 2]]
        yaw, pitch = self.sim.state.yaw, self.sim.state.pitch
        dist = dijkstra(self.graph, indices=self._node(here))
        upper, costs, plans = np.zeros(len(self.spots)), np.full(len(self.spots), np.inf), {}
        for s in range(len(self.spots)):
            views = self._targets(s, gains)
            if not views or s in self.failed:
                continue
            n = self.spot_nodes[s]
            walk = float(dist[n]) if n >= 0 else np.inf
            if not np.isfinite(walk):
                continue
            if walk > 0.1:  # level the camera, face the walk, arrive facing along it
                bearing, level = math.atan2(*(self.spots[s] - here)), len(tilt_toward(pitch, 0.0, self.ctl))
                face, arrive_pitch = len(turn_toward(yaw, bearing, self.ctl)), 0.0
            else:
                bearing, level, face, arrive_pitch = yaw, 0, 0, pitch
            order = rotation_plan(bearing, arrive_pitch, [self.view_angles[v] for v in views], self.ctl)
            look = tour_actions(bearing, arrive_pitch, order, self.ctl)
            costs[s] = walk / self.ctl.forward_m + level + face + look
            upper[s] = gains[views].sum()
            plans[s] = views
        if not plans:
            return None
        ranked = sorted(plans, key=lambda s: -upper[s] / max(costs[s], 1.0))[:self.shortlist]
        best = max(ranked, key=lambda s: self._union(plans[s], open_) / max(costs[s], 1.0))
        return best, plans[best]

    def _path(self, goal: int) -> np.ndarray | None:
        """Waypoints (x, z) of the geodesic path from the agent to graph node `goal`, string-pulled on the
        navigability map where a straight leg stays clear of the follower's drift (10 deg headings)."""
        start = self._node(self.sim.state.position[[0, 2]])
        _, pred = dijkstra(self.walk_graph, indices=start, return_predecessors=True)
        path = [int(goal)]
        while path[-1] != start and path[-1] >= 0:
            path.append(int(pred[path[-1]]))
        if path[-1] != start:
            return None
        cells = self.cells[path[::-1]]
        pts = self.nav.cell_centre(cells[:, 0], cells[:, 1])
        keep, i = [0], 0
        while i < len(pts) - 1:
            j = len(pts) - 1
            while j > i + 1 and not self._clear(pts[i], pts[j]):
                j -= 1
            keep.append(j)
            i = j
        return pts[keep[1:]]

    def _clear(self, a: np.ndarray, b: np.ndarray) -> bool:
        """A straight leg a -> b and its two parallels offset by the drift a 10 deg heading error allows
        (at most 0.1 m) are all navigable."""
        d = b - a
        length = float(np.hypot(*d))
        if length < 1e-9:
            return True
        side = np.array([-d[1], d[0]]) / length * min(0.1, 0.18 * length)
        return all(self.nav.segment_free(a + o, b + o) for o in (0.0, side, -side))

    def _sidestep(self, budget: int) -> bool:
        """After a refused forward move: one turn left and a step, else two turns right and a step.
        Whether a step was taken (the follower turns back toward its waypoint itself)."""
        for turns in (["turn_left"], ["turn_right", "turn_right"]):
            if len(self.actions) + len(turns) + 1 > budget:
                return False
            for t in turns:
                self.act(t)
            if not self.act("move_forward"):
                return True
        return False

    def walk_to(self, spot: int, budget: int) -> bool:
        """Level the camera, then follow the geodesic path to the spot, planned again after a refused
        forward move that a sidestep does not get past (at most three times). Whether the agent stands
        within 0.3 m of the spot."""
        for a in tilt_toward(self.sim.state.pitch, 0.0, self.ctl):
            if len(self.actions) >= budget:
                return False
            self.act(a)
        goal = int(self.spot_nodes[spot])
        for _ in range(4):
            waypoints = self._path(goal)
            if waypoints is None:
                return False
            follower = PathFollower(waypoints, self.ctl)
            while len(self.actions) < budget:
                action = follower.next_action(self.sim.pose)
                if action is None or (self.act(action) and not self._sidestep(budget)):
                    break
            if follower.done or len(self.actions) >= budget:
                break
        return bool(np.hypot(*(self.sim.state.position[[0, 2]] - self.spots[spot])) < 0.3)

    def look(self, views: list[int], budget: int) -> None:
        """Turn and tilt to each view in the cheapest order (the camera is levelled before the next walk)."""
        order = rotation_plan(self.sim.state.yaw, self.sim.state.pitch,
                              [self.view_angles[v] for v in views], self.ctl)
        for target_yaw, target_pitch in order:
            for a in turn_toward(self.sim.state.yaw, target_yaw, self.ctl) + tilt_toward(
                    self.sim.state.pitch, target_pitch, self.ctl):
                if len(self.actions) >= budget:
                    return
                self.act(a)

    def plan_tour(self, budget: int) -> list[int]:
        """Spots chosen by set cover (most new points per action of their own looks, turning to a view only
        when it completes at least `min_gain` points), as many as the estimated budget allows (a spot that
        does not fit is skipped, up to 20 of them), in the order of the shortest open route from the agent
        (`planning.travel.shortest_tour`). Estimated cost: the route's forward steps, 6 turns per leg to
        face it, and each spot's looks."""
        open_ = ~self.cov.completed()
        chosen: list[int] = []
        looks = 0
        here = self._node(self.sim.state.position[[0, 2]])
        dist_from: dict[int, np.ndarray] = {}

        def route(spots: list[int]) -> tuple[list[int], float]:
            """The shortest open route from the agent through `spots`: their order and its length (m)."""
            for k in (here, *self.spot_nodes[spots]):
                if k not in dist_from:
                    dist_from[k] = dijkstra(self.graph, indices=int(k))
            nodes = self.spot_nodes[spots]
            start = dist_from[here][nodes]
            pair = np.stack([dist_from[i][nodes] for i in nodes])
            order = shortest_tour(start, pair)
            legs = pair[np.asarray(order[:-1], int), np.asarray(order[1:], int)]
            return order, float(start[order[0]] + legs.sum())

        skipped: set[int] = set()
        while len(skipped) < 20:
            gains = self.gains(open_)
            plans, upper, cost = {}, {}, {}
            for s_ in range(len(self.spots)):
                views = self._targets(s_, gains)
                if not views or s_ in chosen or s_ in skipped or s_ in self.failed or self.spot_nodes[s_] < 0:
                    continue
                key = tuple(views)
                if key not in self._look_cost:
                    angles = [self.view_angles[v] for v in views]
                    self._look_cost[key] = tour_actions(0.0, 0.0, rotation_plan(0.0, 0.0, angles, self.ctl),
                                                        self.ctl)
                cost[s_] = self._look_cost[key]
                plans[s_], upper[s_] = views, gains[views].sum()
            if not plans:
                break
            ranked = sorted(plans, key=lambda k: -upper[k] / max(cost[k], 1))[:self.shortlist]
            best = max(ranked, key=lambda k: self._union(plans[k], open_) / max(cost[k], 1))
            trial = chosen + [best]
            _, walk = route(trial)
            if walk / self.ctl.forward_m + 6 * len(trial) + looks + cost[best] > budget - len(self.actions):
                skipped.add(best)  # too far for what is left: try the next best
                continue
            chosen, looks = trial, looks + cost[best]
            idx = np.concatenate([self.indices[self.indptr[v]:self.indptr[v + 1]] for v in plans[best]])
            open_[idx] = False
        return [chosen[i] for i in route(chosen)[0]] if chosen else []

    def run(self, budget: int, at: list[int], tour: bool = True, first_budget: int | None = None) -> dict:
        """Walk the route: with `tour`, the planned tour first (`plan_tour`; with `first_budget`, a tour
        planned to fit that many actions, then one for the rest), then greedy choices while budget is left;
        without, greedy choices only (`next_spot`). A leg's tour is planned again when it is walked and
        budget is left in the leg; a leg with nothing left that fits is ended."""
        marks: dict[int, float] = {}
        stops, stale = 0, 0
        legs = sorted({s for s in (first_budget, budget) if s})
        planned: list[int] = []
        while len(self.actions) < budget:
            while tour and legs and len(self.actions) >= legs[0]:
                legs.pop(0)
            if tour and legs and not planned:
                planned = self.plan_tour(legs[0])
                if not planned:
                    legs.pop(0)
                    continue
            if planned:
                spot = planned.pop(0)
            else:
                choice = self.next_spot()
                if choice is None:
                    break
                spot, _ = choice
            if not self.walk_to(spot, budget):
                self.failed.add(spot)
                stale += 1
                if stale >= 10:
                    break
                continue
            self.failed.clear()
            stale = 0
            self.look(self._targets(spot, self.gains()), budget)
            stops += 1
            for s in at:
                if s not in marks and len(self.actions) >= s:
                    marks[s] = self._completion_at(s)
        end = self.cov.metrics(uncapped=False)["completion_ratio_pct"]
        for s in at:
            marks.setdefault(s, end if len(self.actions) <= s else self._completion_at(s))
        rotations = sum(a != "move_forward" for a in self.actions)
        self.cov.flush()
        return {"at": marks, "end": end, "steps": len(self.actions), "stops": stops,
                "completed": self.cov.completed(),
                "rotation_pct": 100.0 * rotations / max(len(self.actions), 1),
                "path_m": self.ctl.forward_m * self.actions.count("move_forward")}

    def _completion_at(self, step: int) -> float:
        """Completion ratio % after `step` actions (frames 0..step: the start frame comes first)."""
        self.cov.flush()
        first = self.cov.first_frame
        return 100.0 * float(((first >= 0) & (first <= step)).sum()) / len(first)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=[f"medium-{i}" for i in range(100, 110)])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--ceilings", type=Path, required=True, help="folder with <scene>/sweep.json")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--at", nargs="+", type=int, default=[500, 1000, 1500])
    ap.add_argument("--min-gain", type=int, default=100,
                    help="a view is worth turning to when it completes at least this many new points")
    ap.add_argument("--greedy", action="store_true",
                    help="choose each next spot greedily (points per action, walk included) instead of a "
                         "planned tour")
    ap.add_argument("--first-budget", type=int, default=None,
                    help="plan a first tour within this many actions (e.g. 1000), then one for the rest")
    ap.add_argument("--cache", type=Path, default=Path("runs/oracle_cache"))
    args = ap.parse_args()
    sim, cov, sweep = SimConfig(), CoverageConfig(), SweepConfig()
    per = len(np.arange(0.0, 360.0, sweep.yaw_step_deg)) * len(sweep.pitches_deg)
    cols = " | ".join(f"at {s} %" for s in args.at)
    print(f"| scene | seed | {cols} | at {args.steps} % | rotations % | path m | stops | worst room % | s |")
    print("|---|---|" + "---|" * (len(args.at) + 6))
    rows = []
    for name in args.scenes:
        scene = load_scene(name)
        sweep_json = json.loads((args.ceilings / name / "sweep.json").read_text())
        ceiling = sweep_json["completion_ratio_pct"]
        gt = scene.sample_surface(cov.n_gt_points, seed=cov.seed)
        t0 = time.time()
        poses, indptr, indices = view_sets(scene, sim, sweep, cov, np.asarray(gt, np.float64),
                                           args.cache / f"{name}.npz" if args.cache else None)
        union = np.zeros(len(gt), bool)
        union[indices] = True
        if abs(100.0 * union.mean() - ceiling) > 0.05:
            print(f"warning: {name}: the view sets complete {100 * union.mean():.2f} % against the sweep's "
                  f"{ceiling:.2f} %")
        for seed in args.seeds:
            route = OracleRoute(scene, seed, sim, cov, gt, poses, indptr, indices, per, args.min_gain)
            out = route.run(args.steps, args.at, tour=not args.greedy, first_budget=args.first_budget)
            worst = np.nan
            if scene.house is not None:
                rooms = room_behaviour(scene.house, np.zeros((0, 2)), gt, out["completed"])
                worst = relative_to_ceiling({"completion_ratio_pct": out["end"], **rooms}, sweep_json).get(
                    "worst_room_of_ceiling_pct", np.nan)
            row = [100 * out["at"][s] / ceiling for s in args.at]
            row += [100 * out["end"] / ceiling, out["rotation_pct"], out["path_m"], out["stops"], worst]
            rows.append(row)
            marks = " | ".join(f"{v:.1f}" for v in row[:len(args.at)])
            print(f"| {name} | {seed} | {marks} | {row[len(args.at)]:.1f} | {out['rotation_pct']:.1f} | "
                  f"{out['path_m']:.1f} | {out['stops']} | {worst:.1f} | {time.time() - t0:.0f} |",
                  flush=True)
    a = np.array(rows)
    marks = " | ".join(f"**{v:.1f}**" for v in a[:, :len(args.at) + 1].mean(axis=0))
    rest = " | ".join(f"{v:.1f}" for v in np.nanmean(a[:, -4:], axis=0))
    print(f"| **mean** | | {marks} | {rest} | |")


if __name__ == "__main__":
    main()
