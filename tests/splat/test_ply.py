"""PLY I/O: standard 3DGS layout, bit-exact round trip, clear errors on bad files."""

import numpy as np
import pytest
import torch

from activesplat.errors import InvalidInputError
from activesplat.splat.gaussians import SH_C0, GaussianMap
from activesplat.splat.ply import PLY_FIELDS, load_ply, save_ply


def _random_map(n: int = 50, seed: int = 0) -> GaussianMap:
    g = torch.Generator().manual_seed(seed)
    raw = {
        "means": torch.randn(n, 3, generator=g) * 3,
        "quats": torch.randn(n, 4, generator=g),
        "log_scales": torch.randn(n, 3, generator=g) - 3,
        "opacity_logits": torch.randn(n, generator=g),
        "f_dc": torch.randn(n, 3, generator=g),
    }
    return GaussianMap(raw)


def test_round_trip_is_bit_exact(tmp_path):
    gmap = _random_map()
    path = save_ply(gmap, tmp_path / "g.ply")
    back = load_ply(path)
    assert len(back) == len(gmap)
    for name, t in gmap.params.items():
        assert torch.equal(back.params[name], t.detach()), name
    assert torch.equal(back.colors, gmap.colors.detach())


def test_header_is_standard_3dgs_layout(tmp_path):
    gmap = _random_map(7)
    path = save_ply(gmap, tmp_path / "g.ply")
    raw = path.read_bytes()
    header, body = raw.split(b"end_header\n", 1)
    lines = header.decode().splitlines()
    assert lines[:3] == ["ply", "format binary_little_endian 1.0", "element vertex 7"]
    assert [ln.split()[2] for ln in lines[3:]] == list(PLY_FIELDS)
    assert all(ln.split()[1] == "float" for ln in lines[3:])
    assert len(body) == 7 * 17 * 4
    # independent decode of the first vertex: f_dc maps to rgb through C0, rot is wxyz
    rec = np.frombuffer(body, dtype="<f4").reshape(7, 17)
    assert np.allclose(0.5 + SH_C0 * rec[0, 6:9], gmap.colors[0].detach().numpy())
    assert np.allclose(rec[0, 13:17], gmap.params["quats"][0].detach().numpy())
    assert np.allclose(rec[0, 9], gmap.params["opacity_logits"][0].item())


def test_extra_properties_are_ignored(tmp_path):
    """Files from other 3DGS tools carry f_rest_* (higher SH); they still load."""
    names = list(PLY_FIELDS) + ["f_rest_0", "f_rest_1"]
    data = np.arange(3 * len(names), dtype="<f4").reshape(3, len(names))
    header = "ply\nformat binary_little_endian 1.0\ncomment made elsewhere\nelement vertex 3\n"
    header += "".join(f"property float {n}\n" for n in names) + "end_header\n"
    path = tmp_path / "other.ply"
    path.write_bytes(header.encode() + data.tobytes())
    gmap = load_ply(path)
    assert len(gmap) == 3
    assert np.array_equal(gmap.params["means"].detach().numpy(), data[:, :3])
    assert np.array_equal(gmap.params["quats"].detach().numpy(), data[:, 13:17])


def test_empty_map_round_trip(tmp_path):
    back = load_ply(save_ply(GaussianMap.empty(), tmp_path / "e.ply"))
    assert len(back) == 0


@pytest.mark.parametrize(
    "content",
    [b"not a ply\n", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
     b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n"],
)
def test_bad_files_raise_clear_errors(tmp_path, content):
    path = tmp_path / "bad.ply"
    path.write_bytes(content)
    with pytest.raises(InvalidInputError, match="bad.ply"):
        load_ply(path)


def test_truncated_and_missing_files(tmp_path):
    path = save_ply(_random_map(5), tmp_path / "t.ply")
    path.write_bytes(path.read_bytes()[:-10])
    with pytest.raises(InvalidInputError, match="truncated"):
        load_ply(path)
    with pytest.raises(InvalidInputError, match="does not exist"):
        load_ply(tmp_path / "nope.ply")


def _header_names(raw: bytes) -> tuple[list[str], bytes]:
    header, body = raw.split(b"end_header\n", 1)
    return [ln.split()[2] for ln in header.decode().splitlines() if ln.startswith("property")], body


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_sh_degree_layout_is_what_the_original_3dgs_loader_asserts(tmp_path, degree):
    """The original 3DGS load_ply asserts 3 (d + 1)^2 - 3 f_rest_* for its --sh_degree d (45 for the default
    3) and its viewer reads records at fixed offsets: x y z n f_dc f_rest opacity scale rot. The padded file
    holds the same Gaussians, f_rest all zero, and loads back bit-exact."""
    gmap = _random_map(9)
    _, plain = _header_names(save_ply(gmap, tmp_path / "d0.ply").read_bytes())
    plain = np.frombuffer(plain, "<f4").reshape(9, 17)
    names, body = _header_names(save_ply(gmap, tmp_path / "g.ply", sh_degree=degree).read_bytes())
    n_rest = 3 * (degree + 1) ** 2 - 3
    rest = sorted((n for n in names if n.startswith("f_rest_")), key=lambda n: int(n.split("_")[-1]))
    assert len(rest) == n_rest
    assert names == [*PLY_FIELDS[:9], *(f"f_rest_{i}" for i in range(n_rest)), *PLY_FIELDS[9:]]
    rec = np.frombuffer(body, "<f4").reshape(9, 17 + n_rest)
    assert not rec[:, 9:9 + n_rest].any()
    assert np.array_equal(np.delete(rec, np.s_[9:9 + n_rest], axis=1), plain)
    back = load_ply(tmp_path / "g.ply")
    for name, t in gmap.params.items():
        assert torch.equal(back.params[name], t.detach()), name


@pytest.mark.parametrize("degree", [-1, 4, True, 1.5])
def test_unknown_sh_degree_is_refused(tmp_path, degree):
    with pytest.raises(InvalidInputError, match="SH degree must be one of 0, 1, 2, 3"):
        save_ply(_random_map(2), tmp_path / "g.ply", sh_degree=degree)
    assert not (tmp_path / "g.ply").exists()


def test_export_ply_command(tmp_path, capsys):
    """`activesplat export DIR --ply FILE --sh-degree 3`: a map folder's (or refined_<method>'s) gaussians.ply
    for the original 3DGS loader; without --sh-degree the file is the map's own."""
    from activesplat.cli import main

    folder = tmp_path / "refined_3dgs"
    gmap = _random_map(4)
    save_ply(gmap, folder / "gaussians.ply")
    out = tmp_path / "out" / "sh3.ply"
    assert main(["export", str(folder), "--ply", str(out), "--sh-degree", "3"]) == 0
    assert "SH degree 3" in capsys.readouterr().out
    names, _ = _header_names(out.read_bytes())
    assert sum(n.startswith("f_rest_") for n in names) == 45
    assert torch.equal(load_ply(out).params["means"], gmap.params["means"].detach())
    same = tmp_path / "same.ply"
    assert main(["export", str(folder), "--ply", str(same)]) == 0
    assert same.read_bytes() == (folder / "gaussians.ply").read_bytes()
    capsys.readouterr()
    refusals = {
        ("export", str(folder)): "export needs --mcap FILE (Foxglove) or --ply FILE (3DGS PLY), or both",
        ("export", str(folder), "--mcap", str(tmp_path / "x.mcap"), "--sh-degree", "3"):
            "--sh-degree applies to --ply FILE only",
        ("export", str(folder), "--ply", str(tmp_path / "x.ply"), "--max-points", "3"):
            "--max-points applies to --mcap FILE only",
        ("export", str(folder), "--ply", str(same)): f"{same} exists; pass --overwrite to replace it",
        ("export", str(folder), "--ply", str(tmp_path / "x.txt")):
            f"--ply file must end in .ply: {tmp_path}/x.txt",
        ("export", str(tmp_path / "out"), "--ply", str(tmp_path / "x.ply")):
            f"{tmp_path}/out: not an episode, map or refined folder (no gaussians.ply)",
    }
    for argv, message in refusals.items():
        assert main(list(argv)) == 2
        assert capsys.readouterr().err == f"activesplat: error: {message}\n"
    assert not (tmp_path / "x.ply").exists() and not list(tmp_path.rglob("*.partial"))
