import numpy as np
import pytest

from activesplat.errors import InvalidInputError
from activesplat.planning.frontier import (
    FrontierConfig,
    descend,
    frontier_cells,
    grid_distances,
    nearest_frontier_path,
)
from activesplat.planning.policies import POLICY_NAMES, make_policy


def test_frontier_cells_border_unknown_space():
    free = np.zeros((10, 10), bool)
    free[2:8, 2:5] = True
    unknown = np.zeros((10, 10), bool)
    unknown[2:8, 5:9] = True
    f = frontier_cells(free, unknown)
    assert f[2:8, 4].all() and f.sum() == 6


def test_grid_distances_go_around_a_wall_and_descend_back():
    passable = np.ones((9, 9), bool)
    passable[0:7, 4] = False  # wall with a gap at the bottom
    dist = grid_distances(passable, (0, 0))
    assert dist[0, 8] > 8  # must go around, not through
    assert np.isinf(grid_distances(passable, (20, 20))).all()
    path = descend(dist, (0, 8))
    assert path[0] == (0, 0) and path[-1] == (0, 8)
    assert all(passable[r, c] for r, c in path)
    assert all(max(abs(a[0] - b[0]), abs(a[1] - b[1])) == 1 for a, b in zip(path, path[1:], strict=False))


def test_unknown_policy_is_a_clear_error():
    with pytest.raises(InvalidInputError, match="unknown policy 'nope'"):
        make_policy("nope", world=None, floor_height=0.0)
    assert {"activesplat", "fbe", "random", "position", "viewpoint", "no-hp"} <= set(POLICY_NAMES)


def test_policies_start_with_the_bootstrap_look_around():
    for name in POLICY_NAMES:
        p = make_policy(name, world=None, floor_height=0.0)
        assert p.queue[:2] == ["turn_left", "look_down"]
        assert p.queue.count("turn_left") == 36 and len(p.queue) == 72


def _layout(free, obstacle):
    """Top-down grids and workspace of a synthetic layout (no map, no rendering)."""
    from activesplat.workspace.clean import extract_workspace
    from activesplat.workspace.config import WorkspaceConfig
    from activesplat.workspace.topdown import GridGeometry, grids_from_alpha

    cfg = WorkspaceConfig(resolution=0.05)
    geometry = GridGeometry(origin=np.zeros(2), resolution=0.05, shape=free.shape)
    grids = grids_from_alpha(geometry, free.astype(np.float32), obstacle.astype(np.float32), 0.0, cfg)
    here = np.array([1.0, 1.0])
    return grids, extract_workspace(grids, here, cfg), here, cfg


def test_fbe_goes_to_the_nearest_frontier_and_not_back_to_a_reached_one():
    # a 3 x 2 m room, walls all around except its right side, which is unknown
    rows, cols = np.indices((60, 100))
    x, z = (cols + 0.5) * 0.05, (rows + 0.5) * 0.05
    free = (x > 0.3) & (x < 3.0) & (z > 0.3) & (z < 2.3)
    walls = ((x > 0.15) & (x < 3.0) & (z > 0.15) & (z < 2.45)) & ~free
    grids, ws, here, cfg = _layout(free, walls)
    path = nearest_frontier_path(grids, ws, here, [], cfg, FrontierConfig())
    assert path is not None and path[-1][0] > 2.5  # the frontier is the room's open right side
    again = nearest_frontier_path(grids, ws, here, [path[-1]], cfg, FrontierConfig())  # reached
    assert again is None or np.hypot(*(again[-1] - path[-1])) > 0.5


def test_fbe_forgets_its_failed_goals_when_no_frontier_is_reachable(monkeypatch):
    """Frontiers left but none reachable from here (the failed goals cover the reachable ones): escape,
    look around, and give every frontier a second chance; keeping the failures trapped the agent."""
    from types import SimpleNamespace

    import activesplat.planning.frontier as frontier_module
    from activesplat.workspace.plan import Plan

    monkeypatch.setattr(frontier_module, "build_plan", lambda *a, **k: Plan())
    monkeypatch.setattr(frontier_module, "nearest_frontier_path", lambda *a, **k: None)
    p = make_policy("fbe", world=SimpleNamespace(gaussians=None), floor_height=0.0)
    p.queue.clear(), p.queue_causes.clear()  # the bootstrap
    p.failed.append(np.array([1.0, 1.0]))
    p.reached.append(np.array([2.0, 1.0]))
    p.replan(np.eye(4))
    assert not p.failed and not p.reached
    assert p.queue_causes[0] == "escape" and p.queue_causes[-1] == "idle"


def test_the_frontier_policy_is_named_where_topdown_png_draws_its_frontiers():
    from activesplat.planning.frontier import FrontierExplorer
    from activesplat.workspace.draw import FRONTIER_POLICIES

    assert FrontierExplorer.name in FRONTIER_POLICIES
