"""`activesplat benchmark`: scenes x policies x trials (seeds) of exploration episodes, then tables and
curves in the paper's style (Tab. I, II, VI, the supplementary per-scene tables, Fig. 6).

```python
from activesplat.bench import run_benchmark
report = run_benchmark(["small-2", "small-3"], ["activesplat", "fbe"], trials=3, workers=2, root="runs/bench")
print(report.markdown)
```

Layout of ROOT: ``<scene>/<policy>/s<seed>/`` (one episode folder per run), ``results.csv`` (one row per
run), ``results.md`` (the tables), ``curves_<scene>.png`` and ``curves_average.png`` (completion ratio and
path length against steps, mean ± std over trials). Runs already complete are skipped, so running the same
command again resumes an interrupted benchmark.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from activesplat.bench.runner import (
    EXECUTORS,
    RunResult,
    RunSpec,
    check_configs,
    persist,
    plan_runs,
    read_metrics,
    run_local,
    run_ray,
    run_serial,
)
from activesplat.bench.tables import RunRecord, TableConfig, add_derived, collect, markdown_report, write_csv
from activesplat.errors import (
    InvalidInputError,
    check_output_file,
    check_output_folder,
    interrupted,
    quiet_interrupts,
)

__all__ = ["BenchmarkConfig", "BenchmarkReport", "RunSpec", "TableConfig", "benchmark_from_command",
           "run_benchmark", "write_report"]


@dataclass(frozen=True)
class BenchmarkConfig:
    """Settings of a benchmark beyond its runs."""

    ray_cpus_per_run: float = 2.0
    """CPUs a Ray task reserves: the numba rasterizer and torch use a few threads per episode."""
    tables: TableConfig = field(default_factory=TableConfig)
    """Number formats of results.md."""


@dataclass
class BenchmarkReport:
    """What a benchmark left in ROOT."""

    root: Path
    records: list[RunRecord]
    csv: Path
    markdown_path: Path
    markdown: str
    curves: list[Path]

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.records)

    @property
    def failed(self) -> list[RunRecord]:
        return [r for r in self.records if r.status == "failed"]


def _print(line: str) -> None:
    print(line, flush=True)


def run_benchmark(scenes: Sequence[str], policies: Sequence[str], trials: int = 1, steps: int | None = None,
                  root: str | Path = "runs/benchmark", workers: int = 1, executor: str = "local",
                  ray_address: str | None = None, seeds: Sequence[int] | None = None,
                  run_options: dict | None = None, config: BenchmarkConfig | None = None,
                  log: Callable[[str], None] = _print, ceiling: bool = False) -> BenchmarkReport:
    """Run every (scene, policy, seed) not yet complete under ROOT, then write the tables and curves.

    seeds default to 0..trials-1. `run_options` are extra keyword arguments of
    `activesplat.explore.run_exploration` (configs, backend); with a `config` (a RunConfig: the settings of
    every run), runs already complete in ROOT must have been made with it. A failed run is reported and
    shown as n/a; it does not stop the others. Ctrl-C stops the runs, writes the tables of what is complete
    and raises `Interrupted`, its one line (what is complete, that the same command resumes) printed.
    `ceiling`: add the sweep ceiling of every scene to the multi-room table (write_report)."""
    config = config or BenchmarkConfig()
    if trials <= 0:
        raise InvalidInputError(f"--trials must be a positive number of trials, got {trials}")
    if workers <= 0:
        raise InvalidInputError(f"--workers must be a positive number of processes, got {workers}")
    if executor not in EXECUTORS:
        raise InvalidInputError(f"unknown executor {executor!r}; choose one of: {', '.join(EXECUTORS)}")
    if executor == "ray" and importlib.util.find_spec("ray") is None:
        raise InvalidInputError("--executor ray needs Ray: pip install 'activesplat[ray]'")
    seeds = list(range(trials)) if seeds is None else [int(s) for s in seeds]
    specs = plan_runs(scenes, policies, seeds, steps, root)
    if (run_options or {}).get("config") is not None:
        check_configs(specs, run_options["config"])
    root = Path(root).resolve()
    check_output_folder(root)  # before the runs, and the tables after them
    for name in ("results.csv", "results.md"):
        check_output_file(root / name)
    root.mkdir(parents=True, exist_ok=True)
    todo = [s for s in specs if read_metrics(s.out) is None]
    for spec in todo:  # a file where a run's folder goes fails here, not run by run after the others
        check_output_folder(spec.out)
    where = f"Ray ({ray_address or 'default address'})" if executor == "ray" else (
        "this process" if workers == 1 else f"{workers} worker processes")
    shape = [len({getattr(s, k) for s in specs}) for k in ("label", "policy", "seed")]
    log(f"benchmark: {len(specs)} runs ({shape[0]} scenes x {shape[1]} policies x {shape[2]} trials), "
        f"{len(specs) - len(todo)} already complete, {len(todo)} to run on {where} -> {root}")

    finished = {"n": len(specs) - len(todo)}

    def on_result(spec: RunSpec, result: RunResult) -> None:
        persist(spec, result)
        finished["n"] += 1
        log(f"[{finished['n']}/{len(specs)}] {spec.name}: {_result_line(result)}")

    bar = executor == "local" and workers == 1 and sys.stderr.isatty()  # a progress bar when serial
    options = {"progress": bar, **(run_options or {})}
    t0 = time.perf_counter()
    stopped = False
    try:
        with quiet_interrupts():  # the run in progress says nothing: the benchmark's line says it all
            if todo and executor == "ray":
                run_ray(todo, options, on_result, ray_address, config.ray_cpus_per_run)
            elif todo and workers == 1:
                run_serial(todo, options, on_result)
            elif todo:
                run_local(todo, options, on_result, workers)
    except KeyboardInterrupt:
        stopped = True
    if ceiling and not stopped:
        log("benchmark: measuring the sweep ceiling of each scene (cached in ROOT/<scene>/sweep.json)")
    try:
        report = write_report(root, specs, steps, config.tables, ceiling=ceiling and not stopped,
                              run_config=(run_options or {}).get("config"))
    except KeyboardInterrupt:
        done = sum(read_metrics(s.out) is not None for s in specs)
        what = "measuring the sweep ceiling" if ceiling and not stopped else "writing the tables"
        raise interrupted(f"benchmark interrupted while {what}: {done} of {len(specs)} runs complete in "
                          f"{root}, the tables not written; run the same command again to write them"
                          + (" (the ceilings measured are kept in ROOT/<scene>/sweep.json)"
                             if ceiling and not stopped else "")) from None
    if stopped:
        failed = f", {report.count('failed')} failed" if report.failed else ""
        raise interrupted(f"benchmark interrupted: {report.count('complete')} of {len(specs)} runs complete"
                          f"{failed}, their tables in {report.markdown_path}; run the same command again to "
                          f"resume (the runs not complete are explored again from scratch)") from None
    log(f"benchmark: {report.count('complete')} complete, {report.count('failed')} failed, "
        f"{report.count('missing')} not run ({time.perf_counter() - t0:.0f} s) -> {report.markdown_path}")
    for r in report.failed:
        log(f"  failed: {r.spec.name}: {r.error} (see {r.spec.out}/error.txt)")
    return report


def _result_line(result: RunResult) -> str:
    if result.status != "complete":
        return f"FAILED after {result.seconds:.0f} s: {result.error_line}"
    m = result.metrics
    return (f"completion {m['completion_ratio_pct']:.2f} % | {m['completion_cm']:.2f} cm | "
            f"path {m['path_length_m']:.1f} m | {result.seconds:.0f} s")


def write_report(root: str | Path, specs: Sequence[RunSpec], steps: int | None = None,
                 cfg: TableConfig | None = None, ceiling: bool = False, run_config=None) -> BenchmarkReport:
    """results.csv, curves_<scene>.png (+ curves_average.png) and results.md from the folders on disk.

    `ceiling`: measure each scene's exhaustive-sweep ceiling (cached in ROOT/<scene>/sweep.json; minutes
    per house) for the multi-room table; `run_config`: the RunConfig of the runs (its sim and coverage
    settings make the sweep comparable)."""
    from activesplat.eval.sweep import sweep_ceiling
    from activesplat.viz.plots import draw_completion

    root = Path(root)
    records = collect(specs)
    tops = {}
    if ceiling:
        sim_config = run_config.sim if run_config is not None else None
        coverage_config = run_config.coverage if run_config is not None else None
        for label, scene in {r.spec.label: r.spec.scene for r in records if r.status == "complete"}.items():
            tops[label] = sweep_ceiling(scene, root / label / "sweep.json", sim_config,
                                        coverage_config=coverage_config)
    for r in records:
        if r.status == "complete":
            add_derived(r.metrics, tops.get(r.spec.label))
    csv_path = write_csv(root / "results.csv", records)
    scenes = list(dict.fromkeys(r.spec.label for r in records))
    policies = list(dict.fromkeys(r.spec.policy for r in records))

    def curves(scene: str | None) -> dict[str, list[list[dict]]]:
        return {p: [r.metrics["curve"] for r in records if r.status == "complete" and r.spec.policy == p
                    and (scene is None or r.spec.label == scene) and r.metrics.get("curve")]
                for p in policies}

    pngs = []
    for scene in [*scenes, *([None] if len(scenes) > 1 else [])]:
        found = curves(scene)
        if any(found.values()):
            name = scene or "average"
            title = f"{name}: mean ± std over trials" if scene else f"all {len(scenes)} scenes: mean ± std"
            pngs.append(draw_completion(root / f"curves_{name}.png", found, title=title))
    markdown = markdown_report(records, cfg, steps=steps, curves=[p.name for p in pngs])
    md_path = root / "results.md"
    md_path.write_text(markdown + "\n", encoding="utf-8")
    return BenchmarkReport(root, records, csv_path, md_path, markdown, pngs)


def benchmark_from_command(cmd) -> int:
    """`activesplat benchmark` (an `activesplat.config.BenchmarkCommand`): exit code 0 when every run is
    complete, 1 when some failed. Its RunConfig's settings (the --GROUP.FIELD options) reach every run."""
    report = run_benchmark(scenes=list(cmd.scenes), policies=list(cmd.policies), trials=cmd.trials,
                           steps=cmd.steps, root=cmd.root, workers=cmd.workers, executor=cmd.executor,
                           ray_address=cmd.ray_address, run_options={"config": cmd.run}, ceiling=cmd.ceiling)
    print("\n" + report.markdown)
    return 1 if report.failed else 0
