"""Every command that writes a file or folder the user names refuses one it cannot write (a file where a
folder should be, a folder where the file should be, a read-only folder) in one line, before its slow work
(scene build, recording scan, connection, training, renders): `activesplat.errors.check_output_file` and
`check_output_folder`."""

import errno
import os
import shutil
import tempfile
from pathlib import Path

import pytest

from activesplat.cli import main
from activesplat.errors import InvalidInputError, check_output_file, check_output_folder
from activesplat.eval.coverage import CoverageConfig
from activesplat.explore import run_exploration
from activesplat.sim import SimConfig

pytestmark = pytest.mark.filterwarnings("ignore:a budget of 3 actions")  # the tiny episode


@pytest.fixture(scope="module")
def episode(tmp_path_factory):
    out = tmp_path_factory.mktemp("outputs") / "ep"
    run_exploration("small-0", steps=3, seed=0, out=out, sim_config=SimConfig(width=32, height=32),
                    coverage_config=CoverageConfig(n_gt_points=500, batch_frames=4), progress=False,
                    backend="numba")
    return out


def _slow(*args, **kwargs):
    raise AssertionError("the slow work started before the output was checked")


# command: (kind of output, argv with {out} / {ep}, the slow work that must not start)
COMMANDS = {
    "explore": ("folder", ["explore", "--steps", "5", "--out", "{out}"], "activesplat.sim.load_scene"),
    "map": ("folder", ["map", "rec.bag", "--out", "{out}"], "activesplat.robot.recording.open_recording"),
    "robot": ("folder", ["robot", "ws://127.0.0.1:9", "--steps", "3", "--out", "{out}"],
              "activesplat.robot.bridge.RosbridgeEnvironment"),
    "benchmark": ("folder", ["benchmark", "--scenes", "small-0", "--policies", "random", "--steps", "5",
                             "--root", "{out}"], "activesplat.bench.run_serial"),
    "scenes export": ("file", ["scenes", "export", "small-0", "{out}.glb"], "activesplat.sim.load_scene"),
    "export --mcap": ("file", ["export", "{ep}", "--mcap", "{out}.mcap"], "activesplat.splat.ply.load_ply"),
    "export --ply": ("file", ["export", "{ep}", "--ply", "{out}.ply"], "activesplat.splat.ply.load_ply"),
    "compare --out": ("file", ["compare", "a", "b", "--out", "{out}.md"],
                      "activesplat.bench.compare.pair_runs"),
}


def _run(capsys, monkeypatch, command, out, ep=Path("ep")):
    _, argv, slow = COMMANDS[command]
    monkeypatch.setattr(slow, _slow)
    code = main([a.format(out=out, ep=ep) for a in argv])
    captured = capsys.readouterr()
    assert code == 2 and captured.err.count("\n") == 1, captured.err
    assert captured.out == ""  # compare: the report is not printed before the refusal
    return captured.err


def _read_only(monkeypatch, folder: Path) -> None:
    """`folder` refuses new files, as a read-only folder does for a user other than root."""
    real = tempfile.TemporaryFile

    def temporary_file(*args, dir=None, **kwargs):
        if dir is not None and Path(dir).resolve() == folder.resolve():
            raise PermissionError(errno.EACCES, "Permission denied", str(dir))
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "TemporaryFile", temporary_file)


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_file_where_a_folder_should_be(command, tmp_path, capsys, monkeypatch, episode):
    blocker = tmp_path / "file"
    blocker.write_text("in the way")
    kind = COMMANDS[command][0]
    outs = [blocker / "sub"] + ([blocker] if kind == "folder" else [])
    for out in outs:
        err = _run(capsys, monkeypatch, command, out, episode)
        assert err.startswith("activesplat: error: cannot write")
        reason = "it is a file, not a folder" if out == blocker else f"{blocker} is a file, not a folder"
        assert err.endswith(f": {reason}\n"), err
    assert blocker.read_text() == "in the way"


@pytest.mark.parametrize("command", [c for c, (kind, _, _) in COMMANDS.items() if kind == "file"])
def test_a_folder_where_the_file_should_be(command, tmp_path, capsys, monkeypatch, episode):
    suffix = COMMANDS[command][1][-1].removeprefix("{out}")
    (tmp_path / f"x{suffix}").mkdir()
    err = _run(capsys, monkeypatch, command, tmp_path / "x", episode)
    assert err.startswith("activesplat: error: cannot write ")
    assert err.endswith(f" {tmp_path / f'x{suffix}'}: it is a folder\n"), err


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_read_only_folder(command, tmp_path, capsys, monkeypatch, episode):
    read_only = tmp_path / "ro"
    read_only.mkdir()
    _read_only(monkeypatch, read_only)
    err = _run(capsys, monkeypatch, command, read_only / "out", episode)
    assert err.endswith(f": {read_only} is not writable (Permission denied)\n"), err
    assert list(read_only.iterdir()) == []


# --------------------------------------------------------------------------- outputs inside an episode
@pytest.fixture
def fresh(episode, tmp_path):
    return shutil.copytree(episode, tmp_path / "ep")


def test_refine_refuses_before_loading_the_map(fresh, capsys, monkeypatch):
    monkeypatch.setattr("activesplat.refine.trainer.evaluation_blocker", _slow)  # loads the scene
    monkeypatch.setattr("activesplat.refine.trainer.load_episode_map", _slow)
    (fresh / "refined_3dgs").write_text("in the way")
    assert main(["refine", str(fresh), "--iters", "3", "--no-lpips"]) == 2
    assert capsys.readouterr().err == (f"activesplat: error: cannot write into {fresh / 'refined_3dgs'}: it "
                                       f"is a file, not a folder\n")
    (fresh / "refined_3dgs").unlink()
    _read_only(monkeypatch, fresh)
    assert main(["refine", str(fresh), "--iters", "3", "--no-lpips"]) == 2
    assert capsys.readouterr().err == (f"activesplat: error: cannot write into {fresh / 'refined_3dgs'}: "
                                       f"{fresh} is not writable (Permission denied)\n")


@pytest.mark.parametrize("budget", [[], ["--budget"]])
def test_render_eval_refuses_before_rendering(fresh, capsys, monkeypatch, budget):
    monkeypatch.setattr("activesplat.splat.ply.load_ply", _slow)
    name = "render_budget.json" if budget else "render_metrics.json"
    (fresh / name).mkdir()
    assert main(["render-eval", str(fresh), "--no-lpips", *budget]) == 2
    assert capsys.readouterr().err == f"activesplat: error: cannot write {fresh / name}: it is a folder\n"
    (fresh / name).rmdir()
    _read_only(monkeypatch, fresh)
    assert main(["render-eval", str(fresh), "--no-lpips", *budget]) == 2
    assert capsys.readouterr().err.endswith(f": {fresh} is not writable (Permission denied)\n")


def test_evaluate_refuses_before_the_replay(fresh, capsys, monkeypatch):
    monkeypatch.setattr("activesplat.eval.evaluate.replay_episode", _slow)
    _read_only(monkeypatch, fresh)
    assert main(["evaluate", str(fresh)]) == 2
    assert capsys.readouterr().err == (f"activesplat: error: cannot write {fresh / 'metrics.json'}: {fresh} "
                                       f"is not writable (Permission denied)\n")


def test_explore_refuses_an_episode_to_keep_before_the_scene_is_built(episode, capsys, monkeypatch):
    monkeypatch.setattr("activesplat.sim.load_scene", _slow)
    assert main(["explore", "--steps", "5", "--out", str(episode)]) == 2
    assert "already holds a complete episode; pass --overwrite" in capsys.readouterr().err


# --------------------------------------------------------------------------- the checks themselves
@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only folder")
def test_a_folder_without_write_permission(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        with pytest.raises(InvalidInputError, match=r"ro is not writable \(Permission denied\)"):
            check_output_file(folder / "x.png")
        with pytest.raises(InvalidInputError, match=r"cannot write into .*ro: it is not writable"):
            check_output_folder(folder)
        with pytest.raises(InvalidInputError, match=r"cannot write into .*new: .*ro is not writable"):
            check_output_folder(folder / "new" / "deeper")
    finally:
        folder.chmod(0o755)


def test_a_writable_path_passes_and_nothing_is_created(tmp_path):
    check_output_file(tmp_path / "new" / "deeper" / "x.png")  # missing folders are made by the command
    check_output_folder(tmp_path / "new" / "deeper")
    check_output_folder(tmp_path)
    (tmp_path / "x.png").write_text("")
    check_output_file(tmp_path / "x.png")  # a file to replace
    assert [p.name for p in tmp_path.iterdir()] == ["x.png"]


def test_a_full_disk_is_left_to_the_command_line(tmp_path, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(tempfile, "TemporaryFile", full)
    with pytest.raises(OSError, match="No space left") as caught:
        check_output_folder(tmp_path)
    assert not isinstance(caught.value, InvalidInputError)


def test_labels_name_the_option(tmp_path):
    (tmp_path / "x.md").mkdir()
    with pytest.raises(InvalidInputError, match=r"^cannot write --out .*x\.md: it is a folder$"):
        check_output_file(tmp_path / "x.md", "--out")
    (tmp_path / "x.md" / "y").write_text("")
    with pytest.raises(InvalidInputError, match=r"^cannot write into --root .*x\.md/y: it is a file"):
        check_output_folder(tmp_path / "x.md" / "y", "--root")


def test_a_folder_that_takes_no_files_is_one_line(tmp_path, monkeypatch):
    """/proc refuses new files with "No such file or directory": a one-line error too, not a traceback."""
    def refuse(*args, **kwargs):
        raise FileNotFoundError(errno.ENOENT, "No such file or directory")

    monkeypatch.setattr(tempfile, "TemporaryFile", refuse)
    with pytest.raises(InvalidInputError, match=r"x\.glb: .* is not writable \(No such file or directory\)"):
        check_output_file(tmp_path / "x.glb")


def test_benchmark_refuses_a_file_where_a_run_folder_goes(tmp_path, capsys, monkeypatch):
    """A file standing where one run's folder (ROOT/<scene>/...) goes is refused before any run, not found
    run by run after the others have explored."""
    (tmp_path / "small-0").write_text("in the way")
    err = _run(capsys, monkeypatch, "benchmark", tmp_path)
    assert err == (f"activesplat: error: cannot write into {tmp_path / 'small-0' / 'random' / 's0'}: "
                   f"{tmp_path / 'small-0'} is a file, not a folder\n")
