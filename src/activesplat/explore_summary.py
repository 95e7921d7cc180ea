"""The lines `activesplat explore` prints after the loop (README "What happens in an exploration": once the
step budget is spent and metrics.json is written): `format_summary` of the episode's metrics (completion,
path length, map size, time per step by module and where the wall time went). `TIMING_KEYS` names the
modules of the per-step timings (metrics.json's ``timing_ms``) and `JIT_NOTE_S` the numba compiling from
which the summary and the benchmark's tables mention it.
"""

from __future__ import annotations

import math
from pathlib import Path

TIMING_KEYS = ("mapper", "workspace", "voronoi", "subregions", "rotation_selection", "position_selection",
               "planner")
"""Per-module mean ms per step, as the paper's Tab. VI."""


def format_summary(metrics: dict, out_dir: Path) -> str:
    """The summary `activesplat explore` prints of an episode's `metrics` (metrics.json) written to `out_dir`:
    one line each for the folder, the run, the steps and where their time went, completion, path length,
    the map's size and the time per step of each module."""
    t = metrics["timing_ms"]
    lines = [
        f"episode      {out_dir}",
        f"scene        {metrics['scene']}  policy {metrics['policy']}  seed {metrics['seed']}",
        f"steps        {metrics['steps']}  ({metrics['ms_per_step']:.0f} ms/step of which "
        f"{metrics['evaluation_ms_per_step']:.0f} live evaluation{_worker_note(metrics)}; "
        f"{metrics['wall_time_s']:.0f} s wall{_setup(metrics)}{_jit(metrics)})",
        f"completion   {metrics['completion_ratio_pct']:.2f} %  |  {metrics['completion_cm']:.2f} cm "
        f"(uncapped {_fmt(metrics['completion_cm_uncapped'])} cm)",
        f"path length  {metrics['path_length_m']:.2f} m",
        f"gaussians    {metrics['n_gaussians']}",
        "time/step    " + "  ".join(f"{k} {t[k]:.1f}" for k in TIMING_KEYS)
        + f"  simulator {metrics.get('simulator_ms_per_step', 0.0):.1f} (ms)",
    ]
    return "\n".join(lines)


def _worker_note(metrics: dict) -> str:
    """The live evaluation's own time, where it ran on a worker thread (the loop waited only for part)."""
    if not metrics.get("evaluation_background"):
        return ""
    return f" (waiting; {metrics['evaluation_worker_ms_per_step']:.0f} on its worker thread)"


JIT_NOTE_S = 1.0
"""Seconds of numba compiling inside the timed loop from which the summary and the benchmark's tables say
that the timings include it."""


def _jit(metrics: dict) -> str:
    """The numba compiling inside the timed loop (the first run after an install or a code change)."""
    jit = metrics.get("jit_compile_s") or 0.0
    if jit < JIT_NOTE_S:
        return ""
    return (f"; {jit:.0f} s of the wall time compiling numba kernels: the first run after an install or a "
            "code change, later runs are faster")


def _setup(metrics: dict) -> str:
    """The kernels' one-time setup before the clock, where it was long enough to matter (a gsplat build,
    numba compiling in the first run after an install or a code change)."""
    setup = metrics.get("backend_setup_s", 0.0)
    return f", after {setup:.0f} s loading the kernels" if setup >= 1.0 else ""


def _fmt(v) -> str:
    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.2f}"
