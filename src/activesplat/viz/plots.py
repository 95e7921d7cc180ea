"""Matplotlib figures of an episode and of a benchmark (Agg only; no display needed)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

Curve = list[dict]
"""Points {"step", "completion_ratio_pct", "path_length_m", ...} of one run, in step order."""


def mean_curve(runs: Sequence[Curve], key: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean and standard deviation over runs of `key` against steps.

    The runs are interpolated onto the union of their steps, cut at the shortest run's last step so that
    every point averages all runs. Returns (steps, mean, std); empty arrays when no run has points."""
    runs = [r for r in runs if r]
    if not runs:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    last = min(r[-1]["step"] for r in runs)
    steps = np.unique(np.concatenate([[p["step"] for p in r] for r in runs]))
    steps = steps[steps <= last]
    values = np.stack([np.interp(steps, [p["step"] for p in r], [p[key] for p in r]) for r in runs])
    return steps, values.mean(axis=0), values.std(axis=0)


def _as_runs(curves: Curve | Sequence[Curve]) -> list[Curve]:
    """One run (a list of points) or several (a list of such lists)."""
    if not curves:
        return []
    return [list(curves)] if isinstance(curves[0], dict) else [list(c) for c in curves]


def curve_markers(n_points: int) -> dict:
    """Marker keywords of a curve of `n_points` points: a line alone would draw nothing for one point and
    hide how few points a short run has, so points are always marked (larger when there are few, and
    about 25 of them at most on a long curve)."""
    return {"marker": "o", "ms": 5.0 if n_points <= 3 else 3.0, "markevery": max(1, n_points // 25)}


def draw_completion(out_png: str | Path, curves: dict[str, Curve | Sequence[Curve]], title: str = "") -> Path:
    """Completion ratio and path length against steps (like the paper's Fig. 6), one line per label.

    `curves` maps a label to one run's points {"step", "completion_ratio_pct", "path_length_m"}, or to a
    list of runs (trials): then the line is their mean and a band shows ± one standard deviation."""
    fig = Figure(figsize=(9, 3.6), dpi=110)
    ax_c, ax_p = fig.subplots(1, 2)
    for label, value in curves.items():
        runs = [r for r in _as_runs(value) if r]
        if not runs:
            continue
        name = label if len(runs) == 1 else f"{label} (n={len(runs)})"
        for ax, key in ((ax_c, "completion_ratio_pct"), (ax_p, "path_length_m")):
            steps, mean, std = mean_curve(runs, key)
            (line,) = ax.plot(steps, mean, label=name, lw=1.6, **curve_markers(len(steps)))
            if len(runs) > 1 and len(steps) > 1:
                ax.fill_between(steps, mean - std, mean + std, color=line.get_color(), alpha=0.2, lw=0)
            elif len(runs) > 1:  # one point: a band has no width, an error bar shows the spread
                ax.errorbar(steps, mean, yerr=std, color=line.get_color(), capsize=3, lw=1.0, ls="")
    ax_c.set(xlabel="step", ylabel="completion ratio (%)", ylim=(0, 100), title="completion ratio")
    ax_p.set(xlabel="step", ylabel="path length (m)", title="path length")
    for ax in (ax_c, ax_p):
        ax.grid(alpha=0.3)
    if len(curves) > 1 or title:
        ax_c.legend(loc="lower right", fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out_png = Path(out_png)
    fig.savefig(out_png)
    return out_png
