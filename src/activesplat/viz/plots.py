"""Matplotlib figures of an episode (Agg only; no display needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure


def draw_completion(out_png: str | Path, curves: dict[str, list[dict]], title: str = "") -> Path:
    """Completion ratio and path length against steps (like the paper's Fig. 6), one line per curve.

    `curves` maps a label to points {"step", "completion_ratio_pct", "path_length_m"}."""
    fig = Figure(figsize=(9, 3.6), dpi=110)
    ax_c, ax_p = fig.subplots(1, 2)
    for label, pts in curves.items():
        if not pts:
            continue
        steps = np.array([p["step"] for p in pts])
        ax_c.plot(steps, [p["completion_ratio_pct"] for p in pts], label=label, lw=1.6)
        ax_p.plot(steps, [p["path_length_m"] for p in pts], label=label, lw=1.6)
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
