"""benchmarks/map_growth.py: the map's size against the surface observed, on a tiny real exploration."""

from _bench import load_benchmark


def test_rows_count_the_observed_surface_of_a_tiny_exploration(tmp_path):
    from activesplat.cli import parse_command
    from activesplat.config import ExploreCommand
    from activesplat.explore import explore_episode

    growth = load_benchmark("map_growth")
    cmd = parse_command(ExploreCommand, ["--scene", "small-0", "--steps", "40", "--sim.width", "64",
                                         "--sim.height", "64", "--coverage.n-gt-points", "4000",
                                         "--coverage.batch-frames", "10", "--backend", "numba"], "explore")
    explore_episode(cmd.run, out=tmp_path, progress=False)
    rows = growth.growth_rows(tmp_path, every=20)
    assert [r["step"] for r in rows] == [20, 40]
    assert 0 < rows[0]["observed_m2"] <= rows[1]["observed_m2"]  # the area only grows
    for r in rows:
        assert r["gaussians"] > 0 and abs(r["per_m2"] * r["observed_m2"] / r["gaussians"] - 1) < 1e-9
