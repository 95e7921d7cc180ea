import subprocess
import sys

from activesplat.cli import main


def test_help_lists_commands(capsys):
    try:
        main(["--help"])
    except SystemExit as exc:
        assert exc.code == 0
    out = capsys.readouterr().out
    assert "explore" in out and "scenes" in out


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
