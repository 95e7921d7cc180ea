"""Panoramas at the candidate nodes and their eq. 12 scores (paper sec. III-B2, III-D2, eq. 12), steps 2
and 3 of goal selection (`planning.goals.rank_goals`): which candidates get a panorama
(`panorama_candidates`), what each one shows (invisible share and hull volume, eq. 12's s_o and s_c before
normalising; `render_panoramas`), the information part w_o s_o + w_c s_c (`information_part`) and eq. 12
with the in-horizon flag s_h (`eq12_scores`). The formulas themselves are `planning.viewpoints`'
(`information_scores`, `node_scores`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from activesplat.planning.candidates import Candidates
from activesplat.planning.config import PlanningConfig, ScoreConfig
from activesplat.planning.explorer_config import GoalRules
from activesplat.planning.panorama import RenderFn, render_panorama
from activesplat.planning.viewpoints import hull_volume, information_scores, invisible_share, node_scores
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.paths import line_of_sight
from activesplat.workspace.plan import Plan


def panorama_candidates(nodes: list[int], dist: np.ndarray, open_: np.ndarray, subregions: dict[int, int],
                        max_panoramas: int, every_subregion: bool = True) -> list[int]:
    """Indices of the nodes scored by panorama: the nearest open node of every subregion first, so that
    rooms farther away are weighed too, then the nearest open nodes, `max_panoramas` in all. With
    `every_subregion` the subregions' nodes do not count against `max_panoramas`: every subregion with an
    open node gets one panorama however many there are, and `max_panoramas` nearest open nodes come on top
    (those already chosen are not scored twice)."""
    order = [int(i) for i in np.argsort(dist, kind="stable") if open_[i]]
    chosen: list[int] = []
    seen: set[int] = set()
    for i in order:
        region = subregions.get(nodes[i])
        if region is not None and region not in seen:
            seen.add(region)
            chosen.append(i)
    if every_subregion:
        taken = set(chosen)
        return chosen + [i for i in order[:max_panoramas] if i not in taken]
    chosen = chosen[:max_panoramas]
    taken = set(chosen)
    chosen += [i for i in order if i not in taken][: max_panoramas - len(chosen)]
    return chosen


@dataclass
class PanoramaTerms:
    """What the panoramas rendered at the candidates show (sec. III-B2), 0 where none was rendered."""

    invisible: np.ndarray
    """eq. 12's s_o before normalising: the panorama's invisible share (`invisible_share`)."""
    hull: np.ndarray
    """eq. 12's s_c before normalising: the hull volume of its invisible regions (`hull_volume`)."""
    scored: np.ndarray
    """Whether a panorama was rendered at the node."""


def render_panoramas(plan: Plan, cand: Candidates, here: np.ndarray, render: RenderFn,
                     floor_height: float, pcfg: PlanningConfig, rules: GoalRules) -> PanoramaTerms:
    """Step 2 of `rank_goals` (sec. III-B2, III-D2): a panorama `panorama_height_m` above the floor at each
    node `panorama_candidates` picks, and its invisible share and hull volume. The largest invisible share
    is `plan.max_invisible`."""
    n = len(cand.nodes)
    views = PanoramaTerms(np.zeros(n), np.zeros(n), np.zeros(n, bool))
    height = floor_height + rules.panorama_height_m
    dist = np.hypot(*(cand.pos - here).T)
    for i in panorama_candidates(cand.nodes, dist, cand.open_, plan.subregions, rules.max_panoramas,
                                  rules.panorama_every_subregion):
        pano = render_panorama(render, [cand.pos[i][0], height, cand.pos[i][1]], pcfg.panorama)
        views.scored[i] = True
        views.invisible[i] = invisible_share(pano, pcfg.rotation)
        views.hull[i] = hull_volume(pano, pcfg.hull)
    plan.max_invisible = float(views.invisible.max()) if views.scored.any() else 0.0
    return views


def information_part(views: PanoramaTerms, cfg: ScoreConfig) -> np.ndarray:
    """Step 3 of `rank_goals`: the information part of eq. 12, w_o s_o + w_c s_c with the shares relative to
    the best candidate (`information_scores`): what keeps planning local, and what makes a node worth a
    stop on a long path's way."""
    return information_scores(views.invisible, views.hull, cfg)


def in_horizon_flags(plan: Plan, cand: Candidates, here: np.ndarray, wcfg: WorkspaceConfig,
                     off: bool) -> np.ndarray:
    """eq. 12's s_h: the straight line from the agent to the node is collision-free; none when `off` (a
    hierarchical ranking with `local_in_horizon` off, ours)."""
    if off:
        return np.zeros(len(cand.pos), bool)
    return np.array([line_of_sight(plan.workspace, here, p, wcfg) for p in cand.pos])


def eq12_scores(cand: Candidates, views: PanoramaTerms, in_horizon: np.ndarray, cfg: ScoreConfig,
                rules: GoalRules) -> tuple[np.ndarray, np.ndarray | None]:
    """Step 3 of `rank_goals`: eq. 12, S = w_o s_o + w_c s_c + w_u s_u + w_h s_h less the release's failure
    penalty (`node_scores`); and the scores of the global stage, None when they are the same
    (`global_in_horizon`). This project's global stage leaves the in-horizon flag out: a node in sight of
    the agent is a local preference and, counted there too, keeps the agent near (ours; docs/protocol.md §5,
    docs/exploration.md)."""

    def eq12(s_h: np.ndarray) -> np.ndarray:
        return node_scores(views.invisible, views.hull, cand.unvisited, s_h, cand.failed, cfg)

    return eq12(in_horizon), None if rules.global_in_horizon else eq12(np.zeros_like(in_horizon))


__all__ = ["PanoramaTerms", "eq12_scores", "in_horizon_flags", "information_part", "panorama_candidates",
           "render_panoramas"]
