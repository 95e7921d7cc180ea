"""Multi-storey meshes: storeys found bottom to top, roofs recognised as open above,
--floor by index or height, the navigability map, start and ground-truth surface of that storey only,
and an error listing the storeys when the choice is ambiguous."""

import numpy as np
import pytest
import trimesh

from activesplat.cli import main
from activesplat.errors import SceneError
from activesplat.sim import Simulator, load_scene
from activesplat.sim.gltf import write_glb
from activesplat.sim.materials import Material, Surface

STOREY = 3.0
"""Height of the second storey's floor in the stacked house (small-0's ceiling is below 2.8 m)."""


def _roof(house, y: float, margin: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """A flat roof quad facing up over the house footprint, a bit larger than the floor."""
    (x0, _, z0), (x1, _, z1) = house.bounds
    v = np.array([[x0 - margin, y, z0 - margin], [x0 - margin, y, z1 + margin], [x1 + margin, y, z1 + margin],
                  [x1 + margin, y, z0 - margin]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def _write(path, parts, house):
    """glb of (vertices, faces) parts; house-shaped parts keep the house's surface, others grey."""
    vertices, faces, surfaces, n = [], [], [], 0
    for v, f in parts:
        vertices.append(v)
        faces.append(f + n)
        n += len(v)
        if len(f) == len(house.mesh.faces):
            surfaces.append(house.surface)
        else:
            surfaces.append(Surface([Material("roof", np.full(3, 0.5))], np.zeros(len(f))))
    return write_glb(path, np.concatenate(vertices), np.concatenate(faces), Surface.concatenate(surfaces))


@pytest.fixture(scope="module")
def two_storeys(small0, tmp_path_factory):
    """small-0 stacked on itself (second floor at y = 3 m) under a flat roof at y = 6 m."""
    v, f = small0.mesh.vertices, small0.mesh.faces
    path = tmp_path_factory.mktemp("storeys") / "two_storeys.glb"
    return _write(path, [(v, f), (v + [0.0, STOREY, 0.0], f), _roof(small0, 2 * STOREY)], small0)


def test_ambiguous_storeys_are_listed(two_storeys):
    with pytest.raises(SceneError) as info:
        load_scene(two_storeys)
    message = str(info.value)
    assert "2 storeys" in message and "--floor" in message
    assert "0: y = 0.00 m" in message and "1: y = 3.00 m" in message and "2: y = 6.00 m" in message
    assert "open above" in message


@pytest.mark.parametrize("floor", [1, 3.0, 2.8])
def test_upper_storey_by_index_or_height(two_storeys, small0, floor):
    scene = load_scene(two_storeys, floor=floor)
    assert scene.floor_height == pytest.approx(STOREY, abs=1e-6)
    assert [s.open_above for s in scene.storeys] == [False, False, True]
    np.testing.assert_array_equal(scene.navmap.grid, small0.navmap.grid)  # the same plan, one storey up
    sim = Simulator(scene, seed=5)
    assert sim.reset().pose[1, 3] == pytest.approx(STOREY + sim.config.sensor_height)
    points = scene.sample_surface(2000)
    assert points[:, 1].min() >= STOREY - 0.1 - 1e-6 and points[:, 1].max() < 2 * STOREY


def test_ground_storey_and_bad_choices(two_storeys, small0):
    scene = load_scene(two_storeys, floor=0)
    assert scene.floor_height == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_array_equal(scene.navmap.grid, small0.navmap.grid)
    assert scene.sample_surface(2000)[:, 1].max() < STOREY - 0.1
    for bad in (7, 4.5, -1):
        with pytest.raises(SceneError, match=r"0: y = 0\.00 m"):
            load_scene(two_storeys, floor=bad)


def test_a_larger_flat_roof_is_not_the_floor(small0, tmp_path):
    """The roof has more upward area than the floor (so the largest bin is the roof), but nothing
    lies above it: the floor under the ceiling is chosen without --floor."""
    house = (small0.mesh.vertices, small0.mesh.faces)
    path = _write(tmp_path / "roofed.glb", [house, _roof(small0, 2.9, 1.0)], small0)
    scene = load_scene(path)
    assert scene.floor_height == pytest.approx(0.0, abs=1e-6)
    assert len(scene.storeys) == 2 and scene.storeys[1].open_above


def test_cli_floor_flag(two_storeys, tmp_path, capsys):
    assert main(["scenes", "export", str(two_storeys), str(tmp_path / "x.glb")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "storeys" in err and "Traceback" not in err
    assert main(["scenes", "export", str(two_storeys), str(tmp_path / "x.glb"), "--floor", "1"]) == 0
    assert main(["explore", "--scene", str(two_storeys), "--floor", "upstairs"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "floor" in err and "storey index" in err and "Traceback" not in err
    with pytest.raises(SceneError, match="one storey"):
        load_scene("small-0", floor=1)


def _slab_house(inside_out: bool) -> trimesh.Trimesh:
    """A 5 x 4 m room modelled two-sided, as architecture exports are: boxes for the floor slab (y -0.2 to
    0), the ceiling slab (2.6 to 2.8) and four walls, and a table; `inside_out` reverses every face."""
    def box(lo, hi):
        b = trimesh.creation.box(np.subtract(hi, lo))
        b.apply_translation(np.add(lo, hi) / 2)
        return b
    boxes = [box([0, -0.2, 0], [5, 0, 4]), box([0, 2.6, 0], [5, 2.8, 4]), box([1, 0, 1], [2, 0.75, 2]),
             box([-0.1, -0.2, 0], [0, 2.8, 4]), box([5, -0.2, 0], [5.1, 2.8, 4]),
             box([0, -0.2, -0.1], [5, 2.8, 0]), box([0, -0.2, 4], [5, 2.8, 4.1])]
    mesh = trimesh.util.concatenate(boxes)
    return trimesh.Trimesh(mesh.vertices, mesh.faces[:, ::-1] if inside_out else mesh.faces, process=False)


@pytest.mark.parametrize("inside_out", [False, True])
def test_faces_wound_inside_out_still_stand_on_the_floor(small0, tmp_path, inside_out):
    """A mesh whose faces are all reversed (floors facing down, ceilings up, as after mirroring an axis)
    once put the agent on top of the ceiling (y = 2.61 m in small-0); the floor is the level with room to
    stand above it, whichever way its faces point."""
    path = tmp_path / "house.ply"
    faces = np.asarray(small0.mesh.faces)
    trimesh.Trimesh(small0.mesh.vertices, faces[:, ::-1] if inside_out else faces, process=False).export(path)
    scene = load_scene(path)
    assert scene.floor_height == pytest.approx(0.0, abs=1e-6) and len(scene.storeys) == 1
    np.testing.assert_array_equal(scene.navmap.grid, small0.navmap.grid)
    path = tmp_path / "slabs.ply"
    _slab_house(inside_out).export(path)  # two-sided: slab undersides face down, the roof up
    assert load_scene(path).floor_height == pytest.approx(0.0, abs=1e-6)
    if not inside_out:  # an open scan, no ceiling: nothing to tell floors by, and the floor faces up
        normals, centres = small0.mesh.face_normals, small0.mesh.triangles_center
        path = tmp_path / "open.ply"
        trimesh.Trimesh(small0.mesh.vertices, faces[~((normals[:, 1] < -0.9) & (centres[:, 1] > 2.0))],
                        process=False).export(path)
        assert load_scene(path).floor_height == pytest.approx(0.0, abs=1e-6)
