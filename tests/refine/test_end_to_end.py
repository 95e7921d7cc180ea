"""``activesplat refine`` end to end on a real (tiny) episode: a box room seen in a 64x64 look-around,
mapped by the online mapper and saved as an episode folder; refinement then render evaluation."""

import dataclasses
import json
import shutil

import numpy as np
import pytest

from activesplat.cli import main
from activesplat.episode import EpisodeWriter
from activesplat.refine import refine
from activesplat.sim import SimConfig, Simulator, box_room, load_scene
from activesplat.splat import Mapper

SIM = SimConfig(width=64, height=64)
EVAL = {"n_train": 2, "n_test": 2}


@pytest.fixture(scope="module")
def episode(tmp_path_factory):
    root = tmp_path_factory.mktemp("refine_e2e")
    scene_file = box_room().export(root / "box.glb")
    sim = Simulator(load_scene(str(scene_file)), seed=0, config=SIM)
    out = root / "episode"
    writer = EpisodeWriter(out)
    obs = sim.reset()
    meta = {"scene": str(scene_file), "z_up": False, "seed": 0, "policy": "scripted",
            "start_pose": sim.start_pose.tolist(), "config": {"sim": dataclasses.asdict(SIM)}}
    writer.start(meta, obs.pose)
    mapper = Mapper(sim.K, sim.width, sim.height, backend="numba")
    mapper.add_frame(obs.rgb, obs.depth, obs.pose, dense=True)
    for step in range(1, 10):
        obs = sim.step("turn_left")
        writer.record(step, "turn_left", obs.pose)
        mapper.add_frame(obs.rgb, obs.depth, obs.pose, dense=True)
    mapper.save(out)
    writer.finish({"steps": 9})
    return out


@pytest.mark.parametrize("method, renderer",
                         [("3dgs", "render_gaussians_view"), ("2dgs", "render_surfel_view")])
def test_refine_then_render_eval(episode, method, renderer):
    res = refine(episode, method, 4, backend="numba", progress=False, eval_kwargs=EVAL)
    out = episode / f"refined_{method}"
    assert res.complete and res.metrics is not None
    saved = json.loads((out / "render_metrics.json").read_text())
    assert saved["train"]["n_views"] == 2 and saved["gaussians"] == str(out / "gaussians.ply")
    assert renderer in saved["renderer"]
    assert saved["train"]["psnr"] > 15.0  # a real map of the room, not noise
    info = json.loads((out / "refine.json").read_text())
    assert info["iterations"] == 4 and info["n_keyframes"] == 10


def test_cli_runs_resumes_and_restarts(episode, tmp_path, capsys, monkeypatch):
    import activesplat.refine.trainer as trainer

    ep = shutil.copytree(episode, tmp_path / "ep", ignore=shutil.ignore_patterns("refined_*"))
    monkeypatch.setattr(trainer.Refiner, "evaluate", lambda self, ply, **kw: None)  # views: tested above
    argv = ["refine", str(ep), "--method", "3dgs", "--iters", "2", "--no-progress", "--backend", "numba"]
    assert main(argv) == 0
    first = capsys.readouterr().out
    assert "refined 3dgs: 2 iterations" in first and "refined_3dgs" in first
    assert main(argv) == 0  # complete: nothing is trained again
    assert "refined 3dgs: 2 iterations" in capsys.readouterr().out
    longer = [*argv[:5], "3", *argv[6:]]
    assert main(longer) == 2  # a checkpoint of a 2-iteration run
    err = capsys.readouterr().err.strip()
    assert err.startswith("activesplat: error:") and "--restart" in err and "\n" not in err
    assert main([*longer, "--restart"]) == 0
    assert "refined 3dgs: 3 iterations" in capsys.readouterr().out


def test_without_the_lpips_weights_refine_says_so_before_training_or_leaves_lpips_out(
        episode, tmp_path, capsys, monkeypatch):
    import activesplat.refine.trainer as trainer

    ep = shutil.copytree(episode, tmp_path / "ep", ignore=shutil.ignore_patterns("refined_*"))
    monkeypatch.setenv("ACTIVESPLAT_LPIPS_WEIGHTS", str(tmp_path / "absent.ckpt"))
    asked = []
    monkeypatch.setattr(trainer.Refiner, "evaluate", lambda self, ply, **kw: asked.append(kw))
    argv = ["refine", str(ep), "--iters", "2", "--no-progress", "--backend", "numba"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "absent.ckpt is not a file" in err and "\n" not in err
    assert not (ep / "refined_3dgs").exists()  # nothing was trained
    assert main([*argv, "--no-lpips"]) == 0
    assert "refined 3dgs: 2 iterations" in capsys.readouterr().out
    assert asked == [{"lpips": False}]


def test_image_size_renders_the_keyframes_again(episode, tmp_path, capsys):
    """--image-size: the keyframes are rendered again by the simulator at that size from their poses (the
    paper refines at 512 x 512 what it explored at 256 x 256), and the evaluation uses that size too."""
    from activesplat.refine.episode_map import load_episode_map, rerender_keyframes

    ep = shutil.copytree(episode, tmp_path / "ep", ignore=shutil.ignore_patterns("refined_*"))
    online = load_episode_map(ep)
    big = rerender_keyframes(ep, online, 96)
    assert big.rgb.shape == (10, 96, 96, 3) and big.depth.shape == (10, 96, 96) and big.width == 96
    assert big.K[0, 0] == pytest.approx(online.K[0, 0] * 1.5) and big.K[0, 2] == pytest.approx(48.0)
    np.testing.assert_array_equal(big.poses, online.poses)
    # the same view at both sizes: the larger one, averaged down, is the smaller one up to texture detail
    small = big.rgb[3].reshape(32, 3, 32, 3, 3).mean(axis=(1, 3))
    coarse = rerender_keyframes(ep, online, 32).rgb[3].astype(float)
    assert np.abs(small - coarse).mean() < 12.0
    res = refine(ep, "3dgs", 2, backend="numba", progress=False, eval_kwargs=EVAL, image_size=96)
    info = json.loads((ep / "refined_3dgs" / "refine.json").read_text())
    assert info["image_size"] == [96, 96] and res.metrics["width"] == 96 and res.metrics["height"] == 96
    # render-eval of the refined folder measures it as refine did (it evaluated at the episode's 64 and
    # overwrote refine's render_metrics.json with those numbers)
    evaluate = ["render-eval", str(ep / "refined_3dgs"), "--n-train", "2", "--n-test", "2", "--no-progress"]
    assert main(evaluate) == 0
    capsys.readouterr()
    again = json.loads((ep / "refined_3dgs" / "render_metrics.json").read_text())
    assert again["width"] == 96 and again["train"]["psnr"] == pytest.approx(res.metrics["train"]["psnr"])
    assert main(["refine", str(ep), "--iters", "2", "--image-size", "8", "--no-progress", "--restart"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("activesplat: error:") and "image_size" in err and "\n" not in err


def test_what_stops_the_evaluation_is_found_before_training(episode, tmp_path, capsys):
    """The evaluation after training needs episode.json and the scene's ground truth. A broken episode is
    refused before the first iteration (it used to fail after the last); an episode explored without
    ground truth (a robot) is refined and says why it was not evaluated (it used to fail at every rerun)."""
    from activesplat.errors import EpisodeError

    ep = shutil.copytree(episode, tmp_path / "ep", ignore=shutil.ignore_patterns("refined_*"))
    meta = json.loads((ep / "episode.json").read_text())
    (ep / "episode.json").unlink()
    with pytest.raises(EpisodeError, match="no episode.json"):
        refine(ep, "3dgs", 2, backend="numba", progress=False, eval_kwargs=EVAL)
    assert not (ep / "refined_3dgs").exists()
    (ep / "episode.json").write_text(json.dumps({**meta, "scene": str(tmp_path / "moved.glb")}))
    with pytest.raises(EpisodeError, match="moved.glb.*ground truth"):
        refine(ep, "3dgs", 2, backend="numba", progress=False, eval_kwargs=EVAL)
    assert not (ep / "refined_3dgs").exists()
    (ep / "episode.json").write_text(json.dumps({**meta, "source": "environment"}))
    argv = ["refine", str(ep), "--iters", "2", "--no-progress", "--backend", "numba", "--no-lpips"]
    for _ in range(2):  # the rerun of a completed run says it again
        assert main(argv) == 0
        out = capsys.readouterr().out
        assert "refined 3dgs: 2 iterations" in out and "not evaluated:" in out and "ground truth" in out
    assert (ep / "refined_3dgs" / "gaussians.ply").is_file()
    assert not (ep / "refined_3dgs" / "render_metrics.json").exists()


def test_a_completed_run_is_evaluated_again_when_asked_for_other_metrics(episode, tmp_path, monkeypatch):
    """Refining twice reuses render_metrics.json only when it was measured as now asked: a first run with
    --no-lpips and a second one with LPIPS used to print the metrics without LPIPS."""
    import activesplat.refine.trainer as trainer

    ep = shutil.copytree(episode, tmp_path / "ep", ignore=shutil.ignore_patterns("refined_*"))
    no_lpips = {**EVAL, "lpips": False}
    first = refine(ep, "3dgs", 2, backend="numba", progress=False, eval_kwargs=no_lpips)
    assert first.metrics["train"]["lpips"] is None
    asked = []
    monkeypatch.setattr(trainer.Refiner, "evaluate", lambda self, ply, **kw: asked.append(kw) or {"new": 1})
    again = refine(ep, "3dgs", 2, backend="numba", progress=False, eval_kwargs=no_lpips)
    assert asked == [] and again.metrics == first.metrics  # measured as asked: read back
    assert refine(ep, "3dgs", 2, backend="numba", progress=False, eval_kwargs=EVAL).metrics == {"new": 1}
    more = {"n_train": 3, "n_test": 2, "lpips": False}
    refine(ep, "3dgs", 2, backend="numba", progress=False, eval_kwargs=more)
    assert asked == [EVAL, more]
    path = ep / "refined_3dgs" / "render_metrics.json"  # measured at another size (render-eval used to)
    path.write_text(json.dumps({**json.loads(path.read_text()), "width": 32, "height": 32}))
    refine(ep, "3dgs", 2, backend="numba", progress=False, eval_kwargs=no_lpips)
    assert asked == [EVAL, more, no_lpips]


def test_restart_leaves_nothing_of_the_run_before(episode, tmp_path):
    """--restart removed the map, metrics and checkpoint but kept the old run's render_grid.png, which then
    sat beside the new run's checkpoint (and stayed there if it was stopped before the evaluation)."""
    ep = shutil.copytree(episode, tmp_path / "ep", ignore=shutil.ignore_patterns("refined_*"))
    out = ep / "refined_3dgs"
    refine(ep, "3dgs", 2, backend="numba", progress=False, eval_kwargs={**EVAL, "lpips": False})
    assert (out / "render_grid.png").is_file()
    refine(ep, "3dgs", 3, backend="numba", progress=False, restart=True, stop_at=1)
    assert sorted(p.name for p in out.iterdir()) == ["checkpoint.pt"]


def test_summary_compares_with_the_online_map_on_the_same_views_only(episode, tmp_path, capsys):
    """The summary printed the refined map's render-eval next to a running training PSNR called "keyframe
    PSNR" (another metric, other views) and nothing of the online map. It now names the training PSNR for
    what it is, and shows online -> refined when the episode's render_metrics.json has the same views."""
    from activesplat.eval.render_eval import render_eval

    ep = shutil.copytree(episode, tmp_path / "ep", ignore=shutil.ignore_patterns("refined_*", "render_*"))
    argv = ["refine", str(ep), "--iters", "2", "--no-progress", "--backend", "numba", "--no-lpips"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "training PSNR" in out and "running mean" in out and "keyframe PSNR" not in out
    assert "render-eval of the refined map (10 train / 50 test views" in out
    assert f"`activesplat render-eval {ep}`" in out  # how to get the online map's numbers
    online = render_eval(ep, backend="numba", progress=False, lpips=False)
    assert main(argv) == 0
    out = capsys.readouterr().out
    refined = json.loads((ep / "refined_3dgs" / "render_metrics.json").read_text())
    assert "online map -> refined on the same 10 train / 50 test views" in out
    assert f"PSNR {online['test']['psnr']:.2f} -> {refined['test']['psnr']:.2f} dB" in out
    render_eval(ep, backend="numba", progress=False, lpips=False, seed=1)  # other test poses
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "render-eval of the refined map" in out and " -> " not in out.split("\n", 2)[2]
    assert "not compared" in out and "other render-eval settings" in out
