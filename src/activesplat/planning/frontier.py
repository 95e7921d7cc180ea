"""Classic frontier-based exploration (Yamauchi 1997), the `fbe` baseline, on the same top-down grids.

A frontier cell is a known-free cell next to an unknown one. Frontier cells are grouped into connected
clusters; the agent travels to the nearest reachable cluster (grid distance through free space with the
agent's clearance), then looks around once the frontier is reached. No panoramas, no Voronoi scores.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from activesplat.errors import check_fields
from activesplat.planning.controller import floor_xz
from activesplat.planning.explorer import Explorer, turns_for
from activesplat.workspace.clean import Workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.paths import needed_clearance, shortcut
from activesplat.workspace.plan import build_plan
from activesplat.workspace.topdown import TopDownGrids, frontier_cells

_NEIGHBOURS = np.ones((3, 3), np.uint8)


@dataclass(frozen=True)
class FrontierConfig:
    """The `fbe` baseline's own knobs (its paths and look-arounds use the explorer's settings)."""

    min_cluster_cells: int = 8
    """Frontier clusters with fewer cells are noise (ours; 0.05 m cells: 8 cells ~ 0.4 m of frontier)."""
    skip_radius_m: float = 0.5
    """Frontier cells within this of the agent, a failed goal or a frontier already reached are not goals
    (ours: classic FBE re-selects an unobservable frontier forever)."""
    start_disc_m: float = 0.3
    """Cells this close to the agent count as passable for the frontier search (ours: it stands there)."""
    look_around_deg: float = 360.0
    """On reaching a frontier the agent turns left this far on the spot (ours: a full circle)."""

    def __post_init__(self) -> None:
        check_fields(self, non_negative=("min_cluster_cells", "skip_radius_m", "start_disc_m",
                                         "look_around_deg"))


def grid_distances(passable: np.ndarray, start_rc: tuple[int, int]) -> np.ndarray:
    """Breadth-first (8-connected) step counts from `start_rc` through `passable`; inf where unreachable."""
    dist = np.full(passable.shape, np.inf)
    r, c = start_rc
    if not (0 <= r < passable.shape[0] and 0 <= c < passable.shape[1]):
        return dist
    reached = np.zeros(passable.shape, np.uint8)
    reached[r, c] = 1
    dist[r, c] = 0
    allowed = passable.astype(np.uint8)
    allowed[r, c] = 1
    step = 0
    while True:
        step += 1
        grown = cv2.dilate(reached, _NEIGHBOURS) & allowed
        new = (grown > 0) & (reached == 0)
        if not new.any():
            return dist
        dist[new] = step
        reached = grown


def descend(dist: np.ndarray, goal_rc: tuple[int, int]) -> list[tuple[int, int]]:
    """Cells from the goal back to the start, always stepping to the lowest-distance neighbour."""
    path = [goal_rc]
    r, c = goal_rc
    while dist[r, c] > 0:
        best = (r, c)
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                rr, cc = r + dr, c + dc
                if 0 <= rr < dist.shape[0] and 0 <= cc < dist.shape[1] and dist[rr, cc] < dist[best]:
                    best = (rr, cc)
        if best == (r, c):
            break
        r, c = best
        path.append(best)
    return path[::-1]


def nearest_frontier_path(grids: TopDownGrids, ws: Workspace, here: np.ndarray, avoid: list[np.ndarray],
                          wcfg: WorkspaceConfig, fcfg: FrontierConfig) -> np.ndarray | None:
    """A safe path (M, 2) from `here` to the nearest reachable frontier cluster, None when none is a goal
    or none is reachable. Frontiers within `skip_radius_m` of the agent or of a point of `avoid` (failed
    goals, frontiers reached) are not goals."""
    geom = grids.geometry
    passable = ws.clearance >= wcfg.agent_radius
    frontier = frontier_cells(ws.mask, grids.unknown)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(frontier.astype(np.uint8), connectivity=8)
    big = np.zeros(count, bool)
    big[1:] = stats[1:, cv2.CC_STAT_AREA] >= fcfg.min_cluster_cells
    # Frontier cells border unknown space, so they never have the agent's clearance themselves: the goals
    # are the passable cells within reach (clearance + 2 cells) of a frontier cluster.
    reach = int(np.ceil(wcfg.agent_radius / geom.resolution)) + 2
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1, 2 * reach + 1))
    targets = (cv2.dilate(big[labels].astype(np.uint8), kernel) > 0) & passable
    # Skip frontiers near failed goals, near frontiers already reached, and right under the agent.
    blocked = np.zeros(targets.shape, np.uint8)
    k = max(1, int(round(fcfg.skip_radius_m / geom.resolution)))
    for p in [*avoid, here]:
        r, c = geom.pixel_index(p)
        cv2.circle(blocked, (int(c), int(r)), k, 1, -1)
    targets &= blocked == 0
    if not targets.any():
        return None
    start = tuple(int(v) for v in geom.pixel_index(here))
    # The agent stands on free floor even where the polished workspace is thin (doorways): let the search
    # leave from a small disc around it, or a door would trap it.
    r = max(1, int(round(fcfg.start_disc_m / geom.resolution)))
    disc = np.zeros(passable.shape, np.uint8)
    if geom.contains(np.array(start)):
        cv2.circle(disc, (start[1], start[0]), r, 1, -1)
    # Never through obstacle cells (floor seen under a table is free but not walkable), nor closer to the
    # workspace border than the agent already is: the path-ahead check would refuse that route.
    near = (ws.mask | grids.free) & (ws.clearance >= needed_clearance(ws, here, wcfg))
    passable = passable | ((disc > 0) & near & ~grids.obstacle)
    dist = grid_distances(passable, start)
    cand = np.where(targets, dist, np.inf)
    if not np.isfinite(cand).any():
        return None
    goal = np.unravel_index(int(np.argmin(cand)), cand.shape)
    cells = np.array(descend(dist, (int(goal[0]), int(goal[1]))), float) + 0.5
    route = np.vstack([here[None], geom.pixel_to_world(cells)])
    return shortcut(route, ws, wcfg)


class FrontierExplorer(Explorer):
    """Nearest-frontier-first exploration with the shared bootstrap, path following and escapes."""

    name = "fbe"

    def __init__(self, *args, frontier: FrontierConfig | None = None, **kwargs):
        super().__init__(*args, **kwargs)
        self.fcfg = frontier or FrontierConfig()
        self.reached: list[np.ndarray] = []

    def arrive(self, pose: np.ndarray) -> None:
        """Look around once. A frontier that survives a look-around from right next to it cannot be seen
        from there (e.g. floor under furniture): remember it so that the agent does not come back forever."""
        self.reached.append(floor_xz(pose))
        self.enqueue(["turn_left"] * turns_for(self.fcfg.look_around_deg, self.cfg.controller), "look_around")

    def replan(self, pose: np.ndarray) -> None:
        """Rebuild the workspace (no graph) and go to the nearest frontier, else idle."""
        cfg = self.cfg
        here = floor_xz(pose)
        plan = self.plan = build_plan(self.world.gaussians, self.floor_height, here, cfg.workspace,
                                      self.timers, graph=False)
        stuck = bool(self.failed)
        path = self.timers.time("position_selection", nearest_frontier_path, plan.grids, plan.workspace,
                                here, [*self.failed, *self.reached], cfg.workspace, self.fcfg)
        if path is None:
            # fallback: give every frontier a second chance, also when frontiers are left but none is
            # reachable from here (the failed ones covered every reachable frontier; kept, they held the
            # agent in a corner for 1500 steps, escaping and turning, on fresh medium-101 and medium-105)
            self.reached.clear()
            self.forget_failures()
            plan.goal = plan.path = None
            self.idle(pose, stuck)
            return
        self.go_to(path[-1], path)
