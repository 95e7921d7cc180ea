"""The area budget (MapperConfig "Area budget"): a place's Gaussians grow with the surface seen there.

The observed surface is counted the way ``benchmarks/mapper.py`` counts it: the 5 cm voxels hit by the
back-projected observed depth (every 4th pixel) of the mapped frames, each worth (5 cm)^2. The voxels
are grouped into cells (``area_budget_cell_m``, a multiple of 5 cm). After a mapped frame's iterations,
the cells of the current view are checked:

- the first time a view holds a cell whole (:meth:`ObservedSurface.cells_in_view`), the cell's
  *density* is set: its Gaussians per observed voxel then;
- from then on, a cell holding more than density x its observed voxels now x (1 + ``area_budget_slack``)
  loses the excess among the Gaussians this frame added and sees, the least opacity x in-plane area
  first. A view that holds the cell in part counts only the Gaussians of its frustum, so it can only
  count too few, never remove too many.

So a cell's Gaussians grow in proportion to the surface observed in it, and a revisit that sees nothing
new there optimises what the cell holds without adding to it. What the map held before the frame is
never removed.
"""

from __future__ import annotations

import numpy as np
import torch

from activesplat.geometry import backproject

SURFACE_VOXEL_M = 0.05
SURFACE_STRIDE_PX = 4
_BIAS = 1 << 20


def _pack(index: np.ndarray) -> np.ndarray:
    """One int64 per integer (M, 3) cell index (21 bits per axis)."""
    v = index.astype(np.int64) + _BIAS
    return (v[:, 0] << 42) | (v[:, 1] << 21) | v[:, 2]


def _unpack(keys: np.ndarray) -> np.ndarray:
    mask = (1 << 21) - 1
    return np.stack([(keys >> 42) & mask, (keys >> 21) & mask, keys & mask], axis=1) - _BIAS


def _lookup(sorted_keys: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions of ``keys`` in ``sorted_keys`` and whether each is there."""
    if len(sorted_keys) == 0:
        return np.zeros(len(keys), dtype=np.int64), np.zeros(len(keys), dtype=bool)
    at = np.minimum(np.searchsorted(sorted_keys, keys), len(sorted_keys) - 1)
    return at, sorted_keys[at] == keys


class ObservedSurface:
    """The observed surface as 5 cm voxels, with each cell's observed voxels and Gaussian density."""

    def __init__(self, cell_m: float):
        ratio = cell_m / SURFACE_VOXEL_M
        if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
            raise ValueError(f"the area budget's cell must be a multiple of {SURFACE_VOXEL_M} m, "
                             f"got {cell_m}")
        self.cell_m = SURFACE_VOXEL_M * round(ratio)
        self.ratio = int(round(ratio))
        self.voxels = np.zeros(0, dtype=np.int64)  # sorted keys of the observed 5 cm voxels
        self.cells = np.zeros(0, dtype=np.int64)  # sorted keys of the cells holding them
        self.counts = np.zeros(0, dtype=np.int64)  # observed voxels per cell
        self.density = np.zeros(0)  # Gaussians per observed voxel allowed in each cell (-1: not set yet)

    @property
    def area_m2(self) -> float:
        return len(self.voxels) * SURFACE_VOXEL_M ** 2

    def add(self, depth: np.ndarray, pose: np.ndarray, K: np.ndarray) -> np.ndarray:
        """Add the voxels one frame's observed depth (metres, 0 = invalid) hits; returns the sorted keys
        of the cells that gained observed area."""
        s = SURFACE_STRIDE_PX
        v, u = np.nonzero(depth[::s, ::s] > 0)
        if len(v) == 0:
            return np.zeros(0, dtype=np.int64)
        index = np.floor(backproject(depth, pose, K, s * v, s * u) / SURFACE_VOXEL_M).astype(np.int64)
        keys, first = np.unique(_pack(index), return_index=True)
        new = ~np.isin(keys, self.voxels, assume_unique=True)
        if not new.any():
            return np.zeros(0, dtype=np.int64)
        self.voxels = np.union1d(self.voxels, keys[new])
        grown, gained = np.unique(_pack(np.floor_divide(index[first[new]], self.ratio)), return_counts=True)
        cells = np.union1d(self.cells, grown)
        counts, density = np.zeros(len(cells), dtype=np.int64), np.full(len(cells), -1.0)
        old = np.searchsorted(cells, self.cells)
        counts[old], density[old] = self.counts, self.density
        counts[np.searchsorted(cells, grown)] += gained
        self.cells, self.counts, self.density = cells, counts, density
        return grown

    def cell_keys(self, points: np.ndarray) -> np.ndarray:
        """The cell key of each point (M, 3)."""
        return _pack(np.floor_divide(np.floor(points / SURFACE_VOXEL_M).astype(np.int64), self.ratio))

    def cell_area(self, keys: np.ndarray) -> np.ndarray:
        """Observed m^2 of each cell key (0 for a cell nothing was observed in)."""
        at, found = _lookup(self.cells, keys)
        return np.where(found, self.counts[at] if len(self.counts) else 0, 0) * SURFACE_VOXEL_M ** 2

    def cells_in_view(self, keys: np.ndarray, pose: np.ndarray, K: np.ndarray, width: int,
                      height: int) -> np.ndarray:
        """Whether the view (camera-to-world ``pose``) holds each cell whole: all eight corners in front
        of the camera (at least 5 cm) and inside the image."""
        lo = _unpack(keys) * self.cell_m
        corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float) * self.cell_m
        world = lo[:, None, :] + corners[None]  # (M, 8, 3)
        w2c = np.linalg.inv(pose)
        cam = world @ w2c[:3, :3].T + w2c[:3, 3]
        z = cam[..., 2]
        safe = np.maximum(z, 1e-6)
        u = K[0, 0] * cam[..., 0] / safe + K[0, 2]
        v = K[1, 1] * cam[..., 1] / safe + K[1, 2]
        inside = (z > 0.05) & (u >= 0) & (u <= width) & (v >= 0) & (v <= height)
        return inside.all(axis=1)

    def enforce(self, means: np.ndarray, removable: np.ndarray, worth: np.ndarray, whole: callable,
                slack: float) -> np.ndarray:
        """Densities first (module docstring), then which of the ``removable`` Gaussians to remove.

        ``means`` are the centres of every Gaussian a cell's count includes, ``removable`` indices into
        them of those that may go, least ``worth`` (one per removable) first; ``whole(keys)`` says which
        cells the view holds whole. Returns positions in ``removable``. A cell whose excess exceeds its
        removable Gaussians loses all of those."""
        keys = self.cell_keys(means)
        cells, count = np.unique(keys, return_counts=True)
        at, found = _lookup(self.cells, cells)
        at = at[found]
        cells, count = cells[found], count[found]
        density, voxels = self.density[at], self.counts[at]
        allowed = np.ceil(density * voxels * (1.0 + slack)).astype(np.int64)
        first = density < 0
        over = ~first & (count > allowed)
        new = first.copy()
        new[first] = whole(cells[first])  # a density is set only where the view holds the cell whole
        self.density[at[new]] = count[new] / voxels[new]
        excess = np.where(over, count - allowed, 0)
        if not (excess > 0).any() or len(removable) == 0:
            return np.zeros(0, dtype=np.int64)
        pos = np.searchsorted(cells, keys[removable])
        pos = np.minimum(pos, len(cells) - 1)
        candidates = np.flatnonzero((cells[pos] == keys[removable]) & (excess[pos] > 0))
        pos = pos[candidates]
        order = np.lexsort((candidates, worth[candidates], pos))  # by cell, then least worth, then index
        candidates, pos = candidates[order], pos[order]
        start = np.ones(len(pos), dtype=bool)
        start[1:] = pos[1:] != pos[:-1]
        rank = np.arange(len(pos)) - np.maximum.accumulate(np.where(start, np.arange(len(pos)), 0))
        return candidates[rank < excess[pos]]


def worth(log_scales: torch.Tensor, opacity_logits: torch.Tensor) -> np.ndarray:
    """Opacity x in-plane area (the product of the two largest scales) of each Gaussian."""
    top2 = torch.topk(log_scales.detach(), 2, dim=1).values.sum(dim=1)
    return (torch.sigmoid(opacity_logits.detach().reshape(-1)) * torch.exp(top2)).cpu().numpy()
