"""Every bad input of the simulator and the command line raises a clear ActiveSplatError naming the
file or value; on the command line it becomes a one-line error with exit code 2 and no traceback."""

import numpy as np
import pytest
import trimesh

from activesplat.cli import main
from activesplat.errors import InvalidActionError, SceneError, SceneNotFoundError
from activesplat.sim import Simulator, load_scene


def _write_bad_files(folder):
    """name -> path of files that must not load."""
    files = {
        "corrupt_glb": (folder / "corrupt.glb", b"this is not a binary glTF" * 4),
        "empty_glb": (folder / "empty.glb", b""),
        "truncated_ply": (folder / "truncated.ply",
                          b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n"),
        "text_obj": (folder / "notes.obj", b"hello\nthis is not a mesh\n"),
        "wrong_suffix": (folder / "house.txt", b"v 0 0 0\n"),
    }
    for path, data in files.values():
        path.write_bytes(data)
    walls = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 2, 0], [0, 2, 0]], [[0, 1, 2], [0, 2, 3]])
    walls.export(folder / "wall_only.obj")
    tiny = trimesh.Trimesh([[0, 0, 0], [0.15, 0, 0], [0.15, 0, 0.15], [0, 0, 0.15]], [[0, 2, 1], [0, 3, 2]])
    tiny.export(folder / "tiny_floor.ply")  # a floor smaller than the agent's disc
    paths = {key: path for key, (path, _) in files.items()}
    paths["wall_only"] = folder / "wall_only.obj"
    paths["tiny_floor"] = folder / "tiny_floor.ply"
    (folder / "folder.glb").mkdir()
    paths["directory"] = folder / "folder.glb"
    return paths


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    return _write_bad_files(tmp_path_factory.mktemp("bad"))


def test_missing_file(tmp_path):
    missing = tmp_path / "nowhere" / "house.glb"
    with pytest.raises(SceneNotFoundError, match="nowhere/house.glb"):
        load_scene(missing)
    with pytest.raises(FileNotFoundError):
        load_scene(missing)


@pytest.mark.parametrize("key", ["corrupt_glb", "empty_glb", "truncated_ply", "text_obj", "wrong_suffix",
                                 "wall_only", "tiny_floor", "directory"])
def test_unreadable_corrupt_or_floorless_file(bad_files, key):
    path = bad_files[key]
    with pytest.raises(SceneError, match=path.name) as info:
        load_scene(path)
    assert "\n" not in str(info.value)
    if key in ("wall_only", "tiny_floor"):
        assert "walkable floor" in str(info.value)


@pytest.mark.parametrize("name", ["large-3", "small-x", "medium-", "small-1.5", "Small-0"])
def test_unknown_builtin_name(name):
    with pytest.raises(SceneError, match=f"'{name}'"):
        load_scene(name)


@pytest.mark.parametrize("action", ["jump", "MOVE_FORWARD", "", None, 3])
def test_unknown_action(box, action):
    sim = Simulator(box, seed=0)
    sim.reset()
    with pytest.raises(InvalidActionError, match=repr(action).replace("(", r"\(")):
        sim.step(action)
    assert sim.step_count == 0  # a refused action costs nothing


def test_bad_start_pose_and_sensor(box):
    with pytest.raises(ValueError, match="not navigable"):
        Simulator(box, start=np.eye(4))  # camera at the room corner, inside the wall clearance
    with pytest.raises(ValueError, match="4x4"):
        Simulator(box, start=np.eye(3))


def _run_cli(capsys, argv):
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.parametrize("key", ["corrupt_glb", "wall_only", "directory"])
def test_cli_bad_file_is_one_line_exit_2(bad_files, capsys, tmp_path, key):
    code, _, err = _run_cli(capsys, ["scenes", "export", str(bad_files[key]), str(tmp_path / "out.glb")])
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("activesplat: error:") and bad_files[key].name in err
    assert "Traceback" not in err


@pytest.mark.parametrize("argv", [["scenes", "export", "large-3", "x.glb"],
                                  ["scenes", "export", "small-x", "x.glb"],
                                  ["scenes", "export", "missing.glb", "x.glb"]])
def test_cli_unknown_scene_is_one_line_exit_2(capsys, argv):
    code, _, err = _run_cli(capsys, argv)
    assert code == 2 and err.count("\n") == 1 and argv[2] in err and "Traceback" not in err


def test_cli_export_needs_glb(capsys, tmp_path):
    code, _, err = _run_cli(capsys, ["scenes", "export", "small-0", str(tmp_path / "house.obj")])
    assert code == 2 and err.count("\n") == 1 and "house.obj" in err


def test_cli_scenes_list(capsys):
    code, out, err = _run_cli(capsys, ["scenes", "list"])
    assert code == 0 and err == ""
    assert "small-<seed>" in out and "medium-<seed>" in out
    assert "small-0" in out and "medium-2" in out


def test_cli_export_writes_loadable_glb(capsys, tmp_path, small0):
    target = tmp_path / "sub" / "small-0.glb"
    code, out, _ = _run_cli(capsys, ["scenes", "export", "small-0", str(target)])
    assert code == 0 and str(target) in out
    loaded = load_scene(target)
    np.testing.assert_array_equal(loaded.mesh.vertices, small0.mesh.vertices)
    np.testing.assert_array_equal(loaded.mesh.faces, small0.mesh.faces)


def test_ctrl_c_in_scenes_export_is_one_line_and_leaves_no_partial_glb(capsys, tmp_path, box, monkeypatch):
    """While the scene is built or while the file is written: one line (exit code 130) saying the file is
    not written; a file already there is kept as it was, and no half-written .glb is left."""
    import activesplat.sim
    from activesplat.sim import gltf

    def ctrl_c(*args, **kwargs):
        raise KeyboardInterrupt

    target = tmp_path / "box.glb"
    monkeypatch.setattr(activesplat.sim, "load_scene", ctrl_c)
    code, _, err = _run_cli(capsys, ["scenes", "export", "small-0", str(target)])
    assert (code, err.strip()) == (130, f"scenes export interrupted: {target} is not written (no partial "
                                        f"file is left); run the same command again")
    monkeypatch.setattr(activesplat.sim, "load_scene", lambda *a, **k: box)
    monkeypatch.setattr(gltf.os, "replace", ctrl_c)  # the whole file written under its temporary name
    code, _, err = _run_cli(capsys, ["scenes", "export", "small-0", str(target)])
    assert code == 130 and "no partial file is left" in err and list(tmp_path.iterdir()) == []
    target.write_bytes(b"an older export")
    code, _, err = _run_cli(capsys, ["scenes", "export", "small-0", str(target)])
    assert (code, err.strip()) == (130, f"scenes export interrupted: {target} is not written (the file "
                                        f"already there is kept as it was); run the same command again")
    assert target.read_bytes() == b"an older export" and list(tmp_path.iterdir()) == [target]
    monkeypatch.undo()
    monkeypatch.setattr(activesplat.sim, "load_scene", lambda *a, **k: box)
    code, _, _ = _run_cli(capsys, ["scenes", "export", "small-0", str(target)])
    assert code == 0 and load_scene(target).mesh.faces.shape == box.mesh.faces.shape
    assert list(tmp_path.iterdir()) == [target]


@pytest.mark.parametrize("case", ["millimetres", "stray_triangle"])
def test_mesh_too_large_for_the_grid_is_refused_at_once(box, tmp_path, case):
    """A mesh in millimetres, or one with a speck of geometry 500 m away, once ran out of memory in the
    navigability grid after minutes; now it is one line naming the extent and the likely causes."""
    v, f = np.asarray(box.mesh.vertices), np.asarray(box.mesh.faces)
    if case == "millimetres":
        v = v * 1000.0
    else:
        f = np.concatenate([f, [[len(v), len(v) + 2, len(v) + 1]]])
        v = np.concatenate([v, [[500.0, 0.0, 500.0], [500.1, 0.0, 500.0], [500.0, 0.0, 500.1]]])
    path = tmp_path / f"{case}.ply"
    trimesh.Trimesh(v, f, process=False).export(path)
    with pytest.raises(SceneError, match=path.name) as info:
        load_scene(path)
    message = str(info.value)
    assert "millimetres" in message and "stray geometry" in message and "\n" not in message
    assert ("4000.0 x 3000.0 m" if case == "millimetres" else "500.1 x 500.1 m") in message


def test_mesh_without_floor_is_refused_not_walked_on_furniture(small0, tmp_path):
    """small-0 without its floor faces once loaded with the top of a bed (y = 0.5 m, 3.4 m^2) as the
    floor and explored it; a floor far smaller than the ceiling is refused unless asked for by --floor."""
    normals, centres = small0.mesh.face_normals, small0.mesh.triangles_center
    floor = (normals[:, 1] > 0.9) & (np.abs(centres[:, 1]) < 0.05)
    path = tmp_path / "no_floor.ply"
    trimesh.Trimesh(small0.mesh.vertices, small0.mesh.faces[~floor], process=False).export(path)
    with pytest.raises(SceneError, match=path.name) as info:
        load_scene(path)
    message = str(info.value)
    assert "no floor" in message and "--floor 0.50" in message and "z-up" not in message
    assert load_scene(path, floor=0.5).floor_height == pytest.approx(0.5, abs=0.01)


def test_floor_errors_hint_at_the_up_axis(small0, tmp_path):
    """A z-up file read as y-up once listed walls as two storeys at y = -5.35 and -2.84 m with no word of
    --z-up; a y-up file read with --z-up the same. The error now says which way the file may point."""
    path = tmp_path / "z_up.ply"
    mesh = small0.mesh.copy()
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    mesh.export(path)
    with pytest.raises(SceneError, match="the file may be z-up: add --z-up"):
        load_scene(path)
    assert load_scene(path, z_up=True).floor_height == pytest.approx(0.0, abs=1e-6)
    path = tmp_path / "y_up.ply"
    small0.mesh.export(path)
    with pytest.raises(SceneError, match="the file may be y-up: leave out --z-up"):
        load_scene(path, z_up=True)
