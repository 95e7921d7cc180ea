"""Subregion partition of the Voronoi graph (paper sec. III-C "Subregion Partition": UPGMA on travel
path length and Euclidean distance, fixed 2 m cut; docs/protocol.md §5)."""

from __future__ import annotations

import networkx as nx
import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.sparse.csgraph import shortest_path
from scipy.spatial.distance import cdist, squareform

from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.voronoi import node_positions


def path_length_matrix(graph: nx.Graph) -> np.ndarray:
    """(V, V) shortest-path lengths over edge weights, node order 0..V-1; inf between components."""
    nodes = sorted(graph.nodes)
    adjacency = nx.to_scipy_sparse_array(graph, nodelist=nodes, weight="weight", format="csr")
    # csgraph's kernels take 32-bit indices; older scipy (1.11) refuses the 64-bit ones networkx may build
    adjacency.indices = adjacency.indices.astype(np.int32)
    adjacency.indptr = adjacency.indptr.astype(np.int32)
    return shortest_path(adjacency, method="D", directed=False)


def subregion_distance(graph: nx.Graph, cfg: WorkspaceConfig) -> np.ndarray:
    """Pairwise distance 0.5 * path length + 0.5 * Euclidean (docs/protocol.md §5). Nodes in different
    connected components get a distance far above the cut, so they never share a subregion."""
    positions = node_positions(graph)
    euclid = cdist(positions, positions)
    travel = path_length_matrix(graph)
    far = 1e3 * cfg.subregion_cut + 2.0 * euclid.max(initial=0.0)
    travel = np.where(np.isfinite(travel), travel, far)
    return cfg.path_weight * travel + cfg.euclidean_weight * euclid


def partition_subregions(graph: nx.Graph, cfg: WorkspaceConfig | None = None) -> dict[int, int]:
    """UPGMA (average linkage) cut at `subregion_cut` metres: node -> subregion label 0..n-1, labels
    numbered in order of their lowest node. Also stored as node attribute `subregion`."""
    cfg = cfg or WorkspaceConfig()
    nodes = sorted(graph.nodes)
    if len(nodes) == 0:
        return {}
    if len(nodes) == 1:
        raw = np.array([1])
    else:
        condensed = squareform(subregion_distance(graph, cfg), checks=False)
        raw = fcluster(linkage(condensed, method="average"), t=cfg.subregion_cut, criterion="distance")
    _, first = np.unique(raw, return_index=True)
    renumber = {int(raw[i]): k for k, i in enumerate(np.sort(first))}
    labels = {n: renumber[int(r)] for n, r in zip(nodes, raw, strict=True)}
    nx.set_node_attributes(graph, labels, "subregion")
    return labels


def nearest_node(graph: nx.Graph, xz: np.ndarray) -> int | None:
    """Node whose position is nearest (Euclidean) to world (x, z); None for an empty graph."""
    if graph.number_of_nodes() == 0:
        return None
    d = np.linalg.norm(node_positions(graph) - np.asarray(xz, dtype=np.float64), axis=1)
    return sorted(graph.nodes)[int(np.argmin(d))]


def agent_subregion(graph: nx.Graph, labels: dict[int, int], agent_xz: np.ndarray) -> int | None:
    """The agent's subregion = that of its nearest node (docs/protocol.md §5); None for an empty graph."""
    node = nearest_node(graph, agent_xz)
    return None if node is None else labels[node]
