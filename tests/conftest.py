"""Shared pytest setup: compile (or load from the numba disk cache) the rasterizer kernels once; fixtures
several test modules use."""

import pytest


@pytest.fixture(scope="session", autouse=True)
def warm_numba_rasterizer():
    """Warm the numba rasterizer once per test run so no single test pays the JIT time."""
    from activesplat.splat.raster.numba_backend import warm_up

    warm_up()


@pytest.fixture
def house():
    """An L-shaped living room (two rectangles, one name), a corridor and a bedroom (tests of per-room
    measures and of trajectory.png; a test module may define its own ``house``)."""
    from activesplat.sim.rooms import House, Room

    rooms = [Room(0, 0, 4, 3, name="living"), Room(0, 3, 2, 5, name="living"),
             Room(4, 0, 5.5, 5, kind="corridor", name="corridor"), Room(5.5, 0, 9, 5, name="bedroom")]
    return House("test", rooms, [], 2.6)


@pytest.fixture
def registry(monkeypatch):
    """A clean policy registry, without this machine's installed entry points: a policy a test registers
    does not outlive it."""
    from activesplat.planning import policies

    monkeypatch.setattr(policies, "_REGISTERED", {})
    policies._entry_points.cache_clear()
    yield
    policies._entry_points.cache_clear()


@pytest.fixture
def threads():
    """``threads(n)`` sets torch's and numba's CPU thread counts (numba's at most its pool's size); both are
    restored afterwards."""
    import numba
    import torch

    saved_torch, saved_numba = torch.get_num_threads(), numba.get_num_threads()

    def set_threads(n: int) -> None:
        torch.set_num_threads(n)
        numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))

    yield set_threads
    torch.set_num_threads(saved_torch)
    numba.set_num_threads(saved_numba)
