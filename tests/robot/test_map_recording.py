"""`activesplat map`: recordings written from our simulator's frames (ROS 1 / ROS 2 / MCAP bags, a TUM
folder) map to the same map as the same frames given to the mapper directly; bad input is one line, a
depth unit the camera motion contradicts included; the held-out frames are capped (--max-heldout)."""

import json
import shutil

import numpy as np
import pytest
import torch

pytest.importorskip("rosbags")

from _bags import ARGS, ros_intrinsics, sim_frames, walk_frames, write_bag, write_tum  # noqa: E402

from activesplat.cli import main  # noqa: E402
from activesplat.robot.mapping import WORLD_UP  # noqa: E402
from activesplat.robot.recording import open_recording  # noqa: E402
from activesplat.splat import Mapper  # noqa: E402
from activesplat.splat.ply import load_ply  # noqa: E402

N = 10
HOLDOUT = 4


@pytest.fixture(scope="module")
def frames():
    return sim_frames(N, 32)


@pytest.fixture(scope="module")
def direct_map(frames, tmp_path_factory):
    """The online mapper fed the same (non-held-out) frames directly, as the explorer feeds it."""
    K, fr = frames
    torch.manual_seed(0)
    mapper = Mapper(K, 32, 32, backend="numba")
    for k, (rgb, depth, pose) in enumerate(fr):
        if k % HOLDOUT != HOLDOUT - 1:
            mapper.add_frame(rgb, depth, pose)
    return mapper


def _render(gmap, pose, K):
    from activesplat.eval.render_eval import render_gaussians_view

    return render_gaussians_view(gmap, pose, K, 32, 32, "numba")


def _same_map(folder, direct, K, fr, rgb_tol=1e-4):
    gmap = load_ply(folder / "gaussians.ply")
    assert abs(len(gmap) - len(direct.gaussians)) <= max(2, len(direct.gaussians) // 100)
    for _, _, pose in fr[::3]:
        a = _render(gmap, pose, K)
        b = _render(direct.gaussians, pose, K)
        assert np.abs(a[0] - b[0]).mean() < rgb_tol
        assert np.abs(a[1] - b[1]).mean() < 10 * rgb_tol


def _map(bag, out, *options):
    argv = ["map", str(bag), *ARGS, "--pose-source", "/camera_pose", "--out", str(out), "--backend", "numba"]
    return main([*argv, "--no-progress", *options])


@pytest.mark.parametrize("fmt", ["mcap", "ros1"])
def test_bag_maps_like_the_online_mapper(fmt, frames, direct_map, tmp_path, capsys):
    K, fr = frames
    bag = write_bag(tmp_path / ("rec.bag" if fmt == "ros1" else "rec"), K, fr, fmt=fmt)
    if fmt == "mcap":  # a bare .mcap file, as ROS 2 records it
        bag = next(bag.glob("*.mcap"))
    out = tmp_path / "map"
    assert _map(bag, out, "--holdout-every", str(HOLDOUT)) == 0
    assert "mapped 8 of 10 frames (2 held out" in capsys.readouterr().out
    for name in (
        "gaussians.ply",
        "keyframes.npz",
        "mapper.json",
        "topdown.png",
        "poses.txt",
        "trajectory_tum.txt",
        "heldout.npz",
        "episode.json",
        "metrics.json",
    ):
        assert (out / name).is_file(), name
    assert not (tmp_path / "map.partial").exists()
    meta = json.loads((out / "episode.json").read_text())
    assert meta["source"] == "recording" and meta["mapped_frames"] == 8
    poses = np.loadtxt(out / "poses.txt")[:, 1:].reshape(-1, 4, 4)
    np.testing.assert_allclose(poses, np.stack([p for _, _, p in fr]), atol=1e-9)
    _same_map(out, direct_map, K, fr)


def test_tum_folder_and_tf_poses_and_16bit_depth(frames, direct_map, tmp_path):
    K, fr = frames
    tum = write_tum(tmp_path / "tum", K, fr)
    rec = open_recording(tum, intrinsics=ros_intrinsics(K))
    assert len(rec) == N
    np.testing.assert_allclose(
        np.einsum("ij,njk->nik", WORLD_UP["z"], rec.poses), [p for _, _, p in fr], atol=1e-9
    )
    bag = write_bag(
        tmp_path / "tf", K, fr, fmt="ros2", pose="tf", depth_encoding="16UC1", rgb_encoding="bgr8"
    )
    rec = open_recording(bag, *ARGS[1::2], pose_source="tf:map")
    np.testing.assert_allclose(
        np.einsum("ij,njk->nik", WORLD_UP["z"], rec.poses), [p for _, _, p in fr], atol=1e-9
    )
    for k, rgb, depth in rec.frames():  # mm depth: within half a millimetre; bgr8 back to rgb
        assert np.array_equal(rgb, fr[k][0])
        assert np.abs(depth - fr[k][1]).max() <= 5.01e-4
    bag = write_bag(tmp_path / "png", K, fr[:3], fmt="mcap", rgb_encoding="png")
    rec = open_recording(bag, *ARGS[1::2], pose_source="/camera_pose")
    assert all(np.array_equal(rgb, fr[k][0]) for k, rgb, _ in rec.frames())


def test_odometry_of_the_base_and_the_static_camera_mount(frames, tmp_path):
    K, fr = frames
    bag = write_bag(tmp_path / "odom", K, fr[:4], fmt="mcap", pose="odom")
    rec = open_recording(bag, *ARGS[1::2], pose_source="/odom")
    want = [p for _, _, p in fr[:4]]
    np.testing.assert_allclose(np.einsum("ij,njk->nik", WORLD_UP["z"], rec.poses), want, atol=1e-9)


def test_render_eval_and_refine_accept_a_recorded_map(frames, tmp_path, capsys):
    K, fr = frames
    bag = write_bag(tmp_path / "rec", K, fr, fmt="mcap")
    out = tmp_path / "map"
    assert _map(bag, out, "--holdout-every", "3") == 0
    assert main(["render-eval", str(out), "--backend", "numba", "--no-progress"]) == 0
    m = json.loads((out / "render_metrics.json").read_text())
    assert m["train"]["n_views"] == 3 and m["test"]["n_views"] == 0
    assert m["train"]["psnr"] > 10 and [v["step"] for v in m["train"]["views"]] == [2, 5, 8]
    assert main(["refine", str(out), "--iters", "3", "--backend", "numba", "--no-progress"]) == 0
    assert (out / "refined_3dgs" / "render_metrics.json").is_file()
    capsys.readouterr()


def _err(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("activesplat: error: ") and "\n" not in err, err
    return err


def test_bad_recordings_fail_in_one_line_and_write_nothing(frames, tmp_path, capsys):
    K, fr = frames
    fr = fr[:4]
    out = tmp_path / "out"
    base = ["--pose-source", "/camera_pose", "--out", str(out), "--no-progress", "--backend", "numba"]

    bag = write_bag(tmp_path / "nodepth", K, fr, skip_topic="/camera/depth/image_raw")
    assert "--depth-topic /camera/depth/image_raw: no such topic" in _err(
        capsys, ["map", str(bag), *ARGS, *base]
    )

    bag = write_bag(tmp_path / "enc", K, fr, fmt="ros2", rgb_encoding="rgb8", depth_encoding="16UC1")
    bad = ["--rgb-topic", "/camera/depth/image_raw", *ARGS[2:]]  # a 16UC1 image as colour
    assert "/camera/depth/image_raw: message 0: unsupported colour encoding '16UC1'" in _err(
        capsys, ["map", str(bag), *bad, *base]
    )

    bag = write_bag(tmp_path / "nopose", K, fr, drop_pose_after=2)
    err = _err(capsys, ["map", str(bag), *ARGS, *base])
    assert "/camera/color/image_raw: message 2" in err and "no pose from /camera_pose" in err

    stamps = [0, 1, 3, 2]
    bag = write_bag(tmp_path / "back", K, fr, stamps=[10**18 + s * 10**8 for s in stamps])
    err = _err(capsys, ["map", str(bag), *ARGS, *base])
    assert "message 3" in err and "non-monotonic" in err

    bag = write_bag(tmp_path / "trunc.bag", K, fr, fmt="ros1")
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) * 2 // 3])
    assert "truncated or corrupt" in _err(capsys, ["map", str(bag), *ARGS, *base])
    mcap = next(write_bag(tmp_path / "trunc", K, fr).glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size * 2 // 3])
    assert "truncated or corrupt" in _err(capsys, ["map", str(mcap), *ARGS, *base])

    assert "--pose-source /odom: no such topic" in _err(
        capsys, ["map", str(bag.parent / "nopose"), *ARGS, *base[2:], "--pose-source", "/odom"]
    )
    assert not out.exists() and not (tmp_path / "out.partial").exists()


def test_an_existing_map_needs_overwrite(frames, tmp_path, capsys):
    K, fr = frames
    bag = write_bag(tmp_path / "rec", K, fr[:3])
    out = tmp_path / "map"
    argv = [
        "map",
        str(bag),
        *ARGS,
        "--pose-source",
        "/camera_pose",
        "--holdout-every",
        "0",
        "--out",
        str(out),
        "--no-progress",
        "--backend",
        "numba",
    ]
    assert main(argv) == 0
    assert "pass --overwrite" in _err(capsys, argv)
    assert main([*argv, "--overwrite"]) == 0
    shutil.rmtree(out)


def test_commands_that_need_a_simulated_episode_say_so(frames, tmp_path, capsys):
    K, fr = frames
    bag = write_bag(tmp_path / "rec", K, fr[:3])
    folder = tmp_path / "map"
    assert _map(bag, folder, "--holdout-every", "0") == 0
    assert "is a map of a recording" in _err(capsys, ["evaluate", str(folder)])
    assert _err(capsys, ["refine", str(folder), "--image-size", "64"]) == (
        f"activesplat: error: --image-size needs a simulated episode (the simulator renders the keyframes "
        f"again at that size); {folder} is a map of a recording (activesplat map): leave --image-size out")
    assert _err(capsys, ["render-eval", str(folder), "--budget", "--no-progress"]) == (
        f"activesplat: error: --budget needs a simulated episode (ground truth rendered from the scene "
        f"mesh); {folder} is a map of a recording (activesplat map): leave --budget out")
    assert not (folder / "render_metrics.json").exists()  # refused before the evaluation ran


def test_map_without_backend_option(frames, tmp_path, capsys):
    K, fr = frames
    tum = write_tum(tmp_path / "tum", K, fr[:3])
    out = tmp_path / "map"
    argv = ["map", str(tum), "--intrinsics", *(str(v) for v in ros_intrinsics(K)),
            "--holdout-every", "0", "--out", str(out), "--no-progress"]
    assert main(argv) == 0, capsys.readouterr().err
    assert json.loads((out / "episode.json").read_text())["backend"] == "auto"


def test_what_is_not_a_recording_says_what_map_reads(frames, tmp_path, capsys):
    from activesplat.robot.recording import RECORDINGS

    K, fr = frames
    bag = write_bag(tmp_path / "rec", K, fr[:3])
    folder = tmp_path / "map"
    assert _map(bag, folder, "--holdout-every", "0") == 0
    exported = tmp_path / "e.mcap"
    assert main(["export", str(folder), "--mcap", str(exported)]) == 0
    capsys.readouterr()
    assert _err(capsys, ["map", str(exported), *ARGS, "--pose-source", "tf:map"]) == (
        f"activesplat: error: {exported}: an MCAP file of profile '' written by `activesplat export` for "
        f"Foxglove (JSON messages), not a ROS bag; `map` reads {RECORDINGS}")
    mesh = tmp_path / "s.glb"
    mesh.write_bytes(b"glTF")
    assert _err(capsys, ["map", str(mesh)]) == (
        f"activesplat: error: {mesh}: a mesh, not a recording; `map` reads {RECORDINGS}. To explore the "
        f"mesh, run `activesplat explore --scene {mesh}`")
    assert f"{folder}: an episode or map folder, not a recording" in _err(capsys, ["map", str(folder)])
    assert "neither a ROS 2 bag (no metadata.yaml) nor a TUM RGB-D folder" in _err(
        capsys, ["map", str(tmp_path / "rec" / "..")])
    assert "ROS 1 bag (.bag)" in RECORDINGS and "TUM RGB-D folder" in RECORDINGS


def _open_bag(bag, **options):
    return open_recording(bag, *ARGS[1::2], pose_source="/camera_pose", **options)


def test_stride_and_holdout_count_the_same_frames(frames, tmp_path):
    from activesplat.robot.mapping import map_recording

    K, fr = frames
    rec = _open_bag(write_bag(tmp_path / "rec", K, fr))
    m = map_recording(rec, tmp_path / "map", holdout_every=2, stride=2, backend="numba", progress=False)
    # --stride 2 keeps frames 0 2 4 6 8; every 2nd of those is held out (before: every 2nd of all
    # frames, all odd, so none was held out and render-eval had nothing to score)
    assert (m["mapped_frames"], m["heldout_frames"]) == (3, 2)
    with np.load(tmp_path / "map" / "heldout.npz") as held:
        assert held["index"].tolist() == [2, 6]


def test_ctrl_c_keeps_the_map_of_the_frames_so_far(frames, tmp_path, capsys):
    from activesplat.robot.mapping import map_recording

    K, fr = frames
    rec = _open_bag(write_bag(tmp_path / "rec", K, fr))
    stream = rec._frames

    def interrupted():
        for k, rgb, depth in stream():
            if k == 6:
                raise KeyboardInterrupt
            yield k, rgb, depth

    rec._frames = interrupted
    out = tmp_path / "map"
    with pytest.raises(KeyboardInterrupt):
        map_recording(rec, out, holdout_every=HOLDOUT, backend="numba", progress=False)
    assert "interrupted after 6 of 10 frames: partial map of 5 frames in" in capsys.readouterr().err
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["complete"] is False and metrics["read_frames"] == 6 and metrics["mapped_frames"] == 5
    assert len(load_ply(out / "gaussians.ply")) > 0 and len(np.loadtxt(out / "poses.txt")) == 6
    assert not (tmp_path / "map.partial").exists()
    rec._frames = lambda: (_ for _ in ()).throw(KeyboardInterrupt)  # nothing mapped yet: nothing kept
    with pytest.raises(KeyboardInterrupt):
        map_recording(rec, tmp_path / "none", backend="numba", progress=False)
    assert not (tmp_path / "none").exists() and not (tmp_path / "none.partial").exists()


def test_ctrl_c_is_one_line_and_exit_code_130(frames, tmp_path, capsys, monkeypatch):
    """What is kept and how to map it all, in one line (not followed by a generic "interrupted"); before a
    frame is mapped, or while scanning the recording, that nothing was written (a map there is kept)."""
    from activesplat.robot import recording

    K, fr = frames
    bag = write_bag(tmp_path / "rec", K, fr)
    stream = recording.Recording.frames

    def interrupted_at(n):
        def frames(self, only=None):
            for k, rgb, depth in stream(self, only):
                if k == n:
                    raise KeyboardInterrupt
                yield k, rgb, depth
        return frames

    out = tmp_path / "map"
    monkeypatch.setattr(recording.Recording, "frames", interrupted_at(6))
    assert _map(bag, out) == 130
    assert capsys.readouterr().err.strip() == (
        f"interrupted after 6 of 10 frames: partial map of 6 frames in {out} (\"complete\": false in its "
        f"metrics.json); the same command with --overwrite maps the whole recording")
    assert json.loads((out / "metrics.json").read_text())["complete"] is False
    before = (out / "metrics.json").read_bytes()
    monkeypatch.setattr(recording.Recording, "frames", interrupted_at(0))
    assert _map(bag, out, "--overwrite") == 130
    assert capsys.readouterr().err.strip() == (
        f"interrupted before the first frame was mapped (0 of 10 read): no map written to {out} (the one "
        f"there is kept); the same command starts again")
    assert (out / "metrics.json").read_bytes() == before and not (tmp_path / "map.partial").exists()
    monkeypatch.setattr("activesplat.robot.recording.open_recording", _ctrl_c)
    assert _map(bag, tmp_path / "none") == 130
    assert capsys.readouterr().err.strip() == (
        f"interrupted while scanning the recording: no map written to {tmp_path / 'none'}; the same command "
        f"starts again")
    assert not (tmp_path / "none").exists()


def _ctrl_c(*args, **kwargs):
    raise KeyboardInterrupt


def test_a_frame_without_pose_says_why(frames, tmp_path):
    from activesplat.errors import RecordingError
    from activesplat.robot.transforms import PoseTrack

    K, fr = frames
    tum = write_tum(tmp_path / "tum", K, fr[:4])
    gt = (tum / "groundtruth.txt").read_text().splitlines()
    (tum / "groundtruth.txt").write_text("\n".join(gt[:1] + gt[2:]) + "\n")  # the first pose is missing
    with pytest.raises(RecordingError) as err:
        open_recording(tum, intrinsics=ros_intrinsics(K))
    assert "0.100 s before the first pose of groundtruth.txt" in str(err.value)
    assert "at most a tenth of --max-pose-gap, 0.050 s" in str(err.value)  # not "within 0.5 s"
    track = PoseTrack([0, 10**9], [np.eye(4)] * 2, "/odom")
    assert track.at(5 * 10**8, 5 * 10**8) is not None and track.at(4 * 10**8, 5 * 10**8) is None
    assert "a gap of 1.000 s between poses of /odom" in track.why_none(4 * 10**8, 5 * 10**8)
    bag = write_bag(tmp_path / "tf", K, fr[:4], pose="tf", drop_pose_after=2)
    with pytest.raises(RecordingError) as err:
        open_recording(bag, *ARGS[1::2], pose_source="tf:map")
    assert "message 2" in str(err.value)
    assert "after the last pose of map -> camera_color_optical_frame" in str(err.value)


def test_a_bag_without_camera_info_takes_intrinsics(frames, tmp_path, capsys):
    K, fr = frames
    bag = write_bag(tmp_path / "rec", K, fr[:3], skip_topic="/camera/color/camera_info")
    intr = [str(v) for v in ros_intrinsics(K)]
    out = tmp_path / "map"
    err = _err(capsys, ["map", str(bag), *ARGS[:4], "--out", str(out)])
    assert err.endswith(
        "a bag needs --camera-info-topic (or --intrinsics), --pose-source; topics: /camera/color/image_raw "
        "(sensor_msgs/msg/Image), /camera/depth/image_raw (sensor_msgs/msg/Image), /camera_pose "
        "(geometry_msgs/msg/PoseStamped)"), err
    assert "no such topic in rec (topics: /camera/color/image_raw (sensor_msgs/msg/Image)," in _err(
        capsys, ["map", str(bag), *ARGS, "--pose-source", "/camera_pose"])
    assert "not both" in _err(capsys, ["map", str(bag), *ARGS, "--intrinsics", *intr, "--pose-source", "x"])
    argv = ["map", str(bag), *ARGS[:4], "--intrinsics", *intr, "--pose-source", "/camera_pose",
            "--holdout-every", "0", "--out", str(out), "--no-progress", "--backend", "numba"]
    assert main(argv) == 0
    meta = json.loads((out / "episode.json").read_text())
    assert np.allclose(meta["K"], K) and (meta["width"], meta["height"]) == (32, 32)
    assert meta["camera_frame"] == "camera_color_optical_frame"  # the colour images' frame
    capsys.readouterr()


def test_intrinsics_of_another_resolution_are_refused(frames, tmp_path, capsys):
    K, fr = frames
    tum = write_tum(tmp_path / "tum", K, fr[:2])
    err = _err(capsys, ["map", str(tum), "--intrinsics", "517.3", "516.5", "318.6", "255.3", "--out",
                        str(tmp_path / "map")])
    assert err.endswith("--intrinsics: principal point (318.6, 255.3) outside the 32x32 images: "
                        "intrinsics of another resolution? (scale fx fy cx cy by the image size over the "
                        "calibrated size)")
    bag = write_bag(tmp_path / "rec", K * [[20], [20], [1]], fr[:2])  # CameraInfo of a 640x640 camera
    assert "/camera/color/camera_info: message 0: principal point (319.5, 319.5) outside the 32x32" in _err(
        capsys, ["map", str(bag), *ARGS, "--pose-source", "/camera_pose"])


def test_poses_of_a_body_frame_or_another_up_axis_warn(frames, tmp_path):
    from activesplat.robot.mapping import map_recording, upright_pct

    K, fr = frames
    bag = write_bag(tmp_path / "odom", K, fr[:4], pose="odom")
    good = open_recording(bag, *ARGS[1::2], pose_source="/odom")
    assert upright_pct(np.einsum("ij,njk->nik", WORLD_UP["z"], good.poses)) == 100.0
    body = open_recording(bag, *ARGS[1::2], pose_source="/odom", camera_in_body=[0, 0, 0, 0, 0, 0, 1])
    with pytest.warns(UserWarning, match=r"upright .* in only 0% of the frames: are the poses of the "
                                         r"camera's optical frame .* in a z-up world \(--world-up\)"):
        map_recording(body, tmp_path / "body", holdout_every=0, backend="numba", progress=False)
    with pytest.warns(UserWarning, match="in a y-up world"):
        map_recording(good, tmp_path / "y", holdout_every=0, world_up="y", backend="numba", progress=False)
    assert json.loads((tmp_path / "y" / "episode.json").read_text())["upright_pct"] == 0.0


def test_compressed_depth_of_image_transport(frames, tmp_path, capsys):
    K, fr = frames
    for kind, tol in (("compressedDepth16", 5.01e-4), ("compressedDepth32", 0.02)):
        bag = write_bag(tmp_path / kind, K, fr[:3], depth_encoding=kind, rgb_encoding="png")
        rec = _open_bag(bag)
        for k, rgb, depth in rec.frames():
            assert np.array_equal(rgb, fr[k][0]) and np.array_equal(depth > 0, fr[k][1] > 0)
            assert np.abs(depth - fr[k][1]).max() <= tol  # mm, or 1/100 m of inverse depth at <= 3 m
    import cv2

    from activesplat.errors import RecordingError

    big = [(cv2.resize(rgb, (64, 48)), depth, T) for rgb, depth, T in fr[:3]]  # colour not registered
    rec = _open_bag(write_bag(tmp_path / "big", K, big, rgb_encoding="png"))  # sizes unknown until decoded
    with pytest.raises(RecordingError, match=r"image_raw: message 0: a 64x48 image, but the camera is 32x32"):
        next(iter(rec.frames()))


# --------------------------------------------------------------------------- the depth check
@pytest.fixture(scope="module")
def walk():
    return walk_frames(8, 48)


def test_a_tum_folder_of_another_depth_scale_is_refused(walk, tmp_path, capsys):
    K, fr = walk
    tum = write_tum(tmp_path / "tum", K, fr, depth_scale=1000.0)  # saved in millimetres
    out = tmp_path / "map"
    argv = ["map", str(tum), "--intrinsics", *(str(v) for v in ros_intrinsics(K)), "--out", str(out),
            "--no-progress", "--backend", "numba", "--holdout-every", "0"]
    err = _err(capsys, argv)  # read at the default 5000 units per metre: everything 5x too small
    assert "the depth looks 5.0x too small for the camera motion" in err, err
    assert err.endswith("is --depth-scale 5000 right for this folder? Try --depth-scale 1000 "
                        "(--no-depth-check maps it anyway)"), err
    assert not out.exists() and not (tmp_path / "map.partial").exists()

    assert main([*argv, "--no-depth-check"]) == 0  # the rare recording where the check misfires
    meta = json.loads((out / "episode.json").read_text())
    assert meta["depth_check"] == {"note": "skipped (--no-depth-check)"}
    capsys.readouterr()

    rec = open_recording(tum, intrinsics=ros_intrinsics(K), depth_scale=1000.0)  # the right scale
    check = rec.info["depth_check"]
    assert check["confident"] and abs(check["scale"] - 1.0) < 0.05 and len(check["pairs"]) >= 2


def test_a_right_scale_passes_and_is_recorded(walk, tmp_path, capsys):
    K, fr = walk
    tum = write_tum(tmp_path / "tum", K, fr)
    out = tmp_path / "map"
    assert main(["map", str(tum), "--intrinsics", *(str(v) for v in ros_intrinsics(K)), "--out", str(out),
                 "--no-progress", "--backend", "numba", "--holdout-every", "0"]) == 0
    assert '"depth_scale_check": 1.0' in capsys.readouterr().out
    check = json.loads((out / "episode.json").read_text())["depth_check"]
    assert check["confident"] and abs(check["scale"] - 1.0) < 0.03
    assert all(abs(p["s"] - 1.0) < 0.05 and p["pixels"] >= 200 for p in check["pairs"])


def test_16uc1_depth_that_is_not_millimetres_is_refused(walk, tmp_path, capsys):
    K, fr = walk
    tenth_mm = [(rgb, depth * 10.0, pose) for rgb, depth, pose in fr]  # 16UC1 in tenths of a millimetre
    bag = write_bag(tmp_path / "rec", K, tenth_mm, depth_encoding="16UC1")
    err = _err(capsys, ["map", str(bag), *ARGS, "--pose-source", "/camera_pose", "--out",
                        str(tmp_path / "map")])
    assert "the depth looks 10.0x too large for the camera motion" in err, err
    assert err.endswith("/camera/depth/image_raw is read as millimetres (16UC1 / mono16) or metres (32FC1): "
                        "is it recorded in another unit? (--no-depth-check maps it anyway)"), err


def test_a_recording_that_does_not_move_is_not_judged(tmp_path):
    K, fr = walk_frames(6, 32, step=0.0)  # turns on the spot: no pair of frames 10 cm apart
    tum = write_tum(tmp_path / "tum", K, fr, depth_scale=1000.0)  # even at the wrong scale
    rec = open_recording(tum, intrinsics=ros_intrinsics(K))
    assert rec.info["depth_check"] == {
        "pairs": [], "scale": None, "note": "not checked: no two frames 0.1 m apart",
        "seconds": rec.info["depth_check"]["seconds"]}


def test_the_held_out_frames_are_capped_and_spread_over_the_recording(tmp_path, capsys):
    from activesplat.robot.mapping import heldout_indices, map_recording

    assert heldout_indices(20, 2, 1, None).tolist() == list(range(1, 20, 2))
    assert heldout_indices(20, 2, 1, 4).tolist() == [1, 7, 13, 19]  # the first and the last, evenly apart
    assert heldout_indices(20, 2, 2, 3).tolist() == [2, 10, 18]  # every 2nd of the frames --stride keeps
    assert heldout_indices(20, 2, 1, 0).tolist() == [] and heldout_indices(20, 0, 1, 5).tolist() == []
    assert heldout_indices(1000, 8, 1, 200).tolist() == list(range(7, 1000, 8))[:125]  # 125 <= 200: all

    K, fr = walk_frames(20, 32, step=0.03)
    tum = write_tum(tmp_path / "tum", K, fr)
    rec = open_recording(tum, intrinsics=ros_intrinsics(K))
    out = tmp_path / "map"
    m = map_recording(rec, out, holdout_every=2, max_heldout=4, backend="numba", progress=False)
    assert (m["mapped_frames"], m["heldout_frames"]) == (16, 4)  # the other every-2nd frames are mapped
    with np.load(out / "heldout.npz") as held:
        assert held["index"].tolist() == [1, 7, 13, 19] and held["rgb"].shape == (4, 32, 32, 3)
        assert np.array_equal(held["rgb"][1], fr[7][0]) and np.allclose(held["pose"][3], fr[19][2], atol=1e-9)
    meta = json.loads((out / "episode.json").read_text())
    assert (meta["max_heldout"], meta["holdout_candidates"], meta["heldout_frames"]) == (4, 10, 4)
    assert main(["render-eval", str(out), "--backend", "numba", "--no-progress", "--no-lpips"]) == 0
    metrics = json.loads((out / "render_metrics.json").read_text())
    assert [v["step"] for v in metrics["train"]["views"]] == [1, 7, 13, 19]
    assert "4 of those 10 spread over the recording" in metrics["protocol"]["train"]
    capsys.readouterr()
