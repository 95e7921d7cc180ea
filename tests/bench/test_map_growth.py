"""benchmarks/map_growth.py: the map's size against the surface observed, on a tiny real exploration."""

import pytest
from _bench import load_benchmark


def _explore(out, steps: int) -> None:
    from activesplat.cli_options import parse_command
    from activesplat.config import ExploreCommand
    from activesplat.explore import explore_episode

    cmd = parse_command(ExploreCommand, ["--scene", "small-0", "--steps", str(steps), "--sim.width", "64",
                                         "--sim.height", "64", "--coverage.n-gt-points", "4000",
                                         "--coverage.batch-frames", "10", "--backend", "numba"], "explore")
    explore_episode(cmd.run, out=out, progress=False)


@pytest.fixture(scope="module")
def run_40(tmp_path_factory):
    """A 40-step exploration, shared by the tests that read one (explored once per module)."""
    out = tmp_path_factory.mktemp("long")
    _explore(out, 40)
    return out


def test_rows_count_the_observed_surface_of_a_tiny_exploration(run_40):
    growth = load_benchmark("map_growth")
    rows = growth.growth_rows(run_40, every=20)
    assert [r["step"] for r in rows] == [20, 40]
    assert 0 < rows[0]["observed_m2"] <= rows[1]["observed_m2"]  # the area only grows
    for r in rows:
        assert r["gaussians"] > 0 and abs(r["per_m2"] * r["observed_m2"] / r["gaussians"] - 1) < 1e-9


def test_the_growth_after_a_shorter_run_is_split_by_cells_whose_surface_grew(tmp_path, run_40):
    from activesplat.splat.ply import load_ply

    growth = load_benchmark("map_growth")
    _explore(tmp_path, 20)
    g = growth.cell_growth(tmp_path, run_40, cell_m=0.2, caps=(1e3, 1e9))
    sizes = [len(load_ply(run / "gaussians.ply")) for run in (tmp_path, run_40)]
    assert g["step"] == 20 and [g["gaussians_then"], g["gaussians_now"]] == sizes
    split = g["added_where_surface_grew"] + g["added_elsewhere"] + g["added_outside_observed"]
    assert split == sizes[1] - sizes[0] and g["area_growth"] >= 0.0
    # with no cap that binds, the excess is the map's growth against the surface's
    assert abs(g["excess_with_cap"][1e9] - (sizes[1] / sizes[0]) / (1 + g["area_growth"]) + 1) < 1e-9


def test_an_earlier_run_that_does_not_begin_the_later_one_is_refused(tmp_path):
    growth = load_benchmark("map_growth")
    runs = {"short": "turn_left\nmove_forward\n", "long": "turn_left\nmove_forward\nturn_left\n",
            "other": "turn_right\n"}
    for run, actions in runs.items():
        (tmp_path / run).mkdir()
        (tmp_path / run / "actions.txt").write_text(actions)
    growth.check_earlier(tmp_path / "short", tmp_path / "long", 0.2)  # a prefix: accepted
    with pytest.raises(SystemExit, match="shorter run whose actions begin"):
        growth.check_earlier(tmp_path / "other", tmp_path / "long", 0.2)
    with pytest.raises(SystemExit, match="shorter run whose actions begin"):
        growth.check_earlier(tmp_path / "long", tmp_path / "short", 0.2)
    with pytest.raises(SystemExit, match="multiple of 0.05"):
        growth.check_earlier(tmp_path / "short", tmp_path / "long", 0.07)
