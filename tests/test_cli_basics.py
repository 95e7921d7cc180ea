import subprocess
import sys

import pytest

from activesplat.cli import main


def test_help_lists_commands(capsys):
    try:
        main(["--help"])
    except SystemExit as exc:
        assert exc.code == 0
    out = capsys.readouterr().out
    assert "explore" in out and "scenes" in out


def test_version_is_the_package_version(capsys):
    from activesplat import __version__

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"activesplat {__version__}"


def test_module_entry_point_runs():
    res = subprocess.run([sys.executable, "-m", "activesplat", "--help"], capture_output=True, text=True)
    assert res.returncode == 0
    assert "usage: activesplat" in res.stdout


def test_a_full_disk_gets_a_message_not_a_traceback(monkeypatch, capsys):
    import errno

    import activesplat.cli as cli

    def full(args):
        raise OSError(errno.ENOSPC, "No space left on device", "runs/b/curves_average.png")

    monkeypatch.setattr(cli, "_cmd_view", full)  # any command that writes; view is the simplest to reach
    assert main(["view", "runs/b"]) == 1
    err = capsys.readouterr().err
    assert "cannot write: runs/b/curves_average.png (No space left on device)" in err
    assert "run the same command again" in err


def _closed_pipe_run(*argv):
    """`activesplat ARGV` with its stdout a pipe whose reader has already gone (`... | head -1`)."""
    import os

    read, write = os.pipe()
    os.close(read)
    try:
        return subprocess.run([sys.executable, "-m", "activesplat", *argv], stdout=write,
                              stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write)


def test_a_closed_pipe_ends_quietly():
    from activesplat.cli import EXIT_BROKEN_PIPE

    res = _closed_pipe_run("refine", "--help")  # tyro's help: more than a pipe's buffer
    assert res.returncode == EXIT_BROKEN_PIPE and res.stderr == "", res.stderr
    res = _closed_pipe_run("scenes", "list")
    assert res.returncode == EXIT_BROKEN_PIPE and res.stderr == "", res.stderr


def test_a_broken_pipe_that_is_not_stdout_still_raises():
    code = ("import sys\nfrom activesplat import cli\n"
            "def boom(args):\n    raise BrokenPipeError(32, 'Broken pipe')\n"
            "cli._cmd_view = boom\nsys.exit(cli.main(['view', 'x']))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 1 and "BrokenPipeError" in res.stderr


def test_map_backend_defaults_to_one_the_mapper_takes():
    import numpy as np

    from activesplat.cli import build_parser
    from activesplat.splat import Mapper

    args = build_parser().parse_args(["map", "recording"])
    assert args.backend == "auto"
    Mapper(np.array([[8.0, 0, 4], [0, 8, 4], [0, 0, 1]]), 8, 8, backend=args.backend)


def test_scene_export_to_an_impossible_path_is_one_line(capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["scenes", "export", "small-0", str(blocker / "x.glb")]) == 2  # before the scene is built
    err = capsys.readouterr().err
    assert err == f"activesplat: error: cannot write {blocker / 'x.glb'}: {blocker} is a file, not a folder\n"


def test_explore_help_gives_the_step_budget_of_a_mesh_file(capsys, monkeypatch):
    """--steps' help named the budgets of small and medium houses only; a mesh file gets 1000."""
    from activesplat.sim.scene import DEFAULT_STEPS

    monkeypatch.setenv("COLUMNS", "80")  # one column of options: a help text reads on across its lines
    with pytest.raises(SystemExit):
        main(["explore", "--help"])
    text = " ".join(capsys.readouterr().out.replace("│", " ").split())
    assert f"{DEFAULT_STEPS['file']} for small scenes and mesh files" in text
