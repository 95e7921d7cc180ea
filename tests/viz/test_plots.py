"""Completion curves: every curve is visible even with a single point (markers, an error bar for a
one-point mean of several trials)."""

from __future__ import annotations

from activesplat.viz import plots
from activesplat.viz.plots import curve_markers, draw_completion


def _point(step: int, pct: float) -> dict:
    return {"step": step, "completion_ratio_pct": pct, "path_length_m": 0.0}


def _figures(monkeypatch) -> list:
    """Capture the Figures draw_completion makes."""
    made = []
    real = plots.Figure

    def spy(*args, **kwargs):
        made.append(real(*args, **kwargs))
        return made[-1]

    monkeypatch.setattr(plots, "Figure", spy)
    return made


def test_a_one_point_curve_draws_a_visible_marker(tmp_path, monkeypatch):
    made = _figures(monkeypatch)
    out = draw_completion(tmp_path / "c.png", {"activesplat": [_point(60, 41.0)]}, title="one point")
    assert out.stat().st_size > 0
    for ax in made[0].axes:
        (line,) = ax.get_lines()
        assert len(line.get_xdata()) == 1
        assert line.get_marker() not in (None, "", "None", " ") and line.get_markersize() >= 4


def test_markers_stay_small_and_sparse_on_long_curves():
    assert curve_markers(1)["ms"] > curve_markers(100)["ms"]
    assert curve_markers(10)["markevery"] == 1
    assert 100 // curve_markers(100)["markevery"] <= 25


def test_a_one_point_mean_of_trials_shows_its_spread(tmp_path, monkeypatch):
    made = _figures(monkeypatch)
    draw_completion(tmp_path / "t.png", {"fbe": [[_point(60, 40.0)], [_point(60, 30.0)]]})
    ax_c = made[0].axes[0]
    assert ax_c.get_lines()[0].get_marker() == "o"
    assert ax_c.containers  # the error bar of the ± one standard deviation
