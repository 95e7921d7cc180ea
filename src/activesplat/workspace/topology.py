"""The whole workspace step of one replan (paper sec. III-A and III-C): top-down grids -> polished
workspace -> Voronoi graph -> subregions, with the time each stage took (metrics `timing_ms` keys
`workspace`, `voronoi`, `subregions`)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import networkx as nx
import numpy as np

from activesplat.workspace.clean import Workspace, extract_workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.subregions import agent_subregion, partition_subregions
from activesplat.workspace.topdown import TopDownGrids, render_topdown
from activesplat.workspace.voronoi import build_voronoi_graph


@dataclass
class Topology:
    """Plain data of one workspace update."""

    grids: TopDownGrids
    workspace: Workspace
    graph: nx.Graph
    """Voronoi graph; node attributes pos, clearance, view, multi, leaf, subregion."""
    subregions: dict[int, int]
    """Node -> subregion label."""
    agent_subregion: int | None
    """Label of the node nearest the agent; None for an empty graph."""
    timing_ms: dict[str, float] = field(default_factory=dict)


def topology_from_grids(grids: TopDownGrids, agent_xz: np.ndarray, cfg: WorkspaceConfig | None = None,
                        timing_ms: dict[str, float] | None = None) -> Topology:
    """Polish the grids, extract the Voronoi graph and partition it, timing each stage."""
    cfg = cfg or WorkspaceConfig()
    timing_ms = dict(timing_ms or {})
    agent_xz = np.asarray(agent_xz, dtype=np.float64).reshape(2)
    t0 = time.perf_counter()
    workspace = extract_workspace(grids, agent_xz, cfg)
    t1 = time.perf_counter()
    graph = build_voronoi_graph(workspace, cfg)
    t2 = time.perf_counter()
    labels = partition_subregions(graph, cfg)
    t3 = time.perf_counter()
    timing_ms["workspace"] = timing_ms.get("workspace", 0.0) + 1e3 * (t1 - t0)
    timing_ms["voronoi"] = 1e3 * (t2 - t1)
    timing_ms["subregions"] = 1e3 * (t3 - t2)
    return Topology(grids, workspace, graph, labels, agent_subregion(graph, labels, agent_xz), timing_ms)


def build_topology(gmap: Any, floor_height: float, agent_xz: np.ndarray, cfg: WorkspaceConfig | None = None,
                   backend: str = "auto") -> Topology:
    """Render the Gaussian map top-down and build the workspace topology around the agent at world
    (x, z) `agent_xz`; `floor_height` comes from the agent's start pose."""
    cfg = cfg or WorkspaceConfig()
    t0 = time.perf_counter()
    grids = render_topdown(gmap, floor_height, cfg, agent_xz=agent_xz, backend=backend)
    render_ms = 1e3 * (time.perf_counter() - t0)
    return topology_from_grids(grids, agent_xz, cfg, {"workspace": render_ms})
