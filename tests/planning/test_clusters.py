"""The pixel-grid DBSCAN against scikit-learn's, label for label."""

import numpy as np
import pytest
from sklearn.cluster import DBSCAN

from activesplat.planning.clusters import disk_offsets, grid_dbscan


def _sklearn_labels(mask, eps, min_samples):
    pix = np.argwhere(mask)
    if len(pix) == 0:
        return np.zeros(0, np.int64)
    return DBSCAN(eps=eps, min_samples=min_samples).fit(pix).labels_


def _blobs(rng, shape, density):
    """Random pixels plus a few filled discs and thin lines: cores, borders, bridges and noise."""
    mask = rng.random(shape) < density
    rr, cc = np.mgrid[: shape[0], : shape[1]]
    for _ in range(rng.integers(1, 6)):
        r0, c0, rad = rng.integers(0, shape[0]), rng.integers(0, shape[1]), rng.integers(2, 9)
        mask |= (rr - r0) ** 2 + (cc - c0) ** 2 <= rad * rad
    for _ in range(rng.integers(0, 3)):
        mask[rng.integers(0, shape[0]), rng.integers(0, shape[1]):] = True
    return mask


@pytest.mark.parametrize("eps,min_samples", [(5.0, 10), (5.0, 25), (3.5, 6), (1.0, 2), (2.2, 1), (5.0, 60)])
def test_grid_dbscan_matches_sklearn(eps, min_samples):
    rng = np.random.default_rng(int(eps * 10) + min_samples)
    for trial in range(12):
        shape = (int(rng.integers(5, 60)), int(rng.integers(5, 90)))
        mask = _blobs(rng, shape, density=float(rng.choice([0.02, 0.1, 0.3])))
        ours = grid_dbscan(mask, eps, min_samples)
        np.testing.assert_array_equal(ours, _sklearn_labels(mask, eps, min_samples),
                                      err_msg=f"trial {trial}, shape {shape}")


def test_border_pixel_between_two_clusters_takes_the_first():
    """A non-core pixel within eps of two clusters joins the one whose first core pixel comes first."""
    mask = np.zeros((7, 11), bool)
    mask[2:5, 0:3] = True  # cluster 0 (row-major first)
    mask[2:5, 8:11] = True  # cluster 1
    mask[3, 5] = True  # 2.x px from both, too few neighbours to be core
    ours = grid_dbscan(mask, 3.0, 6)
    np.testing.assert_array_equal(ours, _sklearn_labels(mask, 3.0, 6))
    assert ours[np.flatnonzero(np.argwhere(mask)[:, 1] == 5)[0]] == 0


def test_grid_dbscan_edge_cases():
    assert grid_dbscan(np.zeros((4, 4), bool), 5.0, 3).shape == (0,)
    np.testing.assert_array_equal(grid_dbscan(np.ones((1, 1), bool), 5.0, 2), [-1])
    np.testing.assert_array_equal(grid_dbscan(np.ones((1, 1), bool), 5.0, 1), [0])
    assert len(disk_offsets(5.0)) == 81  # the 81 integer offsets within radius 5, the rim included
    with pytest.raises(ValueError, match="2D"):
        grid_dbscan(np.ones(5, bool), 5.0, 3)
    with pytest.raises(ValueError, match="eps"):
        grid_dbscan(np.ones((3, 3), bool), 0.0, 3)
