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
