"""Scenes built once per test session (building a house takes about a second)."""

import pytest

from activesplat.sim import box_room, load_scene


@pytest.fixture(scope="session")
def box():
    """Textured 4 x 3 x 2.6 m box room."""
    return box_room()


@pytest.fixture(scope="session")
def flat_box():
    """The same box room with one flat colour per face (exact colours, no texture)."""
    return box_room(textured=False)


@pytest.fixture(scope="session")
def small0():
    return load_scene("small-0")
