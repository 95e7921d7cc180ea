"""Navigability map built from the mesh: a top-down floor grid where the agent cylinder fits.

A cell is navigable when there is floor beneath the agent's whole disc (near-horizontal surfaces
within `step_margin` of the floor height) and no geometry between `floor + step_margin` and
`floor + agent_height` lies within `agent_radius` of any point of the cell (docs/protocol.md §1: agent
radius 0.1 m, height 1.5 m).
The mesh is sampled densely (spacing <= half a cell), the samples in the height band are rasterised
into an occupancy grid, and the clearance is the Euclidean distance transform of that grid. Cell
centres need clearance > radius + 2 cells (sample spacing plus both half-cell diagonals), so any
position inside a navigable cell keeps the true radius from every obstacle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, sparse

from activesplat.sim.config import SimConfig

_MAX_POINTS_PER_CHUNK = 2_000_000
MAX_NAV_CELLS = 32_000_000
"""Largest navigability grid (cells): 20,000 m^2 at the default 2.5 cm cell, about 1 GB while it is built.
A grid beyond it means a mesh in millimetres or centimetres, or stray geometry far from the building."""


class GridTooLargeError(ValueError):
    """The geometry near the floor spans more than MAX_NAV_CELLS grid cells; `lo` / `hi` its (x, z)
    corners and `shape` the grid it would need."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, shape: tuple[int, int]):
        super().__init__(f"geometry near the floor spans {hi[0] - lo[0]:.1f} x {hi[1] - lo[1]:.1f} m")
        self.lo, self.hi, self.shape = lo, hi, shape


@dataclass
class NavMap:
    """Grid indexed [ix, iz]; cell (ix, iz) covers x in origin[0] + [ix, ix+1) * resolution (same
    for z). `grid`: navigable cells; `largest`: the largest 4-connected navigable component."""

    grid: np.ndarray
    floor: np.ndarray
    clearance: np.ndarray
    largest: np.ndarray
    origin: np.ndarray
    resolution: float
    floor_height: float

    def cell_of(self, x, z) -> tuple[np.ndarray, np.ndarray]:
        ix = np.floor((np.asarray(x, dtype=np.float64) - self.origin[0]) / self.resolution).astype(np.int64)
        iz = np.floor((np.asarray(z, dtype=np.float64) - self.origin[1]) / self.resolution).astype(np.int64)
        return ix, iz

    def cell_centre(self, ix, iz) -> np.ndarray:
        return self.origin + (np.stack([ix, iz], axis=-1) + 0.5) * self.resolution

    def is_navigable(self, x, z):
        """True where the agent can stand at (x, z) (vectorised; outside the grid is False)."""
        ix, iz = self.cell_of(x, z)
        inside = (ix >= 0) & (iz >= 0) & (ix < self.grid.shape[0]) & (iz < self.grid.shape[1])
        out = np.zeros(np.shape(ix), dtype=bool)
        out[inside] = self.grid[ix[inside], iz[inside]]
        return out if out.ndim else bool(out)

    def segment_free(self, start, end) -> bool:
        """True when every point of the straight segment start -> end (x, z) is navigable."""
        start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
        n = int(np.ceil(np.linalg.norm(end - start) / (0.25 * self.resolution))) + 1
        pts = start + np.linspace(0.0, 1.0, n)[:, None] * (end - start)
        return bool(np.all(self.is_navigable(pts[:, 0], pts[:, 1])))

    def sample_navigable(self, rng: np.random.Generator) -> np.ndarray:
        """A seeded random cell centre (x, z) of the largest connected component."""
        cells = np.argwhere(self.largest)
        ix, iz = cells[int(rng.integers(len(cells)))]
        return self.cell_centre(ix, iz)

    @property
    def navigable_area(self) -> float:
        return float(self.grid.sum()) * self.resolution**2

    def components(self) -> tuple[np.ndarray, int]:
        """4-connected component labels of the navigable grid and their count."""
        return ndimage.label(self.grid)


def _barycentric_lattice(n: int) -> np.ndarray:
    """(m, 3) barycentric coordinates of the regular lattice with n divisions per edge."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = i + j <= n
    a, b = i[keep] / n, j[keep] / n
    return np.stack([1.0 - a - b, a, b], axis=1)


def sample_triangles(triangles: np.ndarray, spacing: float):
    """Yield (points (k, 3), triangle index (k,)) chunks, lattice spacing <= `spacing` per triangle."""
    edges = np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2).max(axis=1)
    divisions = np.clip(np.ceil(edges / spacing), 1, 2000).astype(np.int64)
    for n in np.unique(divisions):
        lattice = _barycentric_lattice(int(n))
        idx = np.flatnonzero(divisions == n)
        per_chunk = max(1, _MAX_POINTS_PER_CHUNK // len(lattice))
        for s in range(0, len(idx), per_chunk):
            chunk = idx[s : s + per_chunk]
            pts = np.einsum("mk,tkd->tmd", lattice, triangles[chunk]).reshape(-1, 3)
            yield pts, np.repeat(chunk, len(lattice))


def _floor_support(floor: np.ndarray, config: SimConfig) -> np.ndarray:
    """Cells whose whole agent disc (agent_radius) stands on floor; holes of up to
    `floor_hole_cells` cells (scan gaps) are closed first, so they do not erode the floor."""
    closed = ndimage.binary_closing(floor, iterations=config.floor_hole_cells) | floor
    support = ndimage.distance_transform_edt(closed) * config.nav_cell
    return floor & (support > config.agent_radius)


def build_navmap(vertices: np.ndarray, faces: np.ndarray, floor_height: float,
                 config: SimConfig | None = None) -> NavMap:
    """Rasterise floor and obstacle-band samples of the mesh, then threshold the clearance."""
    config = config or SimConfig()
    cell = config.nav_cell
    triangles = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    up = np.abs(normals[:, 1]) > 0.7 * np.linalg.norm(normals, axis=1)
    y_lo, y_hi = floor_height + config.step_margin, floor_height + config.agent_height
    relevant = triangles[:, :, 1].min(axis=1) <= y_hi
    relevant &= triangles[:, :, 1].max(axis=1) >= floor_height - config.step_margin
    triangles, up = triangles[relevant], up[relevant]
    if len(triangles) == 0:
        raise ValueError("no geometry near the floor height")
    lo = triangles.reshape(-1, 3).min(axis=0)[[0, 2]] - 4 * cell
    hi = triangles.reshape(-1, 3).max(axis=0)[[0, 2]] + 4 * cell
    shape = tuple(int(n) for n in np.ceil((hi - lo) / cell))
    if shape[0] * shape[1] > MAX_NAV_CELLS:  # checked before anything of that size is allocated
        raise GridTooLargeError(lo + 4 * cell, hi - 4 * cell, shape)
    floor = np.zeros(shape, dtype=bool)
    occupied = np.zeros(shape, dtype=bool)
    for pts, tri in sample_triangles(triangles, 0.5 * cell):
        ix = ((pts[:, 0] - lo[0]) / cell).astype(np.int64)
        iz = ((pts[:, 2] - lo[1]) / cell).astype(np.int64)
        y = pts[:, 1]
        on_floor = up[tri] & (np.abs(y - floor_height) <= config.step_margin)
        floor[ix[on_floor], iz[on_floor]] = True
        band = (y > y_lo) & (y <= y_hi)
        occupied[ix[band], iz[band]] = True
    clearance = ndimage.distance_transform_edt(~occupied) * cell
    grid = _floor_support(floor, config) & (clearance > config.agent_radius + 2 * cell)
    labels, n = ndimage.label(grid)
    if n == 0:
        largest = grid.copy()
    else:
        sizes = np.bincount(labels.ravel())[1:]
        largest = labels == (int(np.argmax(sizes)) + 1)
    return NavMap(grid=grid, floor=floor, clearance=clearance, largest=largest, origin=lo,
                  resolution=cell, floor_height=float(floor_height))


def grid_graph(mask: np.ndarray, resolution: float) -> tuple[sparse.csr_matrix, np.ndarray]:
    """8-connected graph of the True cells of `mask` (edge lengths in metres) and the (ix, iz) of each
    node."""
    cells = np.argwhere(mask)
    index = -np.ones(mask.shape, dtype=np.int64)
    index[cells[:, 0], cells[:, 1]] = np.arange(len(cells))
    rows, cols, lengths = [], [], []
    for dx, dz in ((1, 0), (0, 1), (1, 1), (1, -1)):
        nx, nz = cells[:, 0] + dx, cells[:, 1] + dz
        ok = (nx >= 0) & (nz >= 0) & (nx < mask.shape[0]) & (nz < mask.shape[1])
        j = np.full(len(cells), -1)
        j[ok] = index[nx[ok], nz[ok]]
        # a diagonal step only where both cells beside it are free too (no corner cutting)
        if dx and dz:
            side_a = np.zeros(len(cells), bool)
            side_b = np.zeros(len(cells), bool)
            side_a[ok] = mask[nx[ok], cells[ok, 1]]
            side_b[ok] = mask[cells[ok, 0], nz[ok]]
            j[~(side_a & side_b)] = -1
        keep = j >= 0
        rows.append(np.nonzero(keep)[0])
        cols.append(j[keep])
        lengths.append(np.full(int(keep.sum()), resolution * math.hypot(dx, dz)))
    r, c, w = (np.concatenate(a) for a in (rows, cols, lengths))
    g = sparse.coo_matrix((w, (r, c)), shape=(len(cells), len(cells))).tocsr()
    return g.maximum(g.T), cells
