"""`activesplat benchmark`: tables from hand-written metrics, resume, failed and interrupted runs, bad input,
the executors (serial, a 2-process pool on tiny real runs, Ray's loop and its missing-package error), and
the mean ± std completion curves."""

import csv
import importlib.util
import json
import sys
import types

import numpy as np
import pytest

from activesplat import explore
from activesplat.bench import run_benchmark, write_report
from activesplat.bench.runner import RunResult, execute_run, plan_runs, run_ray
from activesplat.bench.tables import collect, markdown_report
from activesplat.cli import main
from activesplat.errors import interrupted
from activesplat.eval.coverage import CoverageConfig
from activesplat.explore import TIMING_KEYS
from activesplat.sim import SimConfig
from activesplat.viz.plots import draw_completion, mean_curve

TINY = dict(sim_config=SimConfig(width=64, height=64),
            coverage_config=CoverageConfig(n_gt_points=4000, batch_frames=10), backend="numba")


def _metrics(ratio, cm=2.0, path=10.0, ms=100.0, steps=1000, mapper=40.0, seed=0, policy="activesplat"):
    curve = [{"step": s, "completion_ratio_pct": ratio * s / steps, "completion_cm": cm,
              "path_length_m": path * s / steps} for s in (steps // 2, steps)]
    return {"completion_ratio_pct": ratio, "completion_cm": cm, "completion_cm_uncapped": cm + 1,
            "path_length_m": path, "steps": steps, "wall_time_s": ms * steps / 1000, "ms_per_step": ms,
            "evaluation_ms_per_step": 5.0,
            "timing_ms": {k: (mapper if k == "mapper" else 1.0) for k in TIMING_KEYS},
            "n_gaussians": 1234, "peak_gaussians": 1500 + seed, "peak_rss_mb": 900.0,
            "scene": "x", "policy": policy, "seed": seed, "curve": curve}


def _write(spec, metrics):
    spec.out.mkdir(parents=True, exist_ok=True)
    (spec.out / "metrics.json").write_text(json.dumps(metrics))


class FakeExplore:
    """Stands in for run_exploration: writes metrics.json from a table of results, or raises."""

    def __init__(self, ratios=None, fail=(), interrupt=()):
        self.calls = []
        self.ratios, self.fail, self.interrupt = ratios or {}, set(fail), set(interrupt)

    def __call__(self, scene, policy, steps, seed, out, overwrite, **options):
        self.calls.append((scene, policy, seed))
        assert overwrite, "a partial folder is re-run with overwrite"
        if (policy, seed) in self.interrupt:  # as an exploration's Ctrl-C: its own line, then Interrupted
            out.mkdir(parents=True, exist_ok=True)
            (out / "actions.txt").write_text("turn_left\n")  # a partial episode
            raise interrupted(f"interrupted after 1 steps: partial episode in {out}")
        if (policy, seed) in self.fail:
            raise RuntimeError(f"boom in {policy}")
        m = _metrics(self.ratios.get((scene, policy, seed), 90.0), steps=steps or 1000, seed=seed,
                     policy=policy)
        out.mkdir(parents=True, exist_ok=True)
        (out / "metrics.json").write_text(json.dumps(m))
        return m


@pytest.fixture
def fake(monkeypatch):
    def install(**kw):
        f = FakeExplore(**kw)
        monkeypatch.setattr(explore, "run_exploration", f)
        return f
    return install


def test_tables_mean_std_and_averages_from_handwritten_metrics(tmp_path):
    specs = plan_runs(["small-0", "small-1"], ["activesplat", "fbe", "random"], [0, 1], 1000, tmp_path)
    values = {("small-0", "activesplat"): (89.0, 91.0), ("small-1", "activesplat"): (80.0, 84.0),
              ("small-0", "fbe"): (70.0, 72.0), ("small-1", "fbe"): (60.0, None),
              ("small-0", "random"): (50.0, 50.0), ("small-1", "random"): (50.0, 50.0)}
    for spec in specs:
        ratio = values[(spec.label, spec.policy)][spec.seed]
        if ratio is None:  # the failed run
            spec.out.mkdir(parents=True)
            (spec.out / "error.txt").write_text("RuntimeError: boom\n\nTraceback ...")
        else:
            _write(spec, _metrics(ratio, cm=ratio / 10, mapper=ratio / 2, seed=spec.seed))
    records = collect(specs)
    assert [r.status for r in records].count("failed") == 1
    md = markdown_report(records)
    tab1 = md.split("## Tab. I:")[1].split("## Tab. II")[0]
    rows = {tuple(c.strip() for c in line.strip("|").split("|")[:2]): line for line in tab1.splitlines()
            if line.startswith("|")}
    # per scene: mean ± population std over the 2 seeds; the best completion ratio / completion in bold
    row = rows[("small-0", "activesplat")]
    assert "| **90.00 ± 1.00** | 9.00 ± 0.10 | 10.0 ± 0.0 | 100 ± 0 | 2/2 |" in row
    assert "| 71.00 ± 1.00 | **7.10 ± 0.10** |" in rows[("small-0", "fbe")]
    # average over scenes = mean of scene means (90, 82); ± std over seeds of per-seed averages (84.5, 87.5)
    assert "| **86.00 ± 1.50** |" in rows[("**average (2 scenes)**", "activesplat")]
    # fbe: small-1 has one complete trial of two, the seed-1 average is not paired -> no ±
    assert "| 60.00 | **6.00** |" in rows[("small-1", "fbe")] and "| 1/2 |" in rows[("small-1", "fbe")]
    assert "| 65.50 | **6.55** |" in rows[("**average (2 scenes)**", "fbe")]
    # random is an ablation variant: Tab. II lists it next to the full method, Tab. I does not
    tab2 = md.split("## Tab. II")[1].split("## Per scene")[0]
    assert "| random |" not in tab1 and "| random |" in tab2 and "| activesplat |" in tab2
    # supplementary layout: scenes as columns, Avg. without ±
    assert "| **activesplat** | % ↑ | **90.00 ± 1.00** | **82.00 ± 2.00** | **86.00** |" in md
    # Tab. VI: mean mapper ms over the 4 complete activesplat runs = mean(89, 91, 80, 84) / 2
    tab6 = md.split("## Tab. VI")[1]
    assert "| activesplat | 43.00 | 1.00 |" in tab6 and "| paper (RTX 3090) | 45.14 | 43.87 |" in tab6
    # the map: means over the complete runs (activesplat: seeds 0, 1, 0, 1 -> peak 1500.5, printed as 1500)
    assert "| activesplat | 1234 | 1500 | 900 |" in md.split("## The map")[1]
    assert "| small-1 | fbe | 1 | failed | RuntimeError: boom |" in md


def test_tab3_and_multi_room_tables(tmp_path):
    from activesplat.bench.tables import add_derived, markdown_report

    specs = plan_runs(["small-0"], ["activesplat", "no-hp"], [0], None, tmp_path)
    for spec, ratio in zip(specs, (90.0, 80.0), strict=True):
        metrics = _metrics(ratio)
        metrics.update({"rotation_pct": 30.0, "rooms_entered": 2, "rooms_total": 3})
        turn = ratio - 20.0  # the turns found 70 / 60 %, the forward moves 20 % in both runs
        metrics["completion_gain"] = {
            "by_cause": {"arrival": {"actions": 100, "completion_pct": turn},
                         "path": {"actions": 400, "completion_pct": 20.0}},
            "by_action": {"turn": {"actions": 100, "completion_pct": turn},
                          "move_forward": {"actions": 400, "completion_pct": 20.0}}}
        _write(spec, metrics)
    records = collect(specs)
    for r in records:  # as write_report does with the scene's sweep ceiling
        add_derived(r.metrics, {"completion_ratio_pct": 95.0})
    md = markdown_report(records)
    tab3 = md.split("## Tab. III")[1].split("##")[0]
    # the curve reaches half the path at step 500 (45 % / 40 %) and all of it at step 1000
    assert "| **50 %** | 45.00 | 2.00 | 40.00 | 2.00 |" in tab3
    assert "| **100 %** | 90.00 | 2.00 | 80.00 | 2.00 |" in tab3 and "| **25 %** | 0.00 | n/a |" in tab3
    multi = md.split("## Multi-room behaviour")[1].split("##")[0]
    assert "| small-0 | activesplat | 90.00 | 95.00 | 94.7 | 2.0 | 3 | 30.0 | 1000 | n/a |" in multi
    gain = md.split("## Where the completion came from")[1].split("##")[0]
    assert "| activesplat | turn | 100 | 70.00 | 70.00 |" in gain
    assert "| no-hp | arrival | 100 | 60.00 | 60.00 |" in gain
    assert "| no-hp | path | 400 | 20.00 | 5.00 |" in gain


def test_csv_one_row_per_run_with_every_scalar(tmp_path):
    specs = plan_runs(["small-0"], ["activesplat", "fbe"], [0], None, tmp_path)
    _write(specs[0], _metrics(91.5))
    report = write_report(tmp_path, specs)
    rows = list(csv.DictReader(open(report.csv)))
    assert [(r["policy"], r["status"]) for r in rows] == [("activesplat", "complete"), ("fbe", "missing")]
    assert float(rows[0]["completion_ratio_pct"]) == 91.5 and float(rows[0]["timing_ms.mapper"]) == 40.0
    assert rows[0]["n_gaussians"] == "1234" and "curve" not in rows[0] and rows[1]["completion_cm"] == ""
    assert [p.name for p in report.curves] == ["curves_small-0.png"]
    assert "| small-0 | fbe | n/a | n/a | n/a | n/a | 0/1 |" in report.markdown


def test_resume_skips_complete_runs_and_reruns_partial_ones(tmp_path, fake):
    specs = plan_runs(["small-0"], ["activesplat"], [0, 1, 2], 50, tmp_path)
    _write(specs[0], _metrics(95.0, steps=50))
    specs[1].out.mkdir(parents=True)
    (specs[1].out / "actions.txt").write_text("turn_left\n")  # a partial episode: no metrics.json
    f = fake()
    lines = []
    report = run_benchmark(["small-0"], ["activesplat"], trials=3, steps=50, root=tmp_path, log=lines.append)
    assert f.calls == [("small-0", "activesplat", 1), ("small-0", "activesplat", 2)]
    assert report.count("complete") == 3
    assert "1 already complete, 2 to run" in lines[0] and lines[1].startswith("[2/3] small-0 activesplat s1:")
    again = fake()
    run_benchmark(["small-0"], ["activesplat"], trials=3, steps=50, root=tmp_path, log=lines.append)
    assert again.calls == []


def test_a_failing_run_is_reported_not_fatal(tmp_path, fake, capsys, monkeypatch):
    # the command measures each scene's sweep ceiling by default: a stand-in sweep (the real one takes
    # a minute on small-0; tests/eval/test_sweep.py tests it) shows it is measured once and then cached
    sweeps = []
    monkeypatch.setattr("activesplat.eval.sweep.exhaustive_sweep",
                        lambda scene, *a, **k: sweeps.append(scene.name) or {"completion_ratio_pct": 95.0})
    fake(fail={("fbe", 0)})
    code = main(["benchmark", "--scenes", "small-0", "--policies", "activesplat", "fbe", "--steps", "20",
                 "--root", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 1
    assert "small-0 fbe s0: FAILED" in out and "RuntimeError: boom in fbe" in out
    assert "| small-0 | fbe | n/a | n/a | n/a | n/a | 0/1 |" in out
    assert (tmp_path / "small-0" / "fbe" / "s0" / "error.txt").read_text().startswith("RuntimeError: boom")
    assert (tmp_path / "small-0" / "activesplat" / "s0" / "metrics.json").is_file()
    # next time it works: the failed run is retried and its error file goes
    f = fake()
    assert main(["benchmark", "--scenes", "small-0", "--policies", "activesplat", "fbe", "--steps", "20",
                 "--root", str(tmp_path)]) == 0
    assert f.calls == [("small-0", "fbe", 0)]
    assert not (tmp_path / "small-0" / "fbe" / "s0" / "error.txt").exists()
    assert sweeps == ["small-0"]
    assert json.loads((tmp_path / "small-0" / "sweep.json").read_text())["completion_ratio_pct"] == 95.0
    rows = {r["policy"]: r for r in csv.DictReader((tmp_path / "results.csv").read_text().splitlines())}
    assert float(rows["fbe"]["ceiling_pct"]) == 95.0
    assert float(rows["fbe"]["of_ceiling_pct"]) == pytest.approx(100 * 90 / 95)


def test_ctrl_c_stops_and_keeps_the_tables_of_what_is_done(tmp_path, fake):
    fake(interrupt={("fbe", 0)})
    with pytest.raises(KeyboardInterrupt):
        run_benchmark(["small-0"], ["activesplat", "fbe", "random"], steps=20, root=tmp_path,
                      log=lambda s: None)
    status = {r["policy"]: r["status"] for r in csv.DictReader(open(tmp_path / "results.csv"))}
    assert status == {"activesplat": "complete", "fbe": "missing", "random": "missing"}


def test_ctrl_c_is_one_line_that_says_what_is_kept_and_how_to_resume(tmp_path, fake, capsys):
    """Not the run's own line (its partial episode is explored again, not evaluated), nor the tables' summary
    and a generic "interrupted" after it: one line, exit code 130; the same command then resumes."""
    fake(interrupt={("fbe", 0)})
    argv = ["benchmark", "--scenes", "small-0", "--policies", "activesplat", "fbe", "random", "--steps", "20",
            "--root", str(tmp_path), "--no-ceiling"]
    assert main(argv) == 130
    captured = capsys.readouterr()
    assert captured.err.strip() == (
        f"benchmark interrupted: 1 of 3 runs complete, their tables in {tmp_path / 'results.md'}; run the "
        f"same command again to resume (the runs not complete are explored again from scratch)")
    out = captured.out.splitlines()  # the start and the finished run, no summary of the tables after them
    assert len(out) == 2 and out[0].startswith("benchmark: 3 runs") and out[1].startswith("[1/3] small-0")
    f = fake()
    assert main(argv) == 0
    assert f.calls == [("small-0", "fbe", 0), ("small-0", "random", 0)]


def test_ctrl_c_in_the_sweep_ceiling_is_one_line(tmp_path, fake, capsys, monkeypatch):
    fake()
    monkeypatch.setattr("activesplat.eval.sweep.sweep_ceiling", _ctrl_c)
    argv = ["benchmark", "--scenes", "small-0", "--policies", "fbe", "--steps", "20", "--root", str(tmp_path)]
    assert main(argv) == 130
    assert capsys.readouterr().err.strip() == (
        f"benchmark interrupted while measuring the sweep ceiling: 1 of 1 runs complete in {tmp_path}, the "
        f"tables not written; run the same command again to write them (the ceilings measured are kept in "
        f"ROOT/<scene>/sweep.json)")
    assert not (tmp_path / "results.md").exists()


def _ctrl_c(*args, **kwargs):
    raise KeyboardInterrupt


@pytest.mark.parametrize("argv, needle", [
    (["--policies", "activesplat", "nope"], "unknown policy 'nope'"),
    (["--scenes", "small-0", "huge-3"], "unknown scene 'huge-3'"),
    (["--scenes", "/does/not/exist.glb"], "/does/not/exist.glb"),
    (["--trials", "0"], "--trials must be a positive"),
    (["--workers", "0"], "--workers must be a positive"),
    (["--steps", "-1"], "--steps must be a positive"),
])
def test_bad_input_is_one_line_error_before_anything_runs(capsys, tmp_path, fake, argv, needle):
    f = fake()
    code = main(["benchmark", "--scenes", "small-0", "--root", str(tmp_path / "root"), *argv])
    err = capsys.readouterr().err
    assert code == 2 and needle in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert f.calls == [] and not (tmp_path / "root").exists()


def test_another_budget_in_the_same_root_is_refused(tmp_path):
    spec = plan_runs(["small-0"], ["fbe"], [0], 300, tmp_path)[0]
    _write(spec, _metrics(90.0, steps=300))
    with pytest.raises(Exception, match="holds a 300-step run but this benchmark asks for 1000 steps"):
        plan_runs(["small-0"], ["fbe"], [0], None, tmp_path)


@pytest.mark.skipif(importlib.util.find_spec("ray") is not None, reason="ray is installed")
def test_ray_executor_without_ray_says_how_to_install_it(capsys, tmp_path):
    code = main(["benchmark", "--scenes", "small-0", "--executor", "ray", "--root", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert code == 2 and "pip install 'activesplat[ray]'" in err and len(err.strip().splitlines()) == 1


def test_ray_loop_reports_every_task(tmp_path, monkeypatch, fake):
    """run_ray against a stand-in `ray` module that runs each task when it is waited on."""
    calls = {"init": None, "cancelled": 0}

    class Ref:
        def __init__(self, fn, args):
            self.fn, self.args = fn, args

    def remote(**opts):
        assert opts["num_cpus"] == 2.0
        return lambda fn: types.SimpleNamespace(remote=lambda *args: Ref(fn, args))

    ray = types.SimpleNamespace(
        init=lambda address, ignore_reinit_error: calls.__setitem__("init", address), remote=remote,
        wait=lambda refs, num_returns: (refs[:1], refs[1:]), get=lambda ref: ref.fn(*ref.args),
        cancel=lambda ref, force: calls.__setitem__("cancelled", calls["cancelled"] + 1))
    monkeypatch.setitem(sys.modules, "ray", ray)
    f = fake(fail={("fbe", 0)})
    specs = plan_runs(["small-0"], ["activesplat", "fbe"], [0], 20, tmp_path)
    got = []
    run_ray(specs, {}, lambda spec, result: got.append((spec.policy, result.status)), "auto", 2.0)
    assert calls["init"] == "auto" and got == [("activesplat", "complete"), ("fbe", "failed")]
    assert len(f.calls) == 2


def test_serial_run_of_a_real_tiny_episode(tmp_path):
    specs = plan_runs(["small-0"], ["random"], [0], 3, tmp_path)
    result = execute_run(specs[0], TINY)
    assert isinstance(result, RunResult) and result.status == "complete", result.error
    for name in ("metrics.json", "actions.txt", "completion.png", "topdown.png"):
        assert (specs[0].out / name).is_file(), name
    assert result.metrics["steps"] == 3


@pytest.mark.slow
def test_local_executor_two_workers_two_tiny_runs(tmp_path):
    lines = []
    report = run_benchmark(["small-0"], ["activesplat", "fbe"], steps=3, root=tmp_path, workers=2,
                           run_options=TINY, log=lines.append)
    assert report.count("complete") == 2, lines
    assert "2 worker processes" in lines[0] and sum(line.startswith("[") for line in lines) == 2
    for policy in ("activesplat", "fbe"):
        assert json.loads((tmp_path / "small-0" / policy / "s0" / "metrics.json").read_text())["steps"] == 3
    assert (tmp_path / "curves_small-0.png").is_file() and (tmp_path / "results.md").is_file()


def test_workers_split_the_cores_this_process_may_use(monkeypatch):
    """`taskset -c 0-7 activesplat benchmark --workers 8` on a 16-core machine: one thread per worker, not
    two (the cores of the affinity mask, not of the machine)."""
    from activesplat.bench import runner

    monkeypatch.setattr(runner.os, "sched_getaffinity", lambda pid: set(range(8)), raising=False)
    monkeypatch.setattr(runner.os, "cpu_count", lambda: 16)
    assert runner._usable_cpus() == 8
    monkeypatch.delattr(runner.os, "sched_getaffinity")
    assert runner._usable_cpus() == 16


def test_mean_curve_interpolates_and_cuts_at_the_shortest_run():
    a = [{"step": 0, "v": 0.0}, {"step": 10, "v": 10.0}, {"step": 20, "v": 20.0}]
    b = [{"step": 0, "v": 2.0}, {"step": 5, "v": 2.0}, {"step": 15, "v": 12.0}]
    steps, mean, std = mean_curve([a, b], "v")
    assert steps.tolist() == [0, 5, 10, 15]  # a's step 20 is past b's end
    np.testing.assert_allclose(mean, [1.0, 3.5, 8.5, 13.5])
    np.testing.assert_allclose(std, [1.0, 1.5, 1.5, 1.5])
    assert mean_curve([[], []], "v")[0].size == 0


def test_draw_completion_single_runs_and_trial_bands(tmp_path):
    run = _metrics(90.0)["curve"]
    one = draw_completion(tmp_path / "one.png", {"activesplat": run}, title="single")  # the episode's call
    bands = draw_completion(tmp_path / "bands.png", {"activesplat": [run, _metrics(80.0)["curve"]],
                                                     "fbe": [run], "none": []})
    assert one.stat().st_size > 0 and bands.stat().st_size > 0


def test_a_tie_is_bold_nowhere_and_without_a_ceiling_its_columns_are_not_explained(tmp_path):
    from activesplat.bench.tables import markdown_report

    specs = plan_runs(["small-0"], ["activesplat", "fbe"], [0], None, tmp_path)
    for spec in specs:  # the same completion (a short budget: both only did the bootstrap)
        metrics = _metrics(39.11, cm=5.0 if spec.policy == "fbe" else 6.0)
        metrics.update({"rotation_pct": 100.0, "rooms_entered": 1, "rooms_total": 3})
        _write(spec, metrics)
    md = markdown_report(collect(specs))
    tab1 = md.split("## Tab. I:")[1].split("## Tab. III")[0]
    assert "**39.11**" not in tab1 and "39.11" in tab1
    assert "**5.00**" in tab1  # a difference is still bold
    multi = md.split("## Multi-room behaviour")[1].split("##")[0]
    assert "Sweep ceiling" not in multi and "steps to 90" not in multi and "rotations:" in multi


def test_an_average_that_leaves_out_a_scene_is_not_bold(tmp_path):
    # fbe failed on the hard scene: its average (70, small-0 only) is higher than activesplat's over both
    # scenes (60), but it is over other scenes: neither is bold (one average over every scene is no contest)
    specs = plan_runs(["small-0", "small-1"], ["activesplat", "fbe"], [0], None, tmp_path)
    ratios = {("small-0", "activesplat"): 65.0, ("small-1", "activesplat"): 55.0, ("small-0", "fbe"): 70.0}
    for spec in specs:
        if (spec.label, spec.policy) in ratios:
            _write(spec, _metrics(ratios[(spec.label, spec.policy)], cm=1.0 if spec.policy == "fbe" else 2.0))
        else:
            spec.out.mkdir(parents=True)
            (spec.out / "error.txt").write_text("RuntimeError: boom\n")
    md = markdown_report(collect(specs))
    tab1 = md.split("## Tab. I:")[1].split("## Tab. III")[0]
    assert "| **average (2 scenes)** | fbe | 70.00 † | 1.00 † |" in tab1
    assert "| **average (2 scenes)** | activesplat | 60.00 | 2.00 |" in tab1
    assert "| small-0 | fbe | **70.00** | **1.00** |" in tab1  # per scene, both ran
    assert "| **fbe** | % ↑ | **70.00** | n/a | 70.00 † |" in md  # the per-scene table's Avg. column


def test_runs_whose_timing_includes_numba_compiling_are_marked(tmp_path):
    # a first run after an install compiled kernels inside its timed loop: its ms/step and Tab. VI row say so
    specs = plan_runs(["small-0"], ["activesplat", "fbe"], [0], None, tmp_path)
    for spec in specs:
        metrics = _metrics(60.0, ms=249.0 if spec.policy == "activesplat" else 30.0)
        metrics["jit_compile_s"] = 17.0 if spec.policy == "activesplat" else 0.0
        _write(spec, metrics)
    md = markdown_report(collect(specs))
    tab1 = md.split("## Tab. I:")[1].split("## Tab. III")[0]
    assert "| small-0 | activesplat | 60.00 | 2.00 | 10.0 | 249 ‡ |" in tab1
    assert "| small-0 | fbe | 60.00 | 2.00 | 10.0 | 30 |" in tab1
    assert "‡ = it includes 1 s or more of some run compiling numba kernels" in md
    tab6 = md.split("## Tab. VI")[1].split("##")[0]
    assert "| activesplat ‡ |" in tab6 and "| fbe |" in tab6
    from activesplat.bench.tables import write_csv

    with open(write_csv(tmp_path / "runs.csv", collect(specs)), encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert sorted(float(r["jit_compile_s"]) for r in rows) == [0.0, 17.0]
