"""The area budget (MapperConfig "Area budget", splat/budget.py)."""

import numpy as np
import pytest
import torch
from _synthetic import intrinsics, observe, pose

from activesplat.errors import InvalidInputError
from activesplat.splat import Mapper, MapperConfig
from activesplat.splat.budget import SURFACE_VOXEL_M, ObservedSurface
from activesplat.splat.config import Schedule

S = 32


def test_the_observed_surface_counts_5cm_voxels_per_cell_and_names_the_cells_that_grew():
    cam = pose()
    _rgb, depth = observe(cam, S)
    surface = ObservedSurface(0.2)
    grown = surface.add(depth, cam, intrinsics(S))
    n = len(surface.voxels)
    assert n > 0 and surface.area_m2 == pytest.approx(n * SURFACE_VOXEL_M ** 2)
    assert len(grown) > 0 and surface.counts.sum() == n
    assert np.allclose(surface.cell_area(surface.cells).sum(), surface.area_m2)
    assert len(surface.add(depth, cam, intrinsics(S))) == 0 and len(surface.voxels) == n  # nothing new
    _rgb, shifted = observe(pose(tx=0.3), S)
    assert len(surface.add(shifted, pose(tx=0.3), intrinsics(S))) > 0 and len(surface.voxels) > n
    assert len(surface.add(np.zeros((S, S), np.float32), cam, intrinsics(S))) == 0


def _one_cell(count: int) -> tuple[ObservedSurface, np.ndarray]:
    """A surface with one observed cell [0, 0.2)^3 and ``count`` centres in it, plus one centre in a cell
    nothing was observed in."""
    surface = ObservedSurface(0.2)
    surface.voxels = np.array([1], dtype=np.int64)
    surface.cells = surface.cell_keys(np.array([[0.1, 0.1, 0.1]]))
    surface.counts, surface.density = np.array([4]), np.array([-1.0])
    means = np.vstack([np.full((count, 3), 0.1) + 0.001 * np.arange(count)[:, None], [[5.0, 5.0, 5.0]]])
    return surface, means


def test_a_cell_keeps_its_first_density_and_loses_its_least_worth_removable_gaussians_beyond():
    whole, nowhere = (lambda keys: np.ones(len(keys), bool)), (lambda keys: np.zeros(len(keys), bool))
    surface, means = _one_cell(3)
    # a cell not held whole gets no density; held whole, it gets what it holds per observed voxel
    assert len(surface.enforce(means, np.arange(4), np.zeros(4), nowhere, 0.0)) == 0
    assert surface.density[0] == -1.0
    assert len(surface.enforce(means, np.arange(4), np.zeros(4), whole, 0.0)) == 0
    assert surface.density[0] == 0.75
    _, more = _one_cell(6)
    removable = np.array([0, 1, 2, 4, 5, 6])  # row 3 is not removable, row 6 lies in no observed cell
    worth = np.array([5.0, 1.0, 4.0, 3.0, 2.0, 0.0])
    gone = removable[surface.enforce(more, removable, worth, whole, 0.0)]
    assert sorted(gone.tolist()) == [1, 4, 5]  # three over 0.75 x 4, least worth first
    # with 30 % slack one may stay; once set, the density holds in a partial view too (whose count can
    # only be lower); more surface observed, more allowed
    assert sorted(removable[surface.enforce(more, removable, worth, whole, 0.3)].tolist()) == [1, 5]
    assert sorted(removable[surface.enforce(more, removable, worth, nowhere, 0.0)].tolist()) == [1, 4, 5]
    surface.counts[0] = 8
    assert len(surface.enforce(more, removable, worth, whole, 0.0)) == 0 and surface.density[0] == 0.75


def test_cells_in_view_hold_the_whole_cell_in_front_of_the_camera():
    surface = ObservedSurface(0.2)
    keys = surface.cell_keys(np.array([[0.05, 0.05, 1.05], [0.05, 0.05, -1.0], [5.0, 0.05, 1.05]]))
    assert surface.cells_in_view(keys, pose(), intrinsics(S), S, S).tolist() == [True, False, False]


def test_a_revisit_adds_no_gaussians_where_it_sees_no_new_surface_only_with_the_budget_on(tmp_path):
    """A quarter of a view's map pushed 30 cm back: the next frame of the same view sees no new surface,
    and eq. 8's depth test adds Gaussians in front of the old ones. With the budget on, the cells keep
    what they had (the new ones go again, the Adam state follows) and nothing older is removed; off, the
    map keeps them."""
    cam = pose()
    rgb, depth = observe(cam, S)
    for slack in (None, 0.0):
        cfg = MapperConfig(schedule=Schedule(1, 1, 0), area_budget_slack=slack, area_budget_cell_m=0.5,
                           detail_colour_range=None)
        mapper = Mapper(intrinsics(S), S, S, cfg, backend="torch")
        mapper.add_frame(rgb, depth, cam)
        n = len(mapper.gaussians)
        with torch.no_grad():
            means = mapper.gaussians.params["means"]
            means[means[:, 0] < -1.0, 2] += 0.3
        old = mapper.gaussians.params["means"].detach().clone()
        stats = mapper.add_frame(rgb, depth, cam)
        assert stats.added > 0.15 * n and stats.pruned == 0
        assert len(mapper.optimizer) == len(mapper.gaussians)
        if slack is None:
            assert stats.budgeted == 0 and len(mapper.gaussians) == n + stats.added
            continue
        assert stats.budgeted > 0.9 * stats.added
        assert len(mapper.gaussians) == n + stats.added - stats.budgeted
        assert torch.equal(mapper.gaussians.params["means"][:n].detach(), old)  # the old rows all stay
        # a saved map comes back with its observed surface (from its keyframes)
        reloaded = Mapper.load(mapper.save(tmp_path / "map"), backend="torch")
        assert reloaded.surface is not None and len(reloaded.surface.voxels) == len(mapper.surface.voxels)


def test_area_budget_config_is_checked():
    with pytest.raises(InvalidInputError, match="area_budget_cell_m"):
        MapperConfig(area_budget_slack=0.1, area_budget_cell_m=0.07)
    with pytest.raises(InvalidInputError, match="area_budget_slack"):
        MapperConfig(area_budget_slack=-0.1)
