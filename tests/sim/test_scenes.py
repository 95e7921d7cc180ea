"""Built-in houses (rooms, furniture, connected free space, determinism), export round trip, z-up files."""

import numpy as np
import pytest
import trimesh

from activesplat.sim import HouseConfig, Simulator, box_room, load_scene
from activesplat.sim.house import make_layout

HOUSES = ["small-0", "small-1", "small-2", "small-3", "medium-0", "medium-1"]


@pytest.fixture(scope="module", params=HOUSES)
def house(request, small0):
    return small0 if request.param == "small-0" else load_scene(request.param)


def test_house_free_space_is_connected_and_reaches_every_room(house):
    navmap = house.navmap
    kind, seed = house.name.split("-")
    low, high = getattr(HouseConfig(), f"{kind}_rooms")
    assert low <= house.rooms <= high
    secondary = (navmap.grid & ~navmap.largest).sum() * navmap.resolution**2
    assert secondary <= 0.05, f"{secondary:.3f} m^2 of navigable floor outside the main component"
    labels, _ = navmap.components()
    for room in make_layout(house.name, int(seed), HouseConfig()).rooms:
        ix, iz = navmap.cell_of([room.x0 + 0.1, room.x1 - 0.1], [room.z0 + 0.1, room.z1 - 0.1])
        inside = navmap.largest[ix[0] : ix[1], iz[0] : iz[1]]
        assert inside.sum() * navmap.resolution**2 > 1.0, f"room {room} is not reachable"


def test_houses_have_furniture_of_several_heights():
    """Low boxes/sofas/beds, tables whose top floats above open floor, tall shelves."""
    tops, table_tops = [], 0
    for name in HOUSES:
        house = make_layout(name, int(name.split("-")[1]), HouseConfig())
        assert house.boxes, f"{name} has no furniture"
        tops += [hi[1] for _, hi, _ in house.boxes]
        table_tops += sum(lo[1] > 0.6 and hi[1] < 0.8 for lo, hi, _ in house.boxes)
    tops = np.array(tops)
    assert (tops < 0.6).sum() > 5 and ((tops > 0.6) & (tops < 1.0)).sum() > 5 and (tops > 1.6).sum() > 3
    assert table_tops >= 3


def test_medium_houses_have_a_corridor_and_doorways():
    house = make_layout("medium-0", 0, HouseConfig())
    assert house.corridor_names == ["corridor"]  # one corridor (possibly several rectangles)
    assert len(house.doors) >= house.n_rooms  # spanning tree over rooms + corridor, plus loops


def test_scene_build_is_deterministic(small0):
    again = load_scene("small-0")
    np.testing.assert_array_equal(again.mesh.vertices, small0.mesh.vertices)
    np.testing.assert_array_equal(again.mesh.faces, small0.mesh.faces)
    np.testing.assert_array_equal(again.mesh.visual.uv, small0.mesh.visual.uv)
    np.testing.assert_array_equal(np.asarray(again.mesh.visual.material.baseColorTexture),
                                  np.asarray(small0.mesh.visual.material.baseColorTexture))
    np.testing.assert_array_equal(again.navmap.grid, small0.navmap.grid)
    assert len(load_scene("small-1").mesh.faces) != len(small0.mesh.faces)


def test_export_round_trip_gives_identical_images(small0, tmp_path):
    path = small0.export(tmp_path / "small-0.glb")
    loaded = load_scene(path)
    assert loaded.floor_height == pytest.approx(0.0, abs=1e-6)
    a = Simulator(small0, seed=2)
    b = Simulator(loaded, start=a.start_pose)
    for action in (None, "turn_left", "look_down", "move_forward"):
        oa, ob = (a.reset(), b.reset()) if action is None else (a.step(action), b.step(action))
        np.testing.assert_array_equal(oa.rgb, ob.rgb)
        np.testing.assert_array_equal(oa.depth, ob.depth)
        np.testing.assert_array_equal(oa.pose, ob.pose)
    np.testing.assert_array_equal(loaded.navmap.grid, small0.navmap.grid)


@pytest.mark.parametrize("suffix", [".ply", ".obj"])
def test_z_up_file_loads_with_z_up(tmp_path, suffix):
    box = box_room(textured=False)
    mesh = box.mesh.copy()
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))  # y up -> z up
    path = tmp_path / f"box_zup{suffix}"
    mesh.export(path)
    scene = load_scene(path, z_up=True)
    np.testing.assert_allclose(scene.mesh.bounds, box.mesh.bounds, atol=1e-6)
    assert scene.floor_height == pytest.approx(0.0, abs=1e-6)
    a = Simulator(box, seed=1)
    b = Simulator(scene, start=a.start_pose)
    oa, ob = a.reset(), b.reset()
    np.testing.assert_allclose(ob.depth, oa.depth, atol=1e-5)
    assert scene.navmap.navigable_area == pytest.approx(box.navmap.navigable_area, rel=0.02)


def test_vertex_coloured_mesh_keeps_its_colours(tmp_path):
    box = box_room(textured=False)
    path = tmp_path / "box.ply"
    box.mesh.export(path)
    a, b = Simulator(box, seed=3), Simulator(load_scene(path), seed=3)
    np.testing.assert_array_equal(a.reset().rgb, b.reset().rgb)


def test_plain_house_has_the_same_triangles_and_flat_colours(small0, tmp_path):
    """small-0-plain: the triangles and free space of small-0; every pixel's colour is a function of
    its face's material colour and normal only (flat albedo times the per-face |n . l| shading)."""
    plain = load_scene("small-0-plain")
    assert plain.name == "small-0-plain" and plain.rooms == small0.rooms
    np.testing.assert_array_equal(plain.mesh.vertices, small0.mesh.vertices)
    np.testing.assert_array_equal(plain.mesh.faces, small0.mesh.faces)
    np.testing.assert_array_equal(plain.navmap.grid, small0.navmap.grid)
    assert not isinstance(plain.mesh.visual, trimesh.visual.TextureVisuals)
    sim = Simulator(plain, seed=3)
    spread = {}
    for scene in (plain, small0):
        sensor = Simulator(scene, start=sim.start_pose).sensor
        origins, dirs = sensor.world_rays(sim.start_pose, sim.K, sim.width, sim.height)
        face = sensor.cast(origins, dirs)["primID"]
        rgb, _ = sensor.render(sim.start_pose, sim.K, sim.width, sim.height)
        rgb, face = rgb.reshape(-1, 3), face.ravel()
        hit = face >= 0
        normal = np.round(plain.mesh.face_normals[face[hit]], 3)
        albedo = plain.mesh.visual.face_colors[face[hit], :3]
        key = np.unique(np.hstack([normal, albedo]), axis=0, return_inverse=True)[1].ravel()
        spread[scene.name] = max(np.ptp(rgb[hit][key == k], axis=0).max() for k in np.unique(key))
    assert spread["small-0-plain"] == 0
    assert spread["small-0"] > 20  # the textured house varies within a material and orientation
    path = plain.export(tmp_path / "plain.glb")  # vertex colours in the glb, the same frame back
    again = Simulator(load_scene(path), start=sim.start_pose)
    np.testing.assert_array_equal(again.reset().rgb, sim.reset().rgb)


def test_plain_names_work_wherever_builtin_names_do(tmp_path):
    from activesplat.bench.runner import default_steps, validate_scene
    from activesplat.sim import describe_builtin_scenes

    validate_scene("medium-2-plain")
    assert default_steps("medium-2-plain") == default_steps("medium-2")
    assert "-plain" in describe_builtin_scenes(seeds=(0,))
    with pytest.raises(Exception, match="plain"):
        load_scene("small-0-shiny")


def test_scene_label_is_a_mesh_file_name_or_the_name_as_it_is():
    from activesplat.sim.scene import scene_label

    assert scene_label("/data/hm3d/00800-TEEsavR23oF/TEEsavR23oF.glb") == "TEEsavR23oF.glb"
    assert scene_label("small-0") == "small-0" and scene_label("medium-2-plain") == "medium-2-plain"
    assert scene_label("robot ws://10.0.0.2:9090") == "robot ws://10.0.0.2:9090"
