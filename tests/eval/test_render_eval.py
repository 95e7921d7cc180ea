"""render-eval on a hand-made episode (tests/eval/conftest.py): a box room (exported to .glb), a 360 degree
look-around at 64 x 64, and a map built directly from the ground-truth RGB-D (one Gaussian per 2x2 pixels
of every third frame)."""

import json
import shutil

import numpy as np
import pytest
import torch

from activesplat.cli import main
from activesplat.errors import ActiveSplatError
from activesplat.eval.render_eval import (
    METRIC_KEYS,
    default_renderer,
    map_planar_depth,
    render_eval,
    render_gaussians_view,
    sample_test_poses,
    train_indices,
)
from activesplat.sim import SimConfig, Simulator, load_scene
from activesplat.splat.gaussians import GaussianMap
from activesplat.splat.ply import save_ply

SIM = SimConfig(width=64, height=64)  # as the episode fixture's (tests/eval/conftest.py)

FAST = dict(n_train=3, n_test=3, progress=False, backend="numba")


@pytest.fixture(scope="module")
def result(episode):
    out, _ = episode
    return render_eval(out, **FAST)


def test_writes_metrics_and_grid(episode, result):
    out, gmap = episode
    saved = json.loads((out / "render_metrics.json").read_text())
    for split in ("train", "test"):
        for key in ("psnr", "ssim", "ms_ssim", "lpips", "depth_l1_cm", "n_views"):
            assert key in saved[split], (split, key)
        assert saved[split]["n_views"] == 3 == len(saved[split]["views"])
        for key in ("psnr", "ssim", "lpips", "depth_l1_cm", "depth_l1_cm_normalised", "unmapped_pct"):
            assert np.isfinite(saved[split][key]), (split, key)
        assert saved[split]["ms_ssim"] is None  # 64 px is below MS-SSIM's 161 px minimum
    assert saved["n_gaussians"] == len(gmap)
    assert saved["train"]["psnr"] == pytest.approx(np.mean([v["psnr"] for v in saved["train"]["views"]]))
    assert (out / "render_grid.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_map_built_from_ground_truth_renders_well(result):
    train = result["train"]
    assert train["psnr"] > 18.0
    assert train["ssim"] > 0.5
    assert train["lpips"] < 0.5
    assert train["depth_l1_cm"] < 20.0  # an unoptimised map of 2x2-pixel isotropic blobs at 64 px
    assert train["unmapped_pct"] < 5.0
    assert 0.0 <= result["test"]["unmapped_pct"] <= 100.0


def test_perturbed_map_scores_worse(episode, result, tmp_path):
    out, gmap = episode
    g = torch.Generator().manual_seed(0)
    raw = {k: v.clone() for k, v in gmap.params.items()}
    raw["means"] += 0.08 * torch.randn(raw["means"].shape, generator=g)
    raw["f_dc"] += 0.8 * torch.randn(raw["f_dc"].shape, generator=g)
    folder = out / "refined_perturbed"
    save_ply(GaussianMap(raw), folder / "gaussians.ply")
    worse = render_eval(folder, **FAST)  # a map folder inside an episode is evaluated against the episode
    assert (folder / "render_metrics.json").is_file() and (folder / "render_grid.png").is_file()
    assert worse["gaussians"] == str(folder / "gaussians.ply")
    for split in ("train", "test"):
        assert worse[split]["psnr"] < result[split]["psnr"] - 1.0
        assert worse[split]["ssim"] < result[split]["ssim"]
        assert worse[split]["lpips"] > result[split]["lpips"]
    assert worse["train"]["depth_l1_cm"] > result["train"]["depth_l1_cm"]


def test_explicit_gaussians_and_out_dir(episode, result, tmp_path):
    out, _ = episode
    again = render_eval(out, gaussians_path=out / "gaussians.ply", out_dir=tmp_path / "o", **FAST)
    assert (tmp_path / "o" / "render_metrics.json").is_file()
    for split in ("train", "test"):  # deterministic: same views, same numbers
        for key in METRIC_KEYS:
            if result[split][key] is None:  # MS-SSIM is undefined below its minimum image size
                assert again[split][key] is None, (split, key)
            else:
                expected = pytest.approx(result[split][key], rel=1e-5, abs=1e-6)
                assert again[split][key] == expected, (split, key)


def test_custom_renderer(episode, result, tmp_path):
    """Maps of another kind (2DGS surfels) bring their own renderer; here: the default one with the colours
    halved, which must cost PSNR while leaving the depth error unchanged."""
    out, _ = episode
    calls = []

    def darker(gmap, pose, K, width, height, backend):
        calls.append(pose)
        rgb, depth, alpha = render_gaussians_view(gmap, pose, K, width, height, backend)
        return 0.5 * rgb, depth, alpha

    r = render_eval(out, out_dir=tmp_path, renderer=darker, **FAST)
    assert len(calls) == 6 and r["renderer"].endswith("darker")
    assert r["train"]["psnr"] < result["train"]["psnr"] - 3.0
    assert r["train"]["depth_l1_cm"] == pytest.approx(result["train"]["depth_l1_cm"])


def test_splits(episode):
    out, _ = episode
    assert train_indices(37, 4).tolist() == [0, 12, 24, 36]
    assert train_indices(3, 50).tolist() == [0, 1, 2]
    scene = load_scene(json.loads((out / "episode.json").read_text())["scene"])
    sim = Simulator(scene, seed=0, config=SIM)
    a, b, c = (sample_test_poses(sim, 20, seed=s) for s in (1, 1, 2))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.all(sim.navmap.is_navigable(a[:, 0, 3], a[:, 2, 3]))
    assert np.allclose(a[:, 1, 3], scene.floor_height + SIM.sensor_height)
    assert np.allclose(a[:, 1, 2], 0.0)  # level cameras (pitch 0)
    assert np.ptp(np.arctan2(a[:, 0, 2], a[:, 2, 2])) > np.pi  # yaws spread over the circle
    starts = np.stack([Simulator(scene, seed=s, config=SIM).start_pose for s in (1, 2)])
    assert not np.allclose(a[0], starts[0]) and not np.allclose(c[0], starts[1])  # not the agent's start draw


def test_bad_input(episode, tmp_path, capsys):
    out, _ = episode
    with pytest.raises(ActiveSplatError, match="not a folder"):
        render_eval(tmp_path / "missing", **FAST)
    with pytest.raises(ActiveSplatError, match="not an episode folder"):
        render_eval(tmp_path, **FAST)
    with pytest.raises(ActiveSplatError, match="positive"):
        render_eval(out, n_train=0, n_test=3, progress=False)
    with pytest.raises(ActiveSplatError, match="positive"):
        render_eval(out, n_train=3, n_test=-1, progress=False)
    no_map = tmp_path / "no_map"
    no_map.mkdir()
    for name in ("episode.json", "actions.txt", "poses.txt"):
        (no_map / name).write_bytes((out / name).read_bytes())
    with pytest.raises(ActiveSplatError, match="no map"):
        render_eval(no_map, **FAST)
    assert main(["render-eval", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("activesplat: error:") and "\n" not in err


def test_cli_prints_a_table(episode, tmp_path, capsys):
    out = shutil.copytree(episode[0], tmp_path / "copy")
    assert main(["render-eval", str(out), "--n-train", "1", "--n-test", "1", "--no-progress",
                 "--backend", "numba"]) == 0
    text = capsys.readouterr().out
    assert "train" in text and "test" in text and "PSNR" in text
    assert json.loads((out / "render_metrics.json").read_text())["train"]["n_views"] == 1


def test_without_the_lpips_weights_it_says_how_to_install_them_or_leaves_lpips_out(episode, tmp_path, capsys,
                                                                                    monkeypatch):
    out = shutil.copytree(episode[0], tmp_path / "copy")
    (out / "render_metrics.json").unlink(missing_ok=True)  # left there by the module's `result`
    monkeypatch.setenv("ACTIVESPLAT_LPIPS_WEIGHTS", str(tmp_path / "absent.ckpt"))
    argv = ["render-eval", str(out), "--n-train", "1", "--n-test", "1", "--no-progress", "--backend", "numba"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "absent.ckpt is not a file" in err and "\n" not in err
    assert not (out / "render_metrics.json").exists()  # it fails before rendering anything
    assert main([*argv, "--no-lpips"]) == 0
    text = capsys.readouterr().out
    saved = json.loads((out / "render_metrics.json").read_text())
    for split in ("train", "test"):
        assert saved[split]["lpips"] is None and saved[split]["views"][0]["lpips"] is None
        assert np.isfinite(saved[split]["psnr"]) and np.isfinite(saved[split]["depth_l1_cm"])
    assert "not measured" in saved["protocol"]["lpips"] and "n/a" in text


def test_cli_renders_a_refined_2dgs_folder_with_the_surfel_rasterizer(tmp_path, monkeypatch):
    import argparse

    from activesplat.refine import maps as reval
    from activesplat.refine.surfels import render_surfel_view

    (tmp_path / "episode.json").write_text("{}")
    refined = tmp_path / "refined_2dgs"
    refined.mkdir()
    (refined / "gaussians.ply").write_text("")
    seen = {}

    def fake_render_eval(path, **kwargs):
        seen.update(kwargs)
        return {}

    monkeypatch.setattr(reval, "render_eval", fake_render_eval)
    monkeypatch.setattr(reval, "format_table", lambda result, out: "")
    args = argparse.Namespace(dir=str(refined), n_train=1, n_test=1, seed=0, backend="numba",
                              no_progress=True)
    (refined / "refine.json").write_text(json.dumps({"method": "3dgs"}))
    reval.render_eval_from_args(args)
    assert seen["renderer"] is None
    (refined / "refine.json").write_text(json.dumps({"method": "2dgs"}))
    reval.render_eval_from_args(args)
    assert seen["renderer"] is render_surfel_view


def test_a_map_is_rendered_with_the_depth_it_was_trained_with(tmp_path):
    """render-eval reads ``planar_depth`` from the mapper.json beside the map (or the refine.json beside a
    refined map); no (or a broken) mapper.json means centre depths."""
    ply = tmp_path / "gaussians.ply"
    assert not map_planar_depth(ply)
    for planar in (True, False):
        (tmp_path / "mapper.json").write_text(json.dumps({"config": {"planar_depth": planar}}))
        assert map_planar_depth(ply) is planar
        assert default_renderer(ply).keywords == {"planar_depth": planar}  # render-eval's and the budget's
    (tmp_path / "mapper.json").write_text("{not json")
    assert not map_planar_depth(ply)
    (tmp_path / "mapper.json").unlink()  # a refined map: refine.json says how its depth was trained
    for planar in (True, False):
        (tmp_path / "refine.json").write_text(json.dumps({"method": "3dgs", "planar_depth": planar}))
        assert map_planar_depth(ply) is planar
