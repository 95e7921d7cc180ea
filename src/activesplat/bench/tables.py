"""Benchmark tables from the episode folders on disk: a CSV with one row per run, and markdown in the
style of the paper's tables (docs/protocol.md §6):

- Tab. I   exploration: rows = policies, completion ratio % / completion cm / path length m / ms per step,
           mean ± std over trials per scene, then the average over scenes;
- Tab. II  the same for the ablation variants (Random / Position / Viewpoint / w/o HP / visibility-only /
           hull-only) next to the full method;
- per-scene table as in the supplementary Tab. S1 / S2: policy x metric rows, one column per scene, Avg.;
- Tab. VI  mean processing time per step of each module.

Everything is read back from ROOT (metrics.json of complete runs, error.txt of failed ones), so the tables
of a resumed or partly failed benchmark are the same as those of an uninterrupted one.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from activesplat.bench.runner import ERROR_FILE, RunSpec, read_metrics
from activesplat.explore_summary import JIT_NOTE_S, TIMING_KEYS

PAPER_TAB6_MS = {"mapper": 45.14, "workspace": 43.87, "voronoi": 0.69, "subregions": 1.56,
                 "rotation_selection": 2.76, "position_selection": 6.46, "planner": 0.20}
"""Paper Tab. VI: average processing time per step (ms) on an RTX 3090 (visualizer, 67.43 ms, left out)."""

ABLATION_POLICIES = ("random", "position", "viewpoint", "no-hp", "visibility-only", "hull-only")
"""Variants of the paper's ablations (Tab. II exploration strategy, Tab. III hierarchical planning,
Tab. IV coverage evaluation): listed in Tab. II next to the full method; every other policy is in Tab. I."""

FULL_METHOD = "activesplat"

LEAD_COLUMNS = ("scene", "policy", "seed", "status", "dir", "error")
FIRST_METRICS = ("completion_ratio_pct", "completion_cm", "completion_cm_uncapped", "path_length_m", "steps",
                 "wall_time_s", "ms_per_step", "evaluation_ms_per_step", "n_gaussians")
"""CSV metric columns that come first; any other scalar of metrics.json follows in alphabetical order."""


@dataclass(frozen=True)
class TableConfig:
    """How the markdown tables print numbers."""

    ratio_decimals: int = 2
    """Completion ratio (%), as the paper."""
    cm_decimals: int = 2
    """Completion (cm), as the paper."""
    path_decimals: int = 1
    """Path length (m)."""
    ms_decimals: int = 0
    """Total ms per step in Tab. I."""
    timing_decimals: int = 2
    """Per-module ms per step in Tab. VI, as the paper."""
    std_ddof: int = 0
    """Delta degrees of freedom of the ± standard deviation over trials (0: population std, numpy's
    default; 1: sample std)."""


@dataclass
class RunRecord:
    """One planned run as found on disk."""

    spec: RunSpec
    status: str
    """"complete" (metrics.json), "failed" (error.txt) or "missing" (never run, interrupted, partial)."""
    metrics: dict | None = None
    error: str = ""
    """The exception line of a failed run."""


def collect(specs: Sequence[RunSpec]) -> list[RunRecord]:
    """Read back the outcome of every planned run."""
    records = []
    for spec in specs:
        metrics = read_metrics(spec.out)
        if metrics is not None:
            records.append(RunRecord(spec, "complete", metrics))
        elif (spec.out / ERROR_FILE).is_file():
            line = (spec.out / ERROR_FILE).read_text().strip().splitlines()
            records.append(RunRecord(spec, "failed", error=line[0] if line else "failed"))
        else:
            records.append(RunRecord(spec, "missing"))
    return records


# --------------------------------------------------------------------------- CSV
def _scalars(metrics: dict) -> dict:
    """metrics.json scalars (numbers, strings, booleans, None) plus timing_ms as timing_ms.<module>."""
    row = {k: v for k, v in metrics.items()
           if k not in LEAD_COLUMNS and (v is None or isinstance(v, (int, float, str, bool)))}
    for k, v in (metrics.get("timing_ms") or {}).items():
        row[f"timing_ms.{k}"] = v
    return row


def write_csv(path: str | Path, records: Sequence[RunRecord]) -> Path:
    """One row per planned run: scene, policy, seed, status, folder, error, then every metric."""
    rows = [_scalars(r.metrics) if r.metrics else {} for r in records]
    keys = set().union(*rows) if rows else set()
    timing = [f"timing_ms.{k}" for k in TIMING_KEYS if f"timing_ms.{k}" in keys]
    first = [k for k in FIRST_METRICS if k in keys]
    rest = sorted(keys - set(first) - set(timing))
    columns = [*LEAD_COLUMNS, *first, *rest, *timing]
    path = Path(path)
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        for record, row in zip(records, rows, strict=True):
            s = record.spec
            writer.writerow({"scene": s.label, "policy": s.policy, "seed": s.seed, "status": record.status,
                             "dir": str(s.out), "error": record.error, **row})
    return path


# --------------------------------------------------------------------------- statistics
class Results:
    """The records of a benchmark grouped by scene and policy."""

    def __init__(self, records: Sequence[RunRecord], cfg: TableConfig | None = None):
        self.records = list(records)
        self.cfg = cfg or TableConfig()
        self.scenes = list(dict.fromkeys(r.spec.label for r in self.records))
        self.policies = list(dict.fromkeys(r.spec.policy for r in self.records))

    def complete(self, scene: str | None, policy: str) -> list[dict]:
        """Metrics of the complete runs of a policy on a scene (all scenes: None)."""
        return [r.metrics for r in self.records if r.status == "complete" and r.spec.policy == policy
                and (scene is None or r.spec.label == scene)]

    def values(self, scene: str, policy: str, key: str) -> np.ndarray:
        return np.array([_get(m, key) for m in self.complete(scene, policy)], float)

    def mean(self, scene: str | None, policy: str, key: str) -> float | None:
        """Mean over the complete trials of a scene; scene None: the mean over scenes of those means."""
        if scene is None:
            means = [m for s in self.scenes if (m := self.mean(s, policy, key)) is not None]
            return float(np.mean(means)) if means else None
        v = self.values(scene, policy, key)
        return float(v.mean()) if len(v) else None

    def covers_every_scene(self, policy: str, key: str) -> bool:
        """Whether the average of `policy` is over every scene (no '†')."""
        return all(self.mean(s, policy, key) is not None for s in self.scenes)

    def cell(self, scene: str, policy: str, key: str, decimals: int) -> str:
        """mean ± std over the complete trials; one trial: the value; none: n/a."""
        v = self.values(scene, policy, key)
        return _pm(self.mean(scene, policy, key), _std(v, self.cfg.std_ddof), decimals)

    def average(self, policy: str, key: str, decimals: int, with_std: bool = True) -> str:
        """Mean over scenes of the per-scene means; ± the std over seeds of the per-seed averages over scenes
        (seeds complete on every scene). '†': some scene has no complete run and is left out."""
        mean = self.mean(None, policy, key)
        if mean is None:
            return "n/a"
        per_seed: dict[int, dict[str, float]] = {}
        for r in self.records:
            if r.status == "complete" and r.spec.policy == policy:
                per_seed.setdefault(r.spec.seed, {})[r.spec.label] = _get(r.metrics, key)
        paired = np.array([np.mean(list(d.values())) for d in per_seed.values()
                           if len(d) == len(self.scenes)])
        std = _std(paired, self.cfg.std_ddof) if with_std else None
        return _pm(mean, std, decimals) + ("" if self.covers_every_scene(policy, key) else " †")

    def compiled(self, scene: str | None, policy: str) -> bool:
        """Whether a complete run of `policy` on `scene` (None: any scene) spent `JIT_NOTE_S` or more of its
        timed loop compiling numba kernels (the first run after an install or a code change): its ms/step
        and module times include that ('‡')."""
        return any((m.get("jit_compile_s") or 0.0) >= JIT_NOTE_S for m in self.complete(scene, policy))

    def trials(self, scene: str | None, policy: str) -> str:
        planned = [r for r in self.records
                   if r.spec.policy == policy and (scene is None or r.spec.label == scene)]
        return f"{sum(r.status == 'complete' for r in planned)}/{len(planned)}"


def _get(metrics: dict, key: str) -> float:
    """A metric by name; `timing_ms.<module>` reaches into timing_ms. Missing or None: NaN."""
    value = metrics.get("timing_ms", {}).get(key[10:]) if key.startswith("timing_ms.") else metrics.get(key)
    return float("nan") if value is None else float(value)


def _std(v: np.ndarray, ddof: int) -> float | None:
    return float(v.std(ddof=ddof)) if len(v) > max(1, ddof) else None


def _pm(mean: float | None, std: float | None, decimals: int) -> str:
    if mean is None or not np.isfinite(mean):
        return "n/a"
    return f"{mean:.{decimals}f}" + ("" if std is None else f" ± {std:.{decimals}f}")


# --------------------------------------------------------------------------- markdown
def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header),
            *("| " + " | ".join(row) + " |" for row in rows)]


def _metric_columns(cfg: TableConfig) -> list[tuple[str, str, str, int]]:
    """(metrics.json key, column name, unit as in the paper's per-scene tables, decimals)."""
    return [("completion_ratio_pct", "completion ratio % ↑", "% ↑", cfg.ratio_decimals),
            ("completion_cm", "completion cm ↓", "cm ↓", cfg.cm_decimals),
            ("path_length_m", "path length m", "m", cfg.path_decimals),
            ("ms_per_step", "ms/step", "ms", cfg.ms_decimals)]


BETTER = {"completion_ratio_pct": max, "completion_cm": min}
"""Columns whose best mean is printed bold, as in the paper's tables, and which way is better."""


def _cell(res: Results, scene: str | None, policy: str, policies: Sequence[str], key: str, decimals: int,
          with_std: bool = True) -> str:
    """The cell of a scene (None: the average over scenes), in bold when `policy` alone has the best mean of
    `key` (at the printed decimals) among at least two of `policies` with results: a tie is bold nowhere.
    An average that leaves out a scene (†) is over other scenes than the rest: it is neither bold nor
    what the others are measured against."""
    if scene is None:
        text = res.average(policy, key, decimals, with_std)
    else:
        text = res.cell(scene, policy, key, decimals)
    if key == "ms_per_step" and res.compiled(scene, policy):
        text += " ‡"
    means = {p: round(m, decimals) for p in policies if (m := res.mean(scene, p, key)) is not None
             and (scene is not None or res.covers_every_scene(p, key))}
    best = False
    if key in BETTER and len(means) > 1 and policy in means:
        top = BETTER[key](means.values())
        best = means[policy] == top and sum(m == top for m in means.values()) == 1
    return f"**{text}**" if best else text


def exploration_table(res: Results, policies: Sequence[str]) -> list[str]:
    """Tab. I / Tab. II layout: a block of rows per scene, then the average over scenes; best bold."""
    cols = _metric_columns(res.cfg)
    rows = [[scene or f"**average ({len(res.scenes)} scenes)**", p,
             *(_cell(res, scene, p, policies, k, d) for k, _, _, d in cols), res.trials(scene, p)]
            for scene in [*res.scenes, None] for p in policies]
    return _table(["scene", "policy", *(name for _, name, _, _ in cols), "trials"], rows)


def per_scene_table(res: Results) -> list[str]:
    """Supplementary Tab. S1 / S2 layout: policy x metric rows, scenes as columns, Avg. without ±."""
    metrics = [(k, unit, d) for k, _, unit, d in _metric_columns(res.cfg) if k != "ms_per_step"]
    rows = []
    for p in res.policies:
        for i, (k, unit, d) in enumerate(metrics):
            cells = [_cell(res, s, p, res.policies, k, d, with_std=False) for s in [*res.scenes, None]]
            rows.append([f"**{p}**" if i == 0 else "", unit, *cells])
    return _table(["policy", "metric", *res.scenes, "Avg."], rows)


def timing_table(res: Results) -> list[str]:
    """Tab. VI: mean ms per step of each module over every complete run of a policy; the paper's row first."""
    d = res.cfg.timing_decimals
    keys = [*(f"timing_ms.{k}" for k in TIMING_KEYS), "evaluation_ms_per_step", "ms_per_step"]
    header = ["policy", *(k.replace("_", " ") for k in TIMING_KEYS), "evaluation", "total"]
    rows = [["paper (RTX 3090)", *(f"{PAPER_TAB6_MS[k]:.2f}" for k in TIMING_KEYS), "–", "–"]]
    means = [[row[0] + (" ‡" if res.compiled(None, row[0]) else ""), *row[1:]]
             for row in _policy_means(res, keys, d)]
    return _table(header, rows + means)


def _policy_means(res: Results, keys: Sequence[str], decimals: int) -> list[list[str]]:
    """One row per policy: the mean of each metric over its complete runs."""
    rows = []
    for p in res.policies:
        ms = res.complete(None, p)
        rows.append([p, *(_pm(float(np.mean([_get(m, k) for m in ms])) if ms else None, None, decimals)
                          for k in keys)])
    return rows


def map_table(res: Results) -> list[str]:
    """The online map's size and the memory of the run, means over every complete run of a policy."""
    return _table(["policy", "Gaussians (final)", "Gaussians (peak)", "peak RSS (MB)"],
                  _policy_means(res, ("n_gaussians", "peak_gaussians", "peak_rss_mb"), 0))


PATH_FRACTIONS = (25, 50, 75, 100)
"""Path ratios (%) of the paper's Tab. III."""


def add_derived(metrics: dict, ceiling: dict | None = None) -> dict:
    """Add to a run's metrics what the tables derive from it: Tab. III's completion at 25 / 50 / 75 / 100 %
    of the path length (``path_<p>_completion_ratio_pct``, ``path_<p>_completion_cm``), and with the
    scene's sweep `ceiling` the measures of eval/behaviour.relative_to_ceiling."""
    from activesplat.eval.behaviour import at_path_fractions, relative_to_ceiling

    for row, pct in zip(at_path_fractions(metrics.get("curve") or [], [p / 100 for p in PATH_FRACTIONS]),
                        PATH_FRACTIONS, strict=False):
        metrics[f"path_{pct}_completion_ratio_pct"] = row["completion_ratio_pct"]
        metrics[f"path_{pct}_completion_cm"] = row["completion_cm"]
    if ceiling is not None:
        metrics.update(relative_to_ceiling(metrics, ceiling))
    return metrics


BEHAVIOUR_COLUMNS = (("completion_ratio_pct", "completion %", 2), ("ceiling_pct", "sweep ceiling %", 2),
                     ("of_ceiling_pct", "of ceiling %", 1), ("worst_room_of_ceiling_pct", "worst room %", 1),
                     ("rooms_entered", "rooms entered", 1), ("rooms_total", "rooms", 0),
                     ("rotation_pct", "rotations %", 1), ("steps_to_90_pct_ceiling", "steps to 90 %", 0),
                     ("steps_to_95_pct_ceiling", "steps to 95 %", 0))
"""(metrics key, column, decimals) of the multi-room behaviour table."""


def behaviour_table(res: Results) -> list[str]:
    """Multi-room behaviour (docs/benchmark.md): per scene and policy, then the average over scenes."""
    keys = [c for c in BEHAVIOUR_COLUMNS if any(r.metrics and c[0] in r.metrics for r in res.records)]
    def cell(scene, p, k, d):
        return res.cell(scene, p, k, d) if scene else res.average(p, k, d, with_std=False)

    rows = [[scene or f"**average ({len(res.scenes)} scenes)**", p,
             *(cell(scene, p, k, d) for k, _, d in keys)]
            for scene in [*res.scenes, None] for p in res.policies]
    return _table(["scene", "policy", *(name for _, name, _ in keys)], rows)


def gain_table(res: Results, group: str = "by_cause") -> list[str]:
    """Where the completion came from (`eval.behaviour.completion_gain`): per policy and cause (`group` =
    "by_cause") or action kind ("by_action"), the actions per run, the completion ratio (points) they added
    per run and that per 100 actions, means over every complete run of the policy."""
    rows = []
    for p in res.policies:
        runs = [m["completion_gain"][group] for m in res.complete(None, p) if "completion_gain" in m]
        if not runs:
            continue
        names = sorted({n for r in runs for n in r},
                       key=lambda n: -sum(r.get(n, {}).get("completion_pct", 0.0) for r in runs))
        for n in names:
            acts = float(np.mean([r.get(n, {}).get("actions", 0) for r in runs]))
            pct = float(np.mean([r.get(n, {}).get("completion_pct", 0.0) for r in runs]))
            rows.append([p, n, f"{acts:.0f}", f"{pct:.2f}", f"{100 * pct / acts:.2f}" if acts else "–"])
    return _table(["policy", "cause" if group == "by_cause" else "action", "actions per run",
                   "completion % per run", "per 100 actions"], rows) if rows else []


def path_fraction_table(res: Results) -> list[str]:
    """The paper's Tab. III: completion ratio / completion at 25-100 % of each run's path length, one pair
    of columns per policy, averaged over scenes."""
    d_ratio, d_cm = res.cfg.ratio_decimals, res.cfg.cm_decimals
    rows = [[f"**{pct} %**", *(cell for p in res.policies for cell in (
        res.average(p, f"path_{pct}_completion_ratio_pct", d_ratio, with_std=False),
        res.average(p, f"path_{pct}_completion_cm", d_cm, with_std=False)))] for pct in PATH_FRACTIONS]
    return _table(["path ratio", *(f"{p} {unit}" for p in res.policies for unit in ("% ↑", "cm ↓"))], rows)


def markdown_report(records: Sequence[RunRecord], cfg: TableConfig | None = None, steps: int | None = None,
                    curves: Sequence[str] = ()) -> str:
    """The whole results.md: Tab. I, Tab. II (when ablation variants ran), per-scene table, Tab. VI, and
    the runs that are not complete."""
    res = Results(records, cfg)
    seeds = sorted({r.spec.seed for r in res.records})
    counts = {s: sum(r.status == s for r in res.records) for s in ("complete", "failed", "missing")}
    out = [f"# Exploration benchmark: {len(res.scenes)} scene(s) x {len(res.policies)} policies x "
           f"{len(seeds)} trial(s)", "",
           f"Scenes: {', '.join(res.scenes)}. Seeds: {', '.join(map(str, seeds))}. "
           f"Steps: {steps if steps else 'scene default (1000 small, 2000 medium)'}. "
           f"Runs: {counts['complete']} complete, {counts['failed']} failed, {counts['missing']} missing.",
           "",
           f"Cells: mean ± std over trials (std with ddof={res.cfg.std_ddof}; one trial: the value). "
           "Averages: mean over scenes of the per-scene means, ± the std over seeds of the per-seed averages "
           "over scenes (seeds complete on every scene); † = some scene has no complete run. Completion "
           "ratio and completion follow the paper's protocol (docs/protocol.md §6); path length is the "
           "forward step times the move_forward actions, blocked ones included (the paper's definition); "
           "ms/step is the wall time of the whole step including the live evaluation; ‡ = it includes "
           f"{JIT_NOTE_S:.0f} s or more of some run compiling numba kernels (`jit_compile_s` in the CSV: "
           "the first run after an install or a code change), so it is slower than later runs.", ""]
    main = [p for p in res.policies if p not in ABLATION_POLICIES]
    ablations = [p for p in res.policies if p in ABLATION_POLICIES]
    if main:
        out += ["## Tab. I: exploration", "", *exploration_table(res, main), ""]
    if ablations:
        ours = [FULL_METHOD] if FULL_METHOD in res.policies else []
        out += ["## Tab. II: ablation of the exploration strategy", "",
                *exploration_table(res, ablations + ours), ""]
    out += ["## Tab. III: completion at fractions of the path length", "", *path_fraction_table(res), "",
            "Each run's completion with a path of at most 25 / 50 / 75 / 100 % of its own final path length "
            "(curve points at step 0 and every 50 steps), averaged as above.", ""]
    if any(r.metrics and "rotation_pct" in r.metrics for r in res.records):
        ceiling = any(r.metrics and "ceiling_pct" in r.metrics for r in res.records)
        notes = ""
        if ceiling:
            notes = ("Sweep ceiling: what the exhaustive sweep (eval/sweep.py) observes; of ceiling: "
                     "completion / ceiling; worst room: the lowest share of a room's own ceiling; ")
        notes += ("rooms entered: rooms the agent stood 0.5 m inside (corridors not counted); rotations: "
                  "share of turn / tilt actions; ")
        notes += ("steps to 90 / 95 %: first curve step at that share of the ceiling (n/a: some trial never "
                  "got there). " if ceiling else "without --ceiling the sweep's columns are left out. ")
        out += ["## Multi-room behaviour", "", *behaviour_table(res), "",
                notes + "Means over trials; average rows: means over scenes.", ""]
    if any(r.metrics and "completion_gain" in r.metrics for r in res.records):
        out += ["## Where the completion came from", "", *gain_table(res, "by_action"), "",
                *gain_table(res, "by_cause"), "",
                "Each ground-truth point is credited to the action after which it was first observed within "
                "5 cm (start: the first frame); causes are the explorer's reasons for its actions "
                "(bootstrap, arrival and multi_stop rotations, path following, level, escape, idle). "
                "Means over all complete runs of a policy.", ""]
    out += ["## Per scene (supplementary Tab. S1 / S2 style)", "", *per_scene_table(res), "",
            "## Tab. VI: mean processing time per step (ms)", "", *timing_table(res), "",
            "Module times are means over all complete runs of a policy; `evaluation` is the live completion "
            "measurement (not part of the robot's work), `total` the whole step; ‡ = some run's times "
            "include numba compiling its kernels, as marked in the exploration tables.", ""]
    if any(r.metrics and "n_gaussians" in r.metrics for r in res.records):
        out += ["## The map", "", *map_table(res), "",
                "Gaussians in the online map at the end and at its largest; peak RSS: the peak resident "
                "memory of the process that ran it (with --workers 1 every run is in one process: its "
                "peak over all the runs so far; a worker of --workers N runs one episode).", ""]
    if curves:
        out += ["## Completion curves", "", *(f"![{Path(c).stem}]({Path(c).name})" for c in curves), ""]
    broken = [r for r in res.records if r.status != "complete"]
    if broken:
        out += ["## Runs not complete", "",
                *_table(["scene", "policy", "seed", "status", "error"],
                        [[r.spec.label, r.spec.policy, str(r.spec.seed), r.status, r.error.replace("|", "/")]
                         for r in broken]), ""]
    return "\n".join(out)
