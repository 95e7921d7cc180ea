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
