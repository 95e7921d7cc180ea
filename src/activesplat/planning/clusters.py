"""DBSCAN over the set pixels of a boolean image, on the pixel grid (the panorama and high-loss clusters
of paper sec. III-B).

:func:`grid_dbscan` gives the labels scikit-learn's ``DBSCAN(eps, min_samples).fit(np.argwhere(mask))``
gives, label for label (tested against it), without its neighbour search: on a grid the neighbours of a
pixel are the set pixels at a fixed list of offsets, those with squared distance at most eps². What
DBSCAN does, and so what this reproduces:

- a pixel is a core pixel when at least ``min_samples`` set pixels (itself included) lie within eps;
- core pixels within eps of each other are in the same cluster; clusters are numbered in the order of
  their first core pixel in row-major order (scikit-learn expands a cluster from each core pixel not yet
  labelled, in input order, and ``np.argwhere`` lists pixels in row-major order);
- a set pixel that is not core but lies within eps of a core pixel joins the first-numbered such cluster
  (the first expansion that reaches it labels it); any other pixel is noise (-1).

A replan clustered every scoring panorama twice with scikit-learn (rotation targets and hulls), ~8 ms
each, about as long as rendering the panorama; this takes well under a millisecond.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def disk_offsets(eps: float) -> np.ndarray:
    """(k, 2) int64 (row, col) offsets with row² + col² <= eps², the origin included, row-major."""
    r = int(np.floor(eps))
    d = np.arange(-r, r + 1)
    dr, dc = np.meshgrid(d, d, indexing="ij")
    keep = (dr * dr + dc * dc).astype(np.float64) <= float(eps) * float(eps)
    return np.stack([dr[keep], dc[keep]], axis=1).astype(np.int64)


@njit(cache=True)
def _find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True)
def _grid_dbscan(mask, offsets, min_samples):
    h, w = mask.shape
    index = np.full((h, w), -1, np.int64)  # row-major rank of each set pixel
    n = 0
    for i in range(h):
        for j in range(w):
            if mask[i, j]:
                index[i, j] = n
                n += 1
    rows = np.empty(n, np.int64)
    cols = np.empty(n, np.int64)
    for i in range(h):
        for j in range(w):
            k = index[i, j]
            if k >= 0:
                rows[k], cols[k] = i, j
    core = np.zeros(n, np.bool_)
    for k in range(n):
        count = 0
        for o in range(offsets.shape[0]):
            i, j = rows[k] + offsets[o, 0], cols[k] + offsets[o, 1]
            if 0 <= i < h and 0 <= j < w and mask[i, j]:
                count += 1
        core[k] = count >= min_samples
    parent = np.arange(n)
    for k in range(n):  # union the core pixels within eps of each other
        if not core[k]:
            continue
        for o in range(offsets.shape[0]):
            i, j = rows[k] + offsets[o, 0], cols[k] + offsets[o, 1]
            if 0 <= i < h and 0 <= j < w:
                m = index[i, j]
                if m > k and core[m]:
                    a, b = _find(parent, k), _find(parent, m)
                    if a != b:
                        parent[max(a, b)] = min(a, b)  # a root is its component's first core pixel
    labels = np.full(n, -1, np.int64)
    root_label = np.full(n, -1, np.int64)
    next_label = 0
    for k in range(n):  # cores in row-major order: a component's label is fixed at its first core pixel
        if core[k]:
            root = _find(parent, k)
            if root_label[root] < 0:
                root_label[root] = next_label
                next_label += 1
            labels[k] = root_label[root]
    for k in range(n):  # border pixels: the lowest label among the core pixels within eps
        if core[k]:
            continue
        best = -1
        for o in range(offsets.shape[0]):
            i, j = rows[k] + offsets[o, 0], cols[k] + offsets[o, 1]
            if 0 <= i < h and 0 <= j < w:
                m = index[i, j]
                if m >= 0 and core[m] and (best < 0 or labels[m] < best):
                    best = labels[m]
        labels[k] = best
    return labels


def grid_dbscan(mask: np.ndarray, eps: float, min_samples: int) -> np.ndarray:
    """DBSCAN labels (-1: noise) of the set pixels of the 2D boolean ``mask``, in ``np.argwhere(mask)``
    order: those of ``sklearn.cluster.DBSCAN(eps=eps, min_samples=min_samples)`` on those pixels'
    (row, col) coordinates (module docstring)."""
    mask = np.ascontiguousarray(mask, dtype=np.bool_)
    if mask.ndim != 2:
        raise ValueError(f"grid_dbscan: expected a 2D mask, got shape {mask.shape}")
    if not eps > 0:
        raise ValueError(f"grid_dbscan: eps must be positive, got {eps}")
    return _grid_dbscan(mask, disk_offsets(eps), int(min_samples))
