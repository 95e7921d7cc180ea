"""Voronoi graph of the workspace (paper sec. III-A: "a Voronoi graph G = {V, E} is generated through
Voronoi tessellation, with edges equidistant from the obstacles"; docs/protocol.md §3, release).

Node attributes: `pos` (2,) world (x, z) on the floor plane, `clearance` (metres to the nearest
non-workspace pixel), `view` (view-position node: degree >= 3 before pruning), `multi`
(multi-connected: degree > 2 after pruning), `leaf` (degree 1 after pruning). Edge attribute
`weight` = Euclidean length in metres."""

from __future__ import annotations

import networkx as nx
import numpy as np
from scipy.spatial import QhullError, Voronoi

from activesplat.workspace.clean import Workspace, mask_boundaries
from activesplat.workspace.config import WorkspaceConfig


def boundary_samples(polygons: list[np.ndarray], spacing: float) -> np.ndarray:
    """Points every <= `spacing` metres along the edges of closed polygons (K_i, 2) -> (M, 2)."""
    chunks = []
    for poly in polygons:
        if len(poly) < 2:
            continue
        a, b = poly, np.roll(poly, -1, axis=0)
        counts = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) / spacing).astype(np.int64), 1)
        edge = np.repeat(np.arange(len(a)), counts)
        offsets = np.concatenate([[0], np.cumsum(counts)[:-1]])
        t = (np.arange(counts.sum()) - offsets[edge]) / counts[edge]
        chunks.append(a[edge] + t[:, None] * (b[edge] - a[edge]))
    if not chunks:
        return np.zeros((0, 2))
    return np.unique(np.round(np.concatenate(chunks), 6), axis=0)


def voronoi_ridges(sites: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 2) and finite ridges (R, 2) of the Voronoi diagram of `sites`; empty when qhull
    cannot build one (too few or collinear sites)."""
    if len(sites) < 4:
        return np.zeros((0, 2)), np.zeros((0, 2), dtype=np.int64)
    try:
        vor = Voronoi(sites)
    except QhullError:
        return np.zeros((0, 2)), np.zeros((0, 2), dtype=np.int64)
    ridges = np.asarray(vor.ridge_vertices, dtype=np.int64).reshape(-1, 2)
    return vor.vertices, ridges[(ridges >= 0).all(axis=1)]


def safe_edges(workspace: Workspace, vertices: np.ndarray, ridges: np.ndarray, cfg: WorkspaceConfig
               ) -> tuple[np.ndarray, np.ndarray]:
    """Merge duplicate vertices and keep ridges that lie inside the workspace with more than the agent
    radius of clearance at every sample (release checks the two vertices; we check the whole ridge).
    Returns merged vertices (V', 2) and edges (E, 2) into them."""
    # qhull puts the vertices of nearly collinear sites very far away (or at inf): their ridges cannot be
    # safe, and their keys would overflow the integer cast below
    finite = (np.abs(vertices) < 1e6).all(axis=1)
    ridges = ridges[finite[ridges].all(axis=1)] if len(ridges) else ridges
    if len(ridges) == 0:
        return np.zeros((0, 2)), np.zeros((0, 2), dtype=np.int64)
    vertices = np.where(finite[:, None], vertices, 0.0)
    keys = np.round(vertices / cfg.merge_distance).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    merged = vertices[first]
    edges = inverse.reshape(-1)[ridges]
    edges = np.unique(np.sort(edges[edges[:, 0] != edges[:, 1]], axis=1), axis=0)
    if len(edges) == 0:
        return merged, edges
    # Cheap first: both vertices clear (this also drops the far-away vertices qhull places outside the
    # workspace, whose ridges would be millions of samples long); then the whole ridge.
    vertex_ok = workspace.clearance_at(merged) > cfg.agent_radius
    edges = edges[vertex_ok[edges[:, 0]] & vertex_ok[edges[:, 1]]]
    if len(edges) == 0:
        return merged, edges
    ok = workspace.segments_clearance(merged[edges[:, 0]], merged[edges[:, 1]]) > cfg.agent_radius
    return merged, edges[ok]


def dangling_chain(graph: nx.Graph, leaf: int) -> tuple[list[int], float, int]:
    """Walk from a leaf along degree-2 nodes; returns (chain nodes without the end, length, end node)."""
    chain, length, prev, node = [leaf], 0.0, None, leaf
    while True:
        nxt = next(n for n in graph.neighbors(node) if n != prev)
        length += graph.edges[node, nxt]["weight"]
        if graph.degree(nxt) != 2:
            return chain, length, nxt
        chain.append(nxt)
        prev, node = node, nxt


def chain_reach(graph: nx.Graph, chain: list[int], length: float, end: int) -> float:
    """How far (metres) a dangling chain reaches beyond the clearance disc of the junction it hangs off:
    chain length + clearance at the leaf - clearance at the junction. A spur running into a convex
    corner stays inside that disc (reach ~ 0.41 x junction clearance), a real dead end does not."""
    return length + graph.nodes[chain[0]]["clearance"] - graph.nodes[end]["clearance"]


def insignificant_chains(graph: nx.Graph, max_reach: float) -> dict[int, list[tuple[float, list[int]]]]:
    """Dangling chains (leaf .. last degree-2 node) hanging off a junction (degree >= 3) that reach less
    than `max_reach` beyond it, grouped by junction: {junction: [(reach, chain), ...]}."""
    found: dict[int, list[tuple[float, list[int]]]] = {}
    for leaf in sorted(n for n in graph.nodes if graph.degree(n) == 1):
        chain, length, end = dangling_chain(graph, leaf)
        if graph.degree(end) >= 3:
            reach = chain_reach(graph, chain, length, end)
            if reach < max_reach:
                found.setdefault(end, []).append((reach, chain))
    return found


def prune_dangling_chains(graph: nx.Graph, max_reach: float) -> None:
    """Repeatedly remove dangling leaf chains that reach less than `max_reach` beyond the junction they
    hang off (docs/protocol.md §3, release: prune dangling leaf chains repeatedly; our significance rule
    keeps corridors and dead ends, drops corner spurs). All short chains of a junction go at once (a
    corridor's end keeps no diagonal spur), except that a junction keeps its farthest-reaching chain when
    it would otherwise lose every edge."""
    while True:
        found = insignificant_chains(graph, max_reach)
        if not found:
            return
        removed = False
        for end, chains in found.items():
            chains.sort(key=lambda rc: rc[0])
            if len(chains) == graph.degree(end):
                chains = chains[:-1]
            for _, chain in chains:
                graph.remove_nodes_from(chain)
                removed = True
        if not removed:
            return


def graph_from_edges(vertices: np.ndarray, edges: np.ndarray, workspace: Workspace) -> nx.Graph:
    """networkx graph with nodes numbered in lexicographic (x, z) order (deterministic)."""
    used = np.unique(edges)
    order = used[np.lexsort((vertices[used, 1], vertices[used, 0]))]
    index = {int(v): i for i, v in enumerate(order)}
    clearance = workspace.clearance_at(vertices[order])
    graph = nx.Graph()
    for i, v in enumerate(order):
        graph.add_node(i, pos=vertices[v].copy(), clearance=float(clearance[i]))
    lengths = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    for (a, b), length in zip(edges, lengths, strict=True):
        graph.add_edge(index[int(a)], index[int(b)], weight=float(length))
    return graph


def relabel_in_order(graph: nx.Graph) -> nx.Graph:
    """Renumber nodes 0..n-1 keeping their order (after pruning)."""
    return nx.convert_node_labels_to_integers(graph, ordering="sorted")


def build_voronoi_graph(workspace: Workspace, cfg: WorkspaceConfig | None = None) -> nx.Graph:
    """Voronoi graph of the workspace (docs/protocol.md §3): Voronoi of points sampled along the workspace
    boundary (the mask's contours, or the release's simplified polygons with `sites_from_mask=False`),
    ridges inside the workspace with clearance > agent radius, isolated vertices dropped, short dangling
    chains pruned, edges weighted by length, view and multi-connected nodes
    marked. An empty workspace gives an empty graph."""
    cfg = cfg or WorkspaceConfig()
    if workspace.empty:
        return nx.Graph()
    if cfg.sites_from_mask:
        boundaries = mask_boundaries(workspace, cfg.site_epsilon_px, cfg.min_site_hole_area)
    else:
        boundaries = [workspace.outer, *workspace.holes]
    sites = boundary_samples(boundaries, cfg.boundary_sample_spacing)
    vertices, ridges = voronoi_ridges(sites)
    vertices, edges = safe_edges(workspace, vertices, ridges, cfg)
    if len(edges) == 0:
        return nx.Graph()
    graph = graph_from_edges(vertices, edges, workspace)
    nx.set_node_attributes(graph, {n: d >= 3 for n, d in graph.degree}, "view")
    prune_dangling_chains(graph, cfg.prune_length)
    graph = relabel_in_order(graph)
    nx.set_node_attributes(graph, {n: d > 2 for n, d in graph.degree}, "multi")
    nx.set_node_attributes(graph, {n: d == 1 for n, d in graph.degree}, "leaf")
    return graph


def node_positions(graph: nx.Graph) -> np.ndarray:
    """(V, 2) world (x, z) of the nodes in node order 0..V-1."""
    if graph.number_of_nodes() == 0:
        return np.zeros((0, 2))
    return np.stack([graph.nodes[n]["pos"] for n in sorted(graph.nodes)])
