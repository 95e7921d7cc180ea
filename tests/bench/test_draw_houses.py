"""benchmarks/draw_houses.py: the plan of a built-in house drawn from above, walls cut at doors."""

import pytest
from _bench import load_benchmark


@pytest.fixture(scope="module")
def draw_houses():
    return load_benchmark("draw_houses")


def test_wall_pieces_leave_out_doors_and_open_sides(draw_houses):
    assert draw_houses.wall_pieces(0.0, 4.0, []) == [(0.0, 4.0)]
    assert draw_houses.wall_pieces(0.0, 4.0, [(1.0, 2.0)]) == [(0.0, 1.0), (2.0, 4.0)]
    assert draw_houses.wall_pieces(0.0, 4.0, [(-1.0, 1.0), (3.5, 9.0)]) == [(1.0, 3.5)]
    assert draw_houses.wall_pieces(0.0, 4.0, [(0.0, 4.0)]) == []


def test_a_house_is_drawn_from_above_with_every_door(draw_houses, tmp_path):
    from activesplat.sim import load_scene

    house = load_scene("small-0").house
    fig = draw_houses.houses_figure(["small-0"], columns=1)
    ax = fig.axes[0]
    z_top, z_bottom = ax.get_ylim()
    assert z_top > z_bottom  # z grows downwards, as in topdown.png and trajectory.png
    thick = [line for line in ax.lines if line.get_linewidth() > 2]
    assert len(thick) == len(house.doors) > 0
    assert "small-0" in ax.get_title()
    out = tmp_path / "houses.png"
    assert draw_houses.main(["--out", str(out), "--houses", "small-0", "--columns", "1"]) == 0
    assert out.stat().st_size > 10_000


def test_an_unknown_house_is_a_clear_error(draw_houses, tmp_path, capsys):
    with pytest.raises(SystemExit):
        draw_houses.main(["--out", str(tmp_path / "x.png"), "--houses", "medium-x"])
    assert "unknown scene 'medium-x'" in capsys.readouterr().err


def test_an_output_that_cannot_be_written_is_refused_before_the_houses_are_built(draw_houses, tmp_path,
                                                                                 capsys, monkeypatch):
    def slow(*args, **kwargs):
        raise AssertionError("the houses were built before the output was checked")

    monkeypatch.setattr(draw_houses, "houses_figure", slow)
    (tmp_path / "x.png").mkdir()
    with pytest.raises(SystemExit):
        draw_houses.main(["--out", str(tmp_path / "x.png"), "--houses", "small-0"])
    assert f"cannot write --out {tmp_path / 'x.png'}: it is a folder" in capsys.readouterr().err
