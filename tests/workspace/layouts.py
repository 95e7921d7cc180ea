"""Synthetic top-down layouts with known answers (no rendering)."""

from __future__ import annotations

import numpy as np

from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.topdown import GridGeometry, TopDownGrids, grids_from_alpha

RES = 0.05


def grids_from_layout(free: np.ndarray, obstacle: np.ndarray, cfg: WorkspaceConfig | None = None
                      ) -> TopDownGrids:
    """Grids at RES m/px with the origin at world (0, 0)."""
    cfg = cfg or WorkspaceConfig(resolution=RES)
    geometry = GridGeometry(origin=np.zeros(2), resolution=RES, shape=free.shape)
    return grids_from_alpha(geometry, free.astype(np.float32), obstacle.astype(np.float32), 0.0, cfg)


def box(shape: tuple[int, int], x0: float, x1: float, z0: float, z1: float) -> np.ndarray:
    """Boolean mask of pixels whose centre lies in [x0, x1] x [z0, z1] (metres)."""
    rows, cols = np.indices(shape)
    x, z = (cols + 0.5) * RES, (rows + 0.5) * RES
    return (x >= x0) & (x <= x1) & (z >= z0) & (z <= z1)


TWO_ROOMS_SHAPE = (80, 144)


def _two_rooms_walls() -> np.ndarray:
    walls = box(TWO_ROOMS_SHAPE, 0.3, 6.9, 0.3, 3.7) & ~box(TWO_ROOMS_SHAPE, 0.5, 6.7, 0.5, 3.5)
    return walls | (box(TWO_ROOMS_SHAPE, 3.5, 3.7, 0.5, 3.5) & ~box(TWO_ROOMS_SHAPE, 3.5, 3.7, 1.55, 2.45))


def two_rooms() -> TopDownGrids:
    """Two 3 x 3 m rooms side by side (x in [0.5, 3.5] and [3.7, 6.7], z in [0.5, 3.5]), separated by a
    0.2 m wall at x in [3.5, 3.7] with a 0.9 m door at z in [1.55, 2.45]."""
    walls = _two_rooms_walls()
    free = box(TWO_ROOMS_SHAPE, 0.5, 6.7, 0.5, 3.5) & ~walls
    return grids_from_layout(free, walls)


def two_rooms_seen_at_a_slant() -> TopDownGrids:
    """`two_rooms` as the left room sees it through the door at a grazing angle: all of the left room's
    floor, and of the door and the right room only a strip along the door's upper jamb (z >= 2.3); the
    rest of the right room is unknown (neither free nor obstacle)."""
    walls = _two_rooms_walls()
    free = box(TWO_ROOMS_SHAPE, 0.5, 3.5, 0.5, 3.5) | box(TWO_ROOMS_SHAPE, 3.5, 6.7, 2.3, 3.5)
    return grids_from_layout(free & ~walls, walls)


def corridor() -> TopDownGrids:
    """A 1 m wide, 5 m long corridor: free x in [0.5, 5.5], z in [1.0, 2.0], walls around it."""
    shape = (60, 120)
    free = box(shape, 0.5, 5.5, 1.0, 2.0)
    walls = box(shape, 0.3, 5.7, 0.8, 2.2) & ~free
    return grids_from_layout(free, walls)


def corridor_with_a_slot() -> TopDownGrids:
    """`corridor`'s 1 m wide corridor (x in [0.5, 4.0], z in [1.0, 2.0]) with an L-shaped dead-end slot
    0.2 m wide, thinner than the path clearance: east from the corridor's end along z in [1.4, 1.6] to
    x = 4.8, then north along x in [4.6, 4.8] up to z = 2.7. The straight line from the slot's far end
    back to the corridor crosses the wall between the two legs."""
    shape = (60, 120)
    free = box(shape, 0.5, 4.0, 1.0, 2.0) | box(shape, 4.0, 4.8, 1.4, 1.6) | box(shape, 4.6, 4.8, 1.4, 2.7)
    walls = box(shape, 0.3, 5.0, 0.8, 2.9) & ~free
    return grids_from_layout(free, walls)
