"""Shared pytest setup: compile (or load from the numba disk cache) the rasterizer kernels once."""

import pytest


@pytest.fixture(scope="session", autouse=True)
def warm_numba_rasterizer():
    """Warm the numba rasterizer once per test run so no single test pays the JIT time."""
    from activesplat.splat.raster.numba_backend import warm_up

    warm_up()
