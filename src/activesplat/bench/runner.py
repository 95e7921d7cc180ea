"""Planning and executing the runs of a benchmark: one exploration episode per (scene, policy, seed).

A run is the call `activesplat.explore.run_exploration(scene, policy, steps, seed, out)`; its episode
folder is ``ROOT/<scene>/<policy>/s<seed>/``. A folder holding a complete ``metrics.json`` is a finished
run and is skipped, so an interrupted benchmark resumes; a partial folder is explored again from scratch.

Executors:

- serial (``workers=1``): the runs one after another in this process;
- local (``workers>1``): a ``concurrent.futures.ProcessPoolExecutor`` with the spawn start method, each run
  in a fresh process (``max_tasks_per_child=1``), the CPU threads split between the workers;
- ray: one Ray task per run on a cluster (``pip install 'activesplat[ray]'``; imported only there).

This module imports nothing heavy at module level: spawned workers set their thread counts before numba
and torch are loaded.
"""

from __future__ import annotations

import json
import os
import signal
import time
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from activesplat.errors import InvalidInputError

ERROR_FILE = "error.txt"
"""Written into a run's folder when the run raised: the exception on the first line, then the traceback."""

EXECUTORS = ("local", "ray")


@dataclass(frozen=True)
class RunSpec:
    """One episode of the benchmark."""

    scene: str
    """The scene as given: a built-in name or a mesh file."""
    label: str
    """The scene's short name in folders and tables (the file stem for a mesh file)."""
    policy: str
    seed: int
    steps: int | None
    """Step budget; None: the scene's default (1000 small, 2000 medium)."""
    out: Path
    """The episode folder ROOT/<label>/<policy>/s<seed>."""

    @property
    def name(self) -> str:
        return f"{self.label} {self.policy} s{self.seed}"


@dataclass
class RunResult:
    """What one executed run reports back to the benchmark."""

    status: str
    """"complete", "failed" or "interrupted"."""
    seconds: float
    metrics: dict | None = None
    error: str | None = None
    """The traceback of a failed run (first line: exception type and message)."""

    @property
    def error_line(self) -> str:
        return (self.error or "").strip().splitlines()[-1] if self.error else ""


# --------------------------------------------------------------------------- planning
def scene_label(scene: str) -> str:
    """Built-in names stay as they are; a mesh file is named by its stem."""
    from activesplat.sim.scene import BUILTIN_PATTERN

    return scene if BUILTIN_PATTERN.match(scene) else Path(scene).stem


def default_steps(scene: str) -> int:
    """The budget run_exploration uses when none is given (without building the scene)."""
    from activesplat.sim.scene import BUILTIN_PATTERN, DEFAULT_STEPS

    match = BUILTIN_PATTERN.match(scene)
    return DEFAULT_STEPS[match.group(1) if match else "file"]


def validate_scene(scene: str) -> None:
    """A built-in name or an existing mesh file; checked before any run starts (the mesh itself is read by
    the run, so a corrupt file fails that run only)."""
    from activesplat.errors import SceneError
    from activesplat.sim.scene import BUILTIN_NAMES, BUILTIN_PATTERN, MESH_SUFFIXES

    if BUILTIN_PATTERN.match(scene):
        return
    path = Path(scene)
    if path.suffix.lower() in MESH_SUFFIXES and path.is_file():
        return
    if path.suffix.lower() in MESH_SUFFIXES:
        raise SceneError(f"scene file not found: {scene}")
    raise SceneError(f"unknown scene {scene!r}: expected {BUILTIN_NAMES} or a mesh file "
                     f"({', '.join(MESH_SUFFIXES)})")


def read_metrics(out: Path) -> dict | None:
    """The metrics of a complete episode folder, else None (missing, unreadable or marked partial)."""
    path = Path(out) / "metrics.json"
    if not path.is_file():
        return None
    try:
        metrics = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return metrics if isinstance(metrics, dict) and metrics.get("complete", True) else None


def plan_runs(scenes: Sequence[str], policies: Sequence[str], seeds: Sequence[int], steps: int | None,
              root: str | Path) -> list[RunSpec]:
    """Validate every argument, then list the runs scene by scene, policy by policy, seed by seed.

    Raises InvalidInputError / SceneError (one line each) before anything runs."""
    from activesplat.planning.policies import check_policy

    if not scenes:
        raise InvalidInputError("--scenes needs at least one scene")
    if not policies:
        raise InvalidInputError("--policies needs at least one policy")
    if not seeds:
        raise InvalidInputError("--trials must be a positive number of trials, got 0")
    if steps is not None and steps <= 0:
        raise InvalidInputError(f"--steps must be a positive number of actions, got {steps}")
    for policy in policies:
        check_policy(policy)
    for scene in scenes:
        validate_scene(scene)
    scenes, policies, seeds = _unique(scenes), _unique(policies), _unique(seeds)
    labels: dict[str, str] = {}
    for scene in scenes:
        label = scene_label(scene)
        if label in labels:
            raise InvalidInputError(f"scenes {labels[label]!r} and {scene!r} would share the folder {label}/")
        labels[label] = scene
    root = Path(root).resolve()
    specs = [RunSpec(scene, label, policy, int(seed), steps, root / label / policy / f"s{seed}")
             for label, scene in labels.items() for policy in policies for seed in seeds]
    for spec in specs:  # a finished run with another budget would silently mix budgets in one table
        done = read_metrics(spec.out)
        want = steps or default_steps(spec.scene)
        if done is not None and done.get("steps") != want:
            raise InvalidInputError(f"{spec.out} holds a {done.get('steps')}-step run but this benchmark "
                                    f"asks for {want} steps: use another --root")
    return specs


def check_configs(specs: Sequence[RunSpec], config) -> None:
    """Refuse a ROOT whose finished runs were made with other settings than `config` (a RunConfig whose
    scene, policy, seed and steps each run replaces): one table would mix configurations.

    A setting the recorded config lacks (an option added after the run) ran as its version's code did: the
    value `activesplat.config.ADDED` gives it (a field whose default changed what runs do), else the
    default (an option added off keeps the old behaviour). The ``refine`` group is not compared: a benchmark
    explores and evaluates, and offline refinement (`activesplat refine`) is never part of its runs."""
    from activesplat.config import ADDED

    defaults = _flat(type(config)().to_dict())
    ran_as = {**defaults, **ADDED}
    for spec in specs:
        if read_metrics(spec.out) is None:
            continue
        try:
            recorded = json.loads((spec.out / "episode.json").read_text())["config"]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        want = config.replace(scene=spec.scene, policy=spec.policy, seed=spec.seed,
                              steps=recorded.get("steps")).to_dict()
        was, now = _flat(recorded), _flat(want)
        differ = [k for k in now if was.get(k, ran_as.get(k)) != now[k] and not k.startswith("refine.")]
        if differ:
            key = differ[0]
            then = (f"with {key} = {was[key]!r}" if key in was
                    else f"before {key} existed (it ran as {ran_as.get(key)!r})" if key in ADDED
                    else f"before {key} existed (default {defaults.get(key)!r})")
            raise InvalidInputError(f"{spec.out} was run {then} but this benchmark asks for {now[key]!r}: "
                                    f"use another --root")


def _flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[prefix + k] = list(v) if isinstance(v, tuple) else v
    return out


def _unique(items: Iterable) -> list:
    return list(dict.fromkeys(items))


# --------------------------------------------------------------------------- one run
def execute_run(spec: RunSpec, options: dict | None = None) -> RunResult:
    """Explore one episode into spec.out (replacing a partial folder); never raises for a failed run.

    `options` are extra keyword arguments of run_exploration (configs, backend, progress)."""
    from activesplat import explore

    options = dict(options or {})
    options.setdefault("progress", False)
    error_file = spec.out / ERROR_FILE
    error_file.unlink(missing_ok=True)
    t0 = time.perf_counter()
    try:
        metrics = explore.run_exploration(spec.scene, policy=spec.policy, steps=spec.steps, seed=spec.seed,
                                          out=spec.out, overwrite=True, **options)
    except KeyboardInterrupt:
        return RunResult("interrupted", time.perf_counter() - t0)
    except Exception:  # noqa: BLE001 - a failed run is reported, not fatal to the benchmark
        error = traceback.format_exc()
        spec.out.mkdir(parents=True, exist_ok=True)
        error_file.write_text(_error_first(error))
        return RunResult("failed", time.perf_counter() - t0, error=error)
    return RunResult("complete", time.perf_counter() - t0, metrics=metrics)


def _error_first(error: str) -> str:
    """The exception line first (what tables show), then the traceback."""
    return error.strip().splitlines()[-1] + "\n\n" + error


def persist(spec: RunSpec, result: RunResult) -> None:
    """Make the run's outcome visible in ROOT on this machine (a Ray worker on another node without a
    shared filesystem wrote its episode there): metrics.json of a complete run, error.txt of a failed one."""
    from activesplat.episode import write_json_atomic

    if result.status == "complete" and read_metrics(spec.out) is None and result.metrics is not None:
        spec.out.mkdir(parents=True, exist_ok=True)
        write_json_atomic(spec.out / "metrics.json", result.metrics)
    elif result.status == "failed" and not (spec.out / ERROR_FILE).exists():
        spec.out.mkdir(parents=True, exist_ok=True)
        (spec.out / ERROR_FILE).write_text(_error_first(result.error or "unknown error"))


# --------------------------------------------------------------------------- executors
OnResult = Callable[[RunSpec, RunResult], None]


def run_serial(specs: Sequence[RunSpec], options: dict, on_result: OnResult) -> None:
    """In this process, one after another; Ctrl-C stops after the current run has left a partial folder."""
    for spec in specs:
        result = execute_run(spec, options)
        if result.status == "interrupted":
            raise KeyboardInterrupt
        on_result(spec, result)


def _init_worker(threads: int) -> None:
    """Spawned worker: its share of the cores, and Ctrl-C is the parent's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = str(threads)


def _usable_cpus() -> int:
    """The cores this process may run on (``taskset`` / cgroup affinity), not all the machine has."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def run_local(specs: Sequence[RunSpec], options: dict, on_result: OnResult, workers: int) -> None:
    """A process pool (spawn), each run in a fresh process; Ctrl-C cancels what has not started and
    terminates the running workers (their folders stay partial and are re-run on resume)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    threads = max(1, _usable_cpus() // workers)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_init_worker, initargs=(threads,), max_tasks_per_child=1)
    try:
        futures = {pool.submit(execute_run, spec, options): spec for spec in specs}
        for future in as_completed(futures):
            try:
                result = future.result()
            except Exception as exc:  # noqa: BLE001 - the worker process died (killed, out of memory)
                result = RunResult("failed", 0.0, error=f"{type(exc).__name__}: worker process died: {exc}")
            on_result(futures[future], result)
    except BaseException:  # Ctrl-C, or on_result failing (e.g. its output pipe closed): stop the workers
        processes = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        for process in processes:
            process.join(timeout=10)
        raise
    pool.shutdown()


def run_ray(specs: Sequence[RunSpec], options: dict, on_result: OnResult, address: str | None,
            cpus_per_run: float) -> None:
    """One Ray task per run (each reserves `cpus_per_run` CPUs); Ctrl-C cancels every unfinished task."""
    try:
        import ray
    except ImportError:
        raise InvalidInputError("--executor ray needs Ray: pip install 'activesplat[ray]'") from None
    ray.init(address=address, ignore_reinit_error=True)
    task = ray.remote(num_cpus=cpus_per_run, max_retries=0)(execute_run)
    pending = {task.remote(spec, options): spec for spec in specs}
    try:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                spec = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - the task or its node died
                    result = RunResult("failed", 0.0, error=f"{type(exc).__name__}: {exc}")
                on_result(spec, result)
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref, force=True)
        raise
