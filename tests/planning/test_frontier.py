import numpy as np
import pytest

from activesplat.errors import InvalidInputError
from activesplat.planning.frontier import descend, frontier_cells, grid_distances
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
