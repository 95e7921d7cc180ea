"""The workspace pipeline of one replan (paper sec. III-A, III-C): top-down grids -> workspace polygon ->
Voronoi graph -> UPGMA subregions of the current map, collected in a `Plan` the planner then completes
with node scores, a goal and a path."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import networkx as nx
import numpy as np

from activesplat.timing import Timers
from activesplat.workspace.clean import Workspace, extract_workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.subregions import partition_subregions
from activesplat.workspace.topdown import TopDownGrids, render_topdown
from activesplat.workspace.voronoi import build_voronoi_graph


@dataclass
class Plan:
    """What the explorer currently knows of the workspace (for planning, drawing and the viewer). The
    workspace pipeline fills grids, workspace, graph and subregions; the planner fills the rest."""

    grids: TopDownGrids | None = None
    workspace: Workspace | None = None
    graph: nx.Graph = field(default_factory=nx.Graph)
    subregions: dict[int, int] = field(default_factory=dict)
    scores: dict[int, float] = field(default_factory=dict)
    """Each scored node's eq. 12 score."""
    info: dict[int, float] = field(default_factory=dict)
    """The information part of each node's score (w_o s_o + w_c s_c), see
    `activesplat.planning.viewpoints.information_scores`."""
    max_invisible: float = 0.0
    """The largest invisible share (eq. 12's s_o before normalising) of the panoramas of the last ranking."""
    travel: dict[int, float] = field(default_factory=dict)
    """Each candidate's travel length from the agent in metres (`planning.travel.travel_lengths`)."""
    stage: str = ""
    """How the goal ranking went: "local" (a node of the agent's subregion promised something to see),
    "global" (score minus distance over every node), "flat" (no hierarchical planning); empty when the
    nodes were not ranked (random goals)."""
    goal: np.ndarray | None = None
    path: np.ndarray | None = None


def build_plan(gaussians: Any, floor_height: float, agent_xz: np.ndarray, wcfg: WorkspaceConfig,
               timers: Timers | None = None, graph: bool = True) -> Plan:
    """Top-down grids -> workspace -> Voronoi graph -> subregions of the current map (sec. III-A, III-C).
    `graph=False` stops after the workspace (frontier exploration needs no graph). Each stage is timed under
    its Tab. VI module name."""
    timers = timers or Timers()
    plan = Plan()
    plan.grids = timers.time("workspace", render_topdown, gaussians, floor_height, wcfg, agent_xz)
    plan.workspace = timers.time("workspace", extract_workspace, plan.grids, agent_xz, wcfg)
    if graph:
        plan.graph = timers.time("voronoi", build_voronoi_graph, plan.workspace, wcfg)
        plan.subregions = timers.time("subregions", partition_subregions, plan.graph, wcfg)
    return plan


def grown_plan(plan: Plan, agent_xz: np.ndarray, wcfg: WorkspaceConfig, margin_m: float,
               timers: Timers | None = None) -> Plan:
    """The workspace and Voronoi graph of `plan`'s own grids with the free floor grown `margin_m` into
    unknown pixels (`WorkspaceConfig.unknown_margin`): a door seen at a grazing angle leaves a neck of
    observed floor thinner than the agent, which no graph edge crosses; grown, it has one. No new render."""
    if plan.grids is None:
        raise ValueError("grown_plan needs a plan with its top-down grids")
    timers = timers or Timers()
    cfg = dataclasses.replace(wcfg, unknown_margin=margin_m)
    grown = Plan(grids=plan.grids)
    grown.workspace = timers.time("workspace", extract_workspace, plan.grids, agent_xz, cfg)
    grown.graph = timers.time("voronoi", build_voronoi_graph, grown.workspace, cfg)
    return grown


__all__ = ["Plan", "build_plan", "grown_plan"]
