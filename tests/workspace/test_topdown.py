"""Top-down render of hand-made Gaussians, grid geometry, config checks and the topdown.png drawing."""

from __future__ import annotations

from types import SimpleNamespace

import networkx as nx
import numpy as np
import pytest
import torch
from layouts import RES, box, grids_from_layout, two_rooms

from activesplat.errors import InvalidInputError
from activesplat.workspace.clean import agent_region, extract_workspace
from activesplat.workspace.config import WorkspaceConfig
from activesplat.workspace.draw import draw_topdown
from activesplat.workspace.paths import plan_safe_path
from activesplat.workspace.subregions import partition_subregions
from activesplat.workspace.topdown import GridGeometry, observed_ground, render_topdown
from activesplat.workspace.voronoi import build_voronoi_graph

FLOOR = 0.3  # floor height, not 0, so the height bands are really relative to it


def gaussians(points: np.ndarray, scale: float) -> SimpleNamespace:
    """A Gaussian map with isotropic, opaque, grey Gaussians at `points` (N, 3)."""
    n = len(points)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    return SimpleNamespace(means=torch.as_tensor(points, dtype=torch.float32), quats=quats,
                           scales=torch.full((n, 3), scale), opacities=torch.full((n,), 0.95),
                           colors=torch.full((n, 3), 0.5))


def floor_and_box(floor_step: float = 0.05, rows_every: int = 1, offset: float = 0.0) -> SimpleNamespace:
    """Floor patch x, z in [offset, 2] at FLOOR (every `rows_every`-th row of samples along z), and a box
    obstacle x, z in [0.82, 1.18] from FLOOR + 0.2 to FLOOR + 1.0; plus a lamp above the agent height."""
    xs = np.arange(offset, 2.0 + 1e-9, floor_step)
    zs = xs[::rows_every]
    fx, fz = np.meshgrid(xs, zs)
    floor = np.stack([fx.ravel(), np.full(fx.size, FLOOR), fz.ravel()], axis=1)
    b = np.arange(0.82, 1.18 + 1e-9, 0.04)
    bx, by, bz = np.meshgrid(b, np.arange(FLOOR + 0.2, FLOOR + 1.0, 0.25), b)
    box = np.stack([bx.ravel(), by.ravel(), bz.ravel()], axis=1)
    lamp = np.array([[0.3, FLOOR + 2.2, 0.3]])
    return gaussians(np.concatenate([floor, box, lamp]), scale=0.02)


def cell(grids, x: float, z: float) -> tuple[int, int]:
    r, c = grids.geometry.pixel_index(np.array([x, z]))
    return int(r), int(c)


@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_render_floor_and_box_gives_free_obstacle_unknown(backend):
    gmap = floor_and_box(floor_step=0.1 if backend == "torch" else 0.05)
    cfg = WorkspaceConfig(resolution=0.1 if backend == "torch" else 0.05)
    grids = render_topdown(gmap, FLOOR, cfg, agent_xz=np.array([3.5, 1.0]), backend=backend)
    # Bounds grow with the band Gaussians and the agent (padded), never beyond.
    x_min, x_max, z_min, z_max = grids.geometry.extent
    assert x_min <= -0.5 + 1e-6 and x_max >= 4.0 - 1e-6 and z_min <= -0.5 + 1e-6 and z_max >= 2.5 - 1e-6
    assert x_max < 4.0 + 2 * cfg.resolution and z_max < 2.5 + 2 * cfg.resolution
    assert grids.free[cell(grids, 0.4, 1.6)] and grids.free[cell(grids, 1.6, 0.4)]
    assert grids.obstacle[cell(grids, 1.0, 1.0)] and not grids.free[cell(grids, 1.0, 1.0)]
    assert grids.unknown[cell(grids, 3.0, 1.0)] and grids.unknown[cell(grids, 1.0, 2.3)]
    # The lamp is above the agent height: not an obstacle, and the floor under it is free.
    assert grids.free[cell(grids, 0.3, 0.3)]
    # Every pixel is exactly one of free / obstacle / unknown.
    total = grids.free.astype(int) + grids.obstacle.astype(int) + grids.unknown.astype(int)
    assert (total == 1).all()
    # The box footprint (0.4 m square) is its obstacle area, give or take a pixel ring.
    side = 0.4 / cfg.resolution
    assert (side - 1) ** 2 <= grids.obstacle.sum() <= (side + 3) ** 2


def test_sparse_far_floor_reads_as_observed_ground():
    """Floor rows 0.15 m apart (every third pixel row, samples at pixel centres) render as stripes with
    the release rule; the ground closing fills them."""
    gmap = floor_and_box(rows_every=3, offset=0.025)
    agent = np.array([1.0, 1.0])
    release = render_topdown(gmap, FLOOR, WorkspaceConfig(ground_closing=0.0), agent, backend="numba")
    closed = render_topdown(gmap, FLOOR, WorkspaceConfig(), agent, backend="numba")
    r0, c0 = cell(closed, 0.2, 0.2)
    r1, c1 = cell(closed, 0.6, 1.8)
    patch = (slice(r0, r1), slice(c0, c1))
    assert 0.2 < release.free[patch].mean() < 0.7
    assert closed.free[patch].all()
    # Closing does not grow the observed floor outwards.
    assert not closed.free[cell(closed, 2.2, 1.0)] and not closed.free[cell(closed, 1.0, -0.2)]


def test_observed_ground_closing_fills_gaps_but_not_wide_ones():
    cfg = WorkspaceConfig()
    k = cfg.ground_closing_px
    assert k == 13  # 0.65 m at 0.05 m/px
    for gap, closed in ((k - 1, True), (k, False)):
        alpha = np.zeros((40, 60), np.float32)
        alpha[5:35, 2:20] = 1.0
        alpha[5:35, 20 + gap:55] = 1.0
        observed = observed_ground(alpha, cfg)
        assert observed[10, 20:20 + gap].all() == closed
        # Never grows the observed floor outwards.
        assert not observed[:5].any() and not observed[35:].any() and not observed[:, 55:].any()
    assert (observed_ground(alpha, WorkspaceConfig(ground_closing=0.0)) == (alpha > 0.4)).all()


def test_render_of_an_empty_map_is_all_unknown():
    gmap = gaussians(np.zeros((0, 3)), 0.02)
    grids = render_topdown(gmap, 0.0, WorkspaceConfig(), agent_xz=np.array([1.0, 2.0]), backend="numba")
    assert grids.unknown.all()
    workspace = extract_workspace(grids, np.array([1.0, 2.0]), WorkspaceConfig())
    assert workspace.empty and build_voronoi_graph(workspace).number_of_nodes() == 0


@pytest.mark.parametrize("agent_xz", [(3.9, 1.0), (4.02, 1.02)], ids=["beside the speck", "on the speck"])
def test_a_speck_the_opening_removes_does_not_empty_the_workspace(agent_xz):
    """The agent stands on unobserved floor 0.1 m from a speck of free floor (or on the speck), 1.4 m from
    a 2 x 2 m room (too far for the ground closing to join them): the nearest region would be the speck,
    which the workspace's opening removes; the workspace is the room instead."""
    shape = (60, 100)
    room = box(shape, 0.5, 2.5, 0.5, 2.5)
    speck = box(shape, 4.0, 4.05, 1.0, 1.05)  # 1 x 1 px
    grids = grids_from_layout(room | speck, np.zeros(shape, bool))
    cfg = WorkspaceConfig(resolution=RES)
    workspace = extract_workspace(grids, np.array(agent_xz), cfg)
    assert not workspace.empty
    assert workspace.mask[room].mean() > 0.9 and not workspace.mask[speck].any()
    # without the opening's kernel the speck is the nearest region, and nothing survives its opening
    rc = grids.geometry.pixel_index(np.array(agent_xz))
    assert (agent_region(grids.free, rc) == speck).all()
    region = agent_region(grids.free, rc, cfg.open_kernel)
    assert region[room].mean() > 0.9 and not region[speck].any() and not region[~room].any()


def test_grid_geometry_round_trip():
    geometry = GridGeometry(origin=np.array([-1.0, 2.0]), resolution=0.05, shape=(30, 40))
    xz = np.array([[-0.975, 2.025], [0.91, 3.41]])
    rc = geometry.pixel_index(xz)
    np.testing.assert_array_equal(rc, [[0, 0], [28, 38]])
    np.testing.assert_allclose(geometry.pixel_to_world(rc + 0.5), [[-0.975, 2.025], [0.925, 3.425]])
    assert geometry.contains(rc).all() and not geometry.contains(np.array([30, 0]))


@pytest.mark.parametrize("field, value", [("resolution", 0.0), ("floor_margin", 2.0), ("ground_opacity", 1.0),
                                          ("ground_closing", -0.1)])
def test_config_rejects_bad_values(field, value):
    with pytest.raises(InvalidInputError, match=field):
        WorkspaceConfig(**{field: value})


def test_render_rejects_bad_floor_height():
    with pytest.raises(InvalidInputError, match="floor_height"):
        render_topdown(floor_and_box(), float("nan"), WorkspaceConfig(), backend="numba")


def test_draw_topdown_writes_a_png(tmp_path):
    grids = two_rooms()
    cfg = WorkspaceConfig(resolution=RES)
    agent = np.array([1.0, 1.0])
    workspace = extract_workspace(grids, agent, cfg)
    graph = build_voronoi_graph(workspace, cfg)
    partition_subregions(graph, cfg)
    path = plan_safe_path(graph, workspace, agent, np.array([6.0, 3.0]), cfg)
    out = draw_topdown(tmp_path / "sub" / "topdown.png", grids, workspace, graph, path=path,
                       trajectory=np.array([[1.0, 1.0], [1.2, 1.1]]), title="two rooms")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.image

    image = matplotlib.image.imread(out)
    assert image.shape[0] > 100 and image.shape[1] > 100
    # Grids alone (no workspace, no graph) and an empty graph draw too.
    draw_topdown(tmp_path / "bare.png", grids, graph=nx.Graph())
    assert (tmp_path / "bare.png").stat().st_size > 0
