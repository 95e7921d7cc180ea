"""benchmarks/plan_snapshots.py: the options of `activesplat explore`, and the snapshots of a tiny real
exploration."""

import pytest
from _bench import load_benchmark


@pytest.fixture(scope="module")
def snapshots():
    return load_benchmark("plan_snapshots")


def test_options_are_those_of_activesplat_explore(snapshots, tmp_path):
    from activesplat.cli_options import CommandLineError

    args, run = snapshots.parse(["--at", "5", "9", "--out", str(tmp_path), "--explorer.neck-margin-m", "0.2",
                                 "--sim.width", "64", "--seed", "3", "--explorer.neck-margin-m", "None"])
    assert args.at == [5, 9] and args.out == str(tmp_path)
    assert run.explorer.neck_margin_m is None and run.sim.width == 64 and run.seed == 3
    with pytest.raises(CommandLineError, match="explorer.nope"):
        snapshots.parse(["--at", "5", "--out", str(tmp_path), "--explorer.nope", "1"])
    with pytest.raises(CommandLineError, match="seed"):
        snapshots.parse(["--at", "5", "--out", str(tmp_path), "--seed"])


def test_snapshots_of_a_tiny_exploration(snapshots, tmp_path):
    from activesplat.explore import explore_episode
    from activesplat.sim import load_scene

    _, run = snapshots.parse(["--at", "3", "50", "--out", str(tmp_path), "--scene", "small-0",
                              "--steps", "50", "--sim.width", "64", "--sim.height", "64",
                              "--coverage.n-gt-points", "4000", "--backend", "numba"])
    scene = load_scene("small-0")
    snaps = snapshots.Snapshots(scene.navmap_for(run.sim), {3, 50}, tmp_path, (1.0, 6.0, 0.5, 5.0), "t")
    explore_episode(run, out=tmp_path / "episode", progress=False, viewer=snaps, scene=scene)
    assert [p.name for p in snaps.written] == ["step3.png", "step50.png"]
    assert all(p.stat().st_size > 10_000 for p in snaps.written)


def test_an_output_folder_that_cannot_be_written_is_refused_before_the_scene_is_built(snapshots, tmp_path,
                                                                                      monkeypatch):
    import re
    import sys

    def slow(*args, **kwargs):
        raise AssertionError("the scene was built before the output was checked")

    monkeypatch.setattr(snapshots, "load_scene", slow)
    (tmp_path / "file").write_text("")
    monkeypatch.setattr(sys, "argv", ["plan_snapshots.py", "--at", "3", "--out", str(tmp_path / "file")])
    message = f"plan_snapshots.py: error: cannot write into --out {tmp_path}/file: it is a file, not a folder"
    with pytest.raises(SystemExit, match=re.escape(message)):
        snapshots.main()
