"""``refine`` on a tiny episode rendered from a known Gaussian scene: it improves the map, writes its
outputs, resumes from a checkpoint to the same result as an uninterrupted run, and rejects bad input."""

import json
import shutil

import numpy as np
import pytest
import torch
from _refine_scene import make_episode

from activesplat.cli import main
from activesplat.errors import EpisodeError, InvalidInputError
from activesplat.eval.render_eval import map_planar_depth
from activesplat.refine import RefineConfig, Refiner, refine
from activesplat.refine.trainer import CHECKPOINT
from activesplat.splat import load_ply

# density control early, often and until the end, so that 16 iterations exercise clone / split / prune at
# 4, 8, 12 and an opacity reset at 10, and a resume from iteration 7 crosses them
FAST = RefineConfig(densify_from_iter=3, densify_interval=4, opacity_reset_interval=10,
                    densify_until_frac=1.0, checkpoint_every=5)


@pytest.fixture(scope="module")
def episode(tmp_path_factory):
    return make_episode(tmp_path_factory.mktemp("refine") / "ep")


@pytest.fixture
def fresh(episode, tmp_path):
    """A private copy of the episode (refinement writes into it)."""
    return shutil.copytree(episode, tmp_path / "ep")


def test_refinement_improves_the_keyframes(fresh):
    refiner = Refiner(fresh, "3dgs", 20, backend="numba", progress=False)  # 3DGS schedule: no ADC yet
    before = refiner.keyframe_metrics()
    refiner.train()
    after = refiner.keyframe_metrics()
    assert after["psnr"] > before["psnr"] + 2.5, (before, after)
    assert after["loss"] < 0.8 * before["loss"]
    assert after["depth_l1_m"] < 0.85 * before["depth_l1_m"]
    assert refiner.history[-1]["iteration"] == 20


def test_outputs(fresh):
    res = refine(fresh, "3dgs", 6, config=FAST, backend="numba", progress=False, evaluate=False)
    out = fresh / "refined_3dgs"
    assert res.complete and res.out_dir == out and res.iterations == 6
    gmap = load_ply(out / "gaussians.ply")
    assert len(gmap) == res.n_gaussians
    info = json.loads((out / "refine.json").read_text())
    assert info["iterations"] == 6 and info["n_gaussians"] == res.n_gaussians and info["method"] == "3dgs"
    assert (out / CHECKPOINT).is_file()
    # the online map is left as it was
    assert len(load_ply(fresh / "gaussians.ply")) == res.n_gaussians_initial
    # depth is rendered as the online map was trained, and render-eval reads that from refine.json
    assert info["planar_depth"] is json.loads((fresh / "mapper.json").read_text())["config"]["planar_depth"]
    assert map_planar_depth(out / "gaussians.ply") is info["planar_depth"]


@pytest.mark.parametrize("planar", [True, False, None])
def test_refinement_renders_depth_as_the_online_map_was_trained(fresh, planar):
    """3DGS refinement takes ``planar_depth`` from the episode's mapper.json; a mapper.json written before
    the option existed (no key) made its map with centre depths."""
    meta = json.loads((fresh / "mapper.json").read_text())
    meta["config"].pop("planar_depth")
    if planar is not None:
        meta["config"]["planar_depth"] = planar
    (fresh / "mapper.json").write_text(json.dumps(meta))
    refiner = Refiner(fresh, "3dgs", 1, backend="numba", progress=False)
    assert refiner.method.planar_depth is bool(planar)
    assert refiner.method.eval_renderer().endswith("planar depth") is bool(planar)
    forced = Refiner(fresh, "3dgs", 1, config=RefineConfig(planar_depth=not planar), backend="numba",
                     progress=False, out_dir=fresh / "forced")
    assert forced.method.planar_depth is (not planar)


def test_resume_gives_the_same_map_as_an_uninterrupted_run(episode, tmp_path):
    a = shutil.copytree(episode, tmp_path / "a")
    b = shutil.copytree(episode, tmp_path / "b")
    whole = refine(a, "3dgs", 16, config=FAST, backend="numba", progress=False, evaluate=False)
    part = refine(b, "3dgs", 16, config=FAST, backend="numba", progress=False, evaluate=False, stop_at=7)
    assert part.iterations == 7 and not part.complete
    assert not (b / "refined_3dgs" / "gaussians.ply").exists()
    resumed = Refiner(b, "3dgs", 16, config=FAST, backend="numba", progress=False)
    assert resumed.resumed and resumed.iteration == 7
    rest = refine(b, "3dgs", 16, config=FAST, backend="numba", progress=False, evaluate=False)
    assert rest.iterations == 16 and rest.n_gaussians == whole.n_gaussians
    ga, gb = load_ply(a / "refined_3dgs" / "gaussians.ply"), load_ply(b / "refined_3dgs" / "gaussians.ply")
    for name in ga.params:
        assert torch.equal(ga.params[name], gb.params[name]), name
    assert rest.densify == whole.densify
    assert whole.densify["cloned"] + whole.densify["split"] > 0  # density control ran (and a reset at 10)


def test_checkpoint_of_another_run_needs_restart(fresh):
    refine(fresh, "3dgs", 10, config=FAST, backend="numba", progress=False, evaluate=False, stop_at=5)
    with pytest.raises(InvalidInputError, match="--restart"):
        Refiner(fresh, "3dgs", 20, config=FAST, backend="numba", progress=False)
    again = Refiner(fresh, "3dgs", 20, config=FAST, backend="numba", progress=False, restart=True)
    assert again.iteration == 0 and not again.resumed
    assert not (fresh / "refined_3dgs" / CHECKPOINT).exists()


def test_completed_run_is_not_repeated(fresh):
    first = refine(fresh, "3dgs", 4, config=FAST, backend="numba", progress=False, evaluate=False)
    ply = fresh / "refined_3dgs" / "gaussians.ply"
    stamp = ply.stat().st_mtime_ns
    second = refine(fresh, "3dgs", 4, config=FAST, backend="numba", progress=False, evaluate=False)
    assert second.iterations == 4 and second.n_gaussians == first.n_gaussians
    assert ply.stat().st_mtime_ns == stamp


# ---------------------------------------------------------------------- bad input
def _cli(capsys, *argv):
    code = main(["refine", *map(str, argv), "--no-progress"])
    err = capsys.readouterr().err.strip()
    return code, err


def test_cli_bad_input_gives_one_line_errors(episode, tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    cases = [
        ((empty,), "keyframes.npz"),
        ((tmp_path / "missing",), "no such episode folder"),
        ((episode, "--method", "nerf"), "unknown method 'nerf'; choose one of: 3dgs, 2dgs"),
        # the storey is the episode's own (episode.json); --floor was accepted and did nothing
        ((episode, "--floor", "1"), "unknown option --floor"),
        ((episode, "--iters", "0"), "--iters"),
        ((episode, "--iters", "-5"), "--iters"),
    ]
    for argv, message in cases:
        code, err = _cli(capsys, *argv)
        assert code == 2, argv
        assert err.startswith("activesplat: error:") and message in err and "\n" not in err, err


def test_empty_keyframe_buffer_is_rejected(episode, tmp_path):
    ep = shutil.copytree(episode, tmp_path / "ep")
    np.savez_compressed(ep / "keyframes.npz", rgb=np.zeros((0, 32, 32, 3), np.uint8),
                        depth=np.zeros((0, 32, 32), np.float32), pose=np.zeros((0, 4, 4)),
                        step=np.zeros(0, np.int64))
    with pytest.raises(EpisodeError, match="empty"):
        refine(ep, "3dgs", 5, progress=False)
    (ep / "keyframes.npz").write_bytes(b"not a zip")
    with pytest.raises(EpisodeError, match="unreadable"):
        refine(ep, "3dgs", 5, progress=False)


def test_damaged_keyframe_arrays_are_episode_errors(episode, tmp_path):
    """check_arguments reads only the steps; an rgb array that is missing or fails its CRC is found when the
    buffer is loaded, and is an EpisodeError there too (it was a KeyError / BadZipFile traceback)."""
    ep = shutil.copytree(episode, tmp_path / "ep")
    with np.load(episode / "keyframes.npz") as data:
        arrays = {k: data[k] for k in data.files}
    np.savez(ep / "keyframes.npz", **{k: v for k, v in arrays.items() if k != "rgb"})
    with pytest.raises(EpisodeError, match="unreadable keyframe buffer .*rgb"):
        refine(ep, "3dgs", 2, progress=False, evaluate=False)
    np.savez(ep / "keyframes.npz", **arrays)  # stored (not deflated): the bytes of rgb.npy are in the file
    raw = bytearray((ep / "keyframes.npz").read_bytes())
    start = raw.index(b"rgb.npy") + 200  # inside rgb.npy's data, after its local header and .npy header
    raw[start:start + 64] = bytes(b ^ 0x5A for b in raw[start:start + 64])
    (ep / "keyframes.npz").write_bytes(bytes(raw))
    with pytest.raises(EpisodeError, match="unreadable keyframe buffer .*CRC"):
        refine(ep, "3dgs", 2, progress=False, evaluate=False)
    assert not (ep / "refined_3dgs").exists()


def test_ctrl_c_saves_the_iteration_and_says_how_to_resume(episode, tmp_path, monkeypatch, capsys):
    """The first Ctrl-C ends the iteration in progress, writes the checkpoint and says where it is and that
    the same command resumes (it said only "interrupted"); the resumed run is the uninterrupted one."""
    import signal

    whole = refine(shutil.copytree(episode, tmp_path / "a"), "3dgs", 8, config=FAST, backend="numba",
                   progress=False, evaluate=False)
    ep = shutil.copytree(episode, tmp_path / "b")
    step = Refiner.step

    def step_then_ctrl_c(self):
        out = step(self)
        if self.iteration == 3:
            signal.raise_signal(signal.SIGINT)
        return out

    monkeypatch.setattr(Refiner, "step", step_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        refine(ep, "3dgs", 8, config=FAST, backend="numba", progress=False, evaluate=False)
    err = capsys.readouterr().err
    assert "stopped at iteration 3 of 8" in err and str(ep / "refined_3dgs" / CHECKPOINT) in err
    assert "same command resumes" in err
    assert torch.load(ep / "refined_3dgs" / CHECKPOINT, weights_only=True)["iteration"] == 3
    monkeypatch.setattr(Refiner, "step", step)
    rest = refine(ep, "3dgs", 8, config=FAST, backend="numba", progress=False, evaluate=False)
    assert rest.iterations == 8 and rest.n_gaussians == whole.n_gaussians and rest.densify == whole.densify


def test_ctrl_c_is_one_line_and_exit_code_130(episode, tmp_path, monkeypatch, capsys):
    """The command line's Ctrl-C: one line saying what is kept and that the same command resumes, no generic
    "interrupted" after it: the first Ctrl-C (checkpoint of the iteration), a second one (at once: the last
    checkpoint is kept), one while loading, and one while evaluating the trained map (not trained again)."""
    import signal

    ep = shutil.copytree(episode, tmp_path / "ep")
    monkeypatch.setattr("activesplat.refine.trainer.evaluation_blocker", lambda folder: None)
    checkpoint = ep / "refined_3dgs" / CHECKPOINT
    step = Refiner.step

    def ctrl_c_at(n, at_once=False):
        def stepped(self):
            if at_once and self.iteration + 1 == n:
                raise KeyboardInterrupt  # as the second Ctrl-C's handler does, inside the iteration
            out = step(self)
            if self.iteration == n:
                signal.raise_signal(signal.SIGINT)
            return out
        return stepped

    argv = ["refine", str(ep), "--iters", "8", "--backend", "numba", "--no-progress", "--no-lpips"]
    monkeypatch.setattr(Refiner, "step", ctrl_c_at(3))
    assert main(argv) == 130
    assert capsys.readouterr().err.strip() == (f"refine: stopped at iteration 3 of 8, saved in {checkpoint}; "
                                               f"the same command resumes (--restart starts over)")
    monkeypatch.setattr(Refiner, "step", ctrl_c_at(5, at_once=True))
    assert main(argv) == 130
    assert capsys.readouterr().err.strip() == (f"refine: stopped at once in iteration 5 of 8: the checkpoint "
                                               f"of iteration 3 in {checkpoint} is kept; the same command "
                                               f"resumes from it")
    assert torch.load(checkpoint, weights_only=True)["iteration"] == 3
    monkeypatch.setattr("activesplat.refine.trainer.load_episode_map", _ctrl_c)
    assert main(argv) == 130
    assert capsys.readouterr().err.strip() == (f"refine: interrupted while loading the map and keyframes of "
                                               f"{ep}: nothing written; run the same command again")
    monkeypatch.undo()
    monkeypatch.setattr("activesplat.refine.trainer.evaluation_blocker", lambda folder: None)
    monkeypatch.setattr(Refiner, "evaluate", _ctrl_c)
    assert main(argv) == 130
    assert capsys.readouterr().err.strip() == (
        f"refine: interrupted while writing and evaluating the refined map; its 8 iterations are saved in "
        f"{checkpoint}: the same command writes and evaluates it without training again")
    monkeypatch.setattr(Refiner, "step", _ctrl_c)  # not trained again
    monkeypatch.setattr(Refiner, "evaluate", lambda self, ply, **kw: {"train": {}, "test": {}})
    assert main(argv) == 0


def _ctrl_c(*args, **kwargs):
    raise KeyboardInterrupt


def test_checkpoint_of_other_settings_names_them(fresh):
    refine(fresh, "3dgs", 10, config=FAST, backend="numba", progress=False, evaluate=False, stop_at=2)
    other = RefineConfig(**{**FAST.__dict__, "densify_interval": 5, "lambda_dssim": 0.3})
    with pytest.raises(InvalidInputError, match=r"\(refine\.lambda_dssim=0\.2, refine\.densify_interval=4\)"):
        Refiner(fresh, "3dgs", 10, config=other, backend="numba", progress=False)


def test_an_output_folder_that_cannot_be_written_is_refused_before_training(fresh, monkeypatch):
    """A file where DIR/refined_3dgs should be, or a read-only DIR, failed at the first checkpoint (or at the
    end of a short run), after the training it was meant to keep."""
    import tempfile

    (fresh / "refined_3dgs").write_text("in the way")
    trained = []
    monkeypatch.setattr(Refiner, "step", lambda self: trained.append(1))
    with pytest.raises(InvalidInputError, match="cannot write into .*refined_3dgs: it is a file"):
        refine(fresh, "3dgs", 4, backend="numba", progress=False, evaluate=False)
    (fresh / "refined_3dgs").unlink()

    def read_only(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "TemporaryFile", read_only)
    with pytest.raises(InvalidInputError,
                       match=r"cannot write into .*refined_3dgs: .*ep is not writable \(Permission denied\)"):
        refine(fresh, "3dgs", 4, backend="numba", progress=False, evaluate=False)
    assert trained == []


def test_a_resumed_run_shows_the_progress_bar_from_its_iteration(fresh, monkeypatch, capsys):
    """`timing.progress_bar` (stderr, two updates a second): "refine 3dgs", in iterations, from the
    checkpoint's iteration; none with progress=False."""
    from activesplat import timing
    from activesplat.refine import trainer

    bars = []

    def recorded(*args, **kwargs):
        bars.append((args, kwargs, timing.progress_bar(*args, **kwargs)))
        return bars[-1][2]

    monkeypatch.setattr(trainer, "progress_bar", recorded)
    refine(fresh, "3dgs", 6, config=FAST, backend="numba", progress=False, evaluate=False, stop_at=2)
    assert bars[-1][2] is None
    refine(fresh, "3dgs", 6, config=FAST, backend="numba", progress=True, evaluate=False)
    args, kwargs, bar = bars[-1]
    assert args == (6, "refine 3dgs", "it", True) and kwargs == {"initial": 2}
    assert bar.n == 6 and bar.disable  # closed
    err = capsys.readouterr().err
    assert "refine 3dgs:" in err and "2/6" in err and "6/6" in err and "psnr=" in err
