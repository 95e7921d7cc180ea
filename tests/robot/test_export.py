"""`activesplat export DIR --mcap FILE`: what Foxglove reads back, channel by channel."""

import base64
import json

import numpy as np
import pytest

from activesplat.cli import main

mcap_reader = pytest.importorskip("mcap.reader")


@pytest.fixture(scope="module")
def map_folder(tmp_path_factory):
    from _bags import ARGS, sim_frames, write_bag

    root = tmp_path_factory.mktemp("export")
    K, fr = sim_frames(6, 32)
    bag = write_bag(root / "rec", K, fr)
    out = root / "map"
    argv = [
        "map",
        str(bag),
        *ARGS,
        "--pose-source",
        "/camera_pose",
        "--out",
        str(out),
        "--holdout-every",
        "0",
    ]
    assert main([*argv, "--backend", "numba", "--no-progress"]) == 0
    return out


def test_export_writes_foxglove_channels(map_folder, tmp_path, capsys):
    out = tmp_path / "episode.mcap"
    assert main(["export", str(map_folder), "--mcap", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    with open(out, "rb") as f:
        reader = mcap_reader.make_reader(f)
        summary = reader.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        assert schemas["/camera/rgb"] == "foxglove.RawImage" and schemas["/map"] == "foxglove.PointCloud"
        msgs = {}
        for _, channel, message in reader.iter_messages():
            msgs.setdefault(channel.topic, []).append(json.loads(message.data))
    poses = np.loadtxt(map_folder / "poses.txt")
    assert len(msgs["/tf"]) == len(poses) + 1 + len(msgs["/camera/rgb"])  # world->map, camera, keyframes
    with np.load(map_folder / "keyframes.npz") as kf:
        rgb0 = kf["rgb"][0]
        assert len(msgs["/camera/rgb"]) == len(kf["step"])
    img = msgs["/camera/rgb"][0]
    data = np.frombuffer(base64.b64decode(img["data"]), np.uint8).reshape(img["height"], img["width"], 3)
    assert np.array_equal(data, rgb0)
    cloud = msgs["/map"][0]
    assert (
        len(base64.b64decode(cloud["data"]))
        == 16 * json.loads((map_folder / "metrics.json").read_text())["n_gaussians"]
    )
    assert len(msgs["/trajectory"][0]["poses"]) == len(poses)
    # the calibration is the recording's own, in ROS's convention (pixel centres at whole numbers), and
    # the map was made with the same camera in the project's (centres at integer + 0.5)
    meta = json.loads((map_folder / "episode.json").read_text())
    calibration = np.reshape(msgs["/camera/calibration"][0]["K"], (3, 3))
    assert np.allclose(calibration, meta["K_ros"]) and np.allclose(calibration[:2, 2], 15.5)
    assert np.allclose(np.reshape(meta["K"], (3, 3))[:2, 2], 16.0)
    assert main(["export", str(map_folder), "--mcap", str(out)]) == 2  # exists: needs --overwrite
    assert main(["export", str(tmp_path), "--mcap", str(tmp_path / "x.mcap")]) == 2
    assert "not an episode or map folder" in capsys.readouterr().err


def test_export_refuses_bad_point_counts_and_paths(map_folder, tmp_path, capsys):
    out = tmp_path / "e.mcap"
    for n in ("0", "-1"):
        assert main(["export", str(map_folder), "--mcap", str(out), "--max-points", n]) == 2
        assert capsys.readouterr().err == (f"activesplat: error: --max-points must be >= 1 (leave it out for "
                                           f"every map point), got {n}\n")
    assert not out.exists()
    assert main(["export", str(map_folder), "--mcap", str(out), "--max-points", "1"]) == 0
    capsys.readouterr()
    with open(out, "rb") as f:
        messages = mcap_reader.make_reader(f).iter_messages()
        clouds = [json.loads(m.data) for _, c, m in messages if c.topic == "/map"]
    assert len(base64.b64decode(clouds[0]["data"])) == 16  # one point
    inside = out / "e1.mcap"  # out is a file
    assert main(["export", str(map_folder), "--mcap", str(inside)]) == 2
    assert capsys.readouterr().err == (f"activesplat: error: cannot write --mcap {inside}: {out} is a file, "
                                       f"not a folder\n")
    nested = tmp_path / "new" / "sub" / "e.mcap"  # missing folders are made
    assert main(["export", str(map_folder), "--mcap", str(nested)]) == 0 and nested.is_file()
    assert not list(tmp_path.rglob("*.partial"))


def test_a_corrupt_poses_file_is_refused_in_one_line(map_folder, tmp_path, capsys):
    """A bad line inside poses.txt was the end of the trajectory (the rest silently left out); now it is an
    error naming the file and the line. A last line cut by a crash is still dropped, as everywhere else."""
    import shutil

    folder = shutil.copytree(map_folder, tmp_path / "map")
    lines = (folder / "poses.txt").read_text().splitlines()
    out = tmp_path / "e.mcap"
    (folder / "poses.txt").write_text("\n".join([*lines[:2], lines[2][:40], *lines[3:]]) + "\n")
    assert main(["export", str(folder), "--mcap", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"activesplat: error: {folder / 'poses.txt'}, line 3: not a pose line") and \
        err.count("\n") == 1, err
    assert not out.exists() and not out.with_name(out.name + ".partial").exists()
    (folder / "poses.txt").write_text("\n".join([*lines[:-1], lines[-1][:40]]) + "\n")  # cut by a crash
    assert main(["export", str(folder), "--mcap", str(out)]) == 0
    with open(out, "rb") as f:
        trajectory = [json.loads(m.data) for _, c, m in mcap_reader.make_reader(f).iter_messages()
                      if c.topic == "/trajectory"]
    assert len(trajectory[0]["poses"]) == len(lines) - 1


def test_ctrl_c_leaves_no_half_written_file_and_says_what_is_written(map_folder, tmp_path, capsys,
                                                                     monkeypatch):
    """A Ctrl-C while a file is written leaves no partial file (nor replaces one already there), and its one
    line (exit code 130) says which file is written and which is not."""
    from activesplat.robot import export
    from activesplat.splat import ply

    def cut_short(gmap, path, *args, **kwargs):  # a PLY half written when Ctrl-C comes
        path.write_bytes(b"ply\nformat binary_little_endian 1.0\n")
        raise KeyboardInterrupt

    def ctrl_c(*args, **kwargs):
        raise KeyboardInterrupt

    out, ply_out = tmp_path / "e.mcap", tmp_path / "e.ply"
    monkeypatch.setattr(ply, "save_ply", cut_short)
    assert main(["export", str(map_folder), "--ply", str(ply_out), "--mcap", str(out)]) == 130
    assert capsys.readouterr().err.strip() == (f"export interrupted while writing --ply {ply_out}: {ply_out} "
                                               f"is not written (no partial file is left); run the same "
                                               f"command again")
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    monkeypatch.setattr(export, "_point_cloud", ctrl_c)  # the last message: the rest is in the file
    assert main(["export", str(map_folder), "--ply", str(ply_out), "--mcap", str(out)]) == 130
    assert capsys.readouterr().err.strip() == (f"export interrupted while writing --mcap {out}: {ply_out} is "
                                               f"written (complete), {out} is not written (no partial file "
                                               f"is left); run it again without --ply {ply_out}")
    assert [p.name for p in tmp_path.iterdir()] == ["e.ply"]
    out.write_bytes(b"an older export")
    assert main(["export", str(map_folder), "--mcap", str(out), "--overwrite"]) == 130
    assert capsys.readouterr().err.strip() == (f"export interrupted while writing --mcap {out}: {out} is not "
                                               f"written (the file already there is kept as it was); run the "
                                               f"same command again")
    assert out.read_bytes() == b"an older export" and sorted(p.name for p in tmp_path.iterdir()) == [
        "e.mcap", "e.ply"]
