"""write_glb to a path it cannot write: one InvalidInputError naming the path (the command line's one-line
error), never a bare FileExistsError / NotADirectoryError / FileNotFoundError."""

import errno
import re

import pytest

from activesplat.errors import InvalidInputError
from activesplat.sim import box_room
from activesplat.sim.gltf import write_glb


@pytest.fixture(scope="module")
def room():
    scene = box_room()
    return scene.mesh.vertices, scene.mesh.faces, scene.surface


def test_a_file_where_a_folder_should_be(room, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    for path in (blocker / "x.glb", blocker / "sub" / "x.glb"):
        message = f"cannot write {path}: {blocker} is a file, not a folder"
        with pytest.raises(InvalidInputError, match=re.escape(message)):
            write_glb(path, *room)


def test_a_folder_in_the_files_place(room, tmp_path):
    (tmp_path / "x.glb").mkdir()
    with pytest.raises(InvalidInputError, match="x.glb: it is a folder"):
        write_glb(tmp_path / "x.glb", *room)


def test_a_path_that_cannot_be_created(room, tmp_path, monkeypatch):
    from pathlib import Path

    def refuse(self, mode="r", *args, **kwargs):
        raise FileNotFoundError(errno.ENOENT, "No such file or directory", str(self))

    monkeypatch.setattr(Path, "open", refuse)  # as /proc/x.glb does
    with pytest.raises(InvalidInputError, match=r"cannot write .*x.glb \(No such file or directory\)"):
        write_glb(tmp_path / "x.glb", *room)


def test_a_full_disk_is_left_to_the_command_line(room, tmp_path, monkeypatch):
    from pathlib import Path

    def full(self, mode="r", *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    monkeypatch.setattr(Path, "open", full)
    with pytest.raises(OSError) as exc:
        write_glb(tmp_path / "x.glb", *room)
    assert exc.value.errno == errno.ENOSPC and not isinstance(exc.value, InvalidInputError)


def test_written_where_it_can_be(room, tmp_path):
    path = write_glb(tmp_path / "a" / "b" / "x.glb", *room)
    assert path.is_file() and path.read_bytes()[:4] == b"glTF"


def test_glb_structure_is_what_the_khronos_validator_checks(tmp_path):
    """What the Khronos glTF validator reported clean on exported houses, kept by hand: chunk lengths and
    4-byte alignment, bufferViews inside the buffer and aligned for their float accessors, POSITION min/max
    equal to the data (float32), no target on image views, PNG images with their mime type, sampler and
    texture indices valid, every attribute of a primitive the same count."""
    import json
    import struct

    import numpy as np

    from activesplat.sim.materials import CLAMP_TO_EDGE, MIRRORED_REPEAT, Material, Surface

    rng = np.random.default_rng(0)
    vertices = rng.normal(size=(12, 3))
    faces = np.stack([np.arange(10), np.arange(1, 11), np.arange(2, 12)], axis=1)
    texture = rng.integers(0, 256, size=(5, 7, 3), dtype=np.uint8)
    materials = [Material("tiles", [1.0, 0.5, 0.2], texture, CLAMP_TO_EDGE, MIRRORED_REPEAT),
                 Material("plain", [0.3, 0.3, 0.3]), Material("unused", [1.0, 1.0, 1.0], texture)]
    surface = Surface(materials, np.r_[np.zeros(6, int), np.ones(4, int)],
                      rng.uniform(-2, 3, size=(10, 3, 2)), rng.uniform(0, 1, size=(10, 3, 3)))
    data = write_glb(tmp_path / "x.glb", vertices, faces, surface).read_bytes()
    magic, version, total = struct.unpack_from("<III", data)
    assert (magic, version, total) == (0x46546C67, 2, len(data))
    json_len, json_type = struct.unpack_from("<II", data, 12)
    assert json_type == 0x4E4F534A and json_len % 4 == 0
    gltf = json.loads(data[20:20 + json_len])
    bin_len, bin_type = struct.unpack_from("<II", data, 20 + json_len)
    assert bin_type == 0x004E4942 and bin_len % 4 == 0 and 28 + json_len + bin_len == len(data)
    blob = data[28 + json_len:]
    assert gltf["buffers"] == [{"byteLength": bin_len}]
    for view in gltf["bufferViews"]:
        assert view["byteOffset"] % 4 == 0 and view["byteOffset"] + view["byteLength"] <= bin_len
    sizes = {"VEC2": 2, "VEC3": 3}
    for prim in gltf["meshes"][0]["primitives"]:
        counts = {gltf["accessors"][a]["count"] for a in prim["attributes"].values()}
        assert len(counts) == 1 and 0 <= prim["material"] < len(gltf["materials"])
        for name, a in prim["attributes"].items():
            acc = gltf["accessors"][a]
            view = gltf["bufferViews"][acc["bufferView"]]
            assert acc["componentType"] == 5126 and view.get("target") == 34962
            n = sizes[acc["type"]]
            assert view["byteLength"] == 4 * n * acc["count"]
            values = np.frombuffer(blob, "<f4", n * acc["count"], view["byteOffset"]).reshape(-1, n)
            if name == "POSITION":  # required, and exactly the data's bounds
                assert acc["min"] == values.min(axis=0).tolist() and acc["max"] == values.max(axis=0).tolist()
            if name == "COLOR_0":
                assert values.min() >= 0 and values.max() <= 1
    assert len(gltf["materials"]) == 2  # a material without faces is left out
    for image in gltf["images"]:
        view = gltf["bufferViews"][image["bufferView"]]
        assert "target" not in view and image["mimeType"] == "image/png"
        assert blob[view["byteOffset"]:view["byteOffset"] + 8] == b"\x89PNG\r\n\x1a\n"
    for tex in gltf["textures"]:
        assert 0 <= tex["source"] < len(gltf["images"]) and 0 <= tex["sampler"] < len(gltf["samplers"])
    assert gltf["samplers"][0]["wrapS"] == CLAMP_TO_EDGE and gltf["samplers"][0]["wrapT"] == MIRRORED_REPEAT
