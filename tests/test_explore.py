"""The closed loop end to end on tiny settings: episode folder, determinism, evaluate = explore, crash safety,
bad input on the command line."""

import json

import numpy as np
import pytest

from activesplat.cli import main
from activesplat.episode import read_episode
from activesplat.eval.coverage import CoverageConfig
from activesplat.eval.evaluate import evaluate_episode, replay_episode
from activesplat.explore import TIMING_KEYS, run_exploration
from activesplat.sim import SimConfig

TINY = dict(sim_config=SimConfig(width=64, height=64), coverage_config=CoverageConfig(n_gt_points=4000,
                                                                                     batch_frames=10),
            progress=False, backend="numba")


@pytest.fixture(scope="module")
def episode(tmp_path_factory):
    out = tmp_path_factory.mktemp("ep") / "small0"
    metrics = run_exploration("small-0", policy="activesplat", steps=90, seed=1, out=out, **TINY)
    return out, metrics


def test_episode_folder_is_complete(episode):
    out, metrics = episode
    for name in ("episode.json", "actions.txt", "poses.txt", "metrics.json", "gaussians.ply", "topdown.png",
                 "completion.png"):
        assert (out / name).is_file(), name
    ep = read_episode(out)
    assert ep.complete and len(ep.actions) == 90 and ep.poses.shape == (91, 4, 4)
    assert ep.actions[:2] == ["turn_left", "look_down"]  # the bootstrap look-around comes first
    assert set(ep.meta["software"]) == {"activesplat", "commit", "modified"}  # which code wrote it
    assert "config_not_used" not in ep.meta  # the run's own simulator: every setting applied
    saved = json.loads((out / "metrics.json").read_text())
    for key in ("completion_ratio_pct", "completion_cm", "completion_cm_uncapped", "path_length_m", "steps",
                "wall_time_s", "timing_ms"):
        assert key in saved
    assert set(TIMING_KEYS) <= set(saved["timing_ms"])
    phases = saved["mapper_phases_ms"]  # the mapper's time split by phase, within the mapper's total
    assert {"render_masks", "densify", "window", "optimize", "prune"} <= set(phases)
    assert 0 < sum(phases.values()) <= saved["timing_ms"]["mapper"]
    assert 0 <= saved["backend_setup_s"] < saved["wall_time_s"] + 60  # kernels loaded before the clock
    # numba compiling inside the loop (none once the kernels are cached on disk), by module, within the wall
    assert 0 <= saved["jit_compile_s"] <= saved["wall_time_s"]
    assert sum(saved["jit_compile_s_by_module"].values()) == pytest.approx(saved["jit_compile_s"])
    assert saved["path_length_m"] == pytest.approx(0.065 * ep.actions.count("move_forward"))
    assert 0 < saved["completion_ratio_pct"] < 100
    # multi-room measures: action shares, rooms of the built-in house, per-point coverage, trajectory figure
    assert sum(saved["action_counts"].values()) == 90
    turns = sum(a != "move_forward" for a in ep.actions)
    assert saved["rotation_pct"] == pytest.approx(100 * turns / 90)
    assert saved["rotation_causes"]["bootstrap"] == 72 and sum(saved["rotation_causes"].values()) == turns
    from activesplat.eval.behaviour import BehaviourConfig, rooms_entered
    from activesplat.sim import load_scene

    house = load_scene("small-0").house
    entered = rooms_entered(house, ep.poses[:, [0, 2], 3], BehaviourConfig().entered_inset_m)
    assert saved["rooms_total"] == house.n_rooms == len(saved["rooms"]["completion"])
    assert saved["rooms"]["entered"] == entered and saved["rooms_entered"] == len(entered)
    n_points = sum(r["points"] for r in saved["rooms"]["completion"].values())
    coverage = np.load(out / "coverage.npz")
    completed = np.unpackbits(coverage["completed"])[: int(coverage["n"])]
    assert int(coverage["n"]) == 4000 and n_points <= 4000
    assert 100 * completed.mean() == pytest.approx(saved["completion_ratio_pct"])
    assert (out / "trajectory.png").stat().st_size > 5000
    # the completion is credited to the actions after which each point was first seen: it adds up
    gain = saved["completion_gain"]
    for group in ("by_cause", "by_action"):
        assert sum(g["completion_pct"] for g in gain[group].values()) == pytest.approx(
            saved["completion_ratio_pct"])
        assert sum(g["actions"] for g in gain[group].values()) == 90
    boot, turn = gain["by_cause"]["bootstrap"], gain["by_action"]["turn"]
    assert boot["actions"] == 72 and boot["completion_pct"] > 0
    assert turn["actions"] == ep.actions.count("turn_left") + ep.actions.count("turn_right")
    # every turn toward a rotation target belongs to a logged stop of that cause with targets
    stops = json.loads((out / "stops.json").read_text())["stops"]
    for cause in ("arrival", "multi_stop"):
        if saved["rotation_causes"].get(cause):
            assert any(s["cause"] == cause and s["targets"] for s in stops), cause
    for s in stops:
        assert 72 <= s["step"] < 90 and len(s["xz"]) == 2
        assert set(s["candidates"]) == {"panorama", "high_loss"}
    # every replan after the look-around is logged: the goal it took and how it was ranked
    replans = json.loads((out / "stops.json").read_text())["replans"]
    assert replans and all(72 <= r["step"] < 90 and r["stage"] in ("local", "global") for r in replans)
    for r in replans:
        assert r["goal"] is None or (r["path_m"] > 0 and r["candidates"] >= r["promising"])
        assert 0 < len(r["ranked"]) <= min(8, r["candidates"])  # why: the best candidates, best first
        assert all(len(c["xz"]) == 2 and c["travel_m"] >= 0 for c in r["ranked"])
    failures = json.loads((out / "stops.json").read_text())["failures"]
    whys = ("no path", "no path, skipped", "blocked")
    assert all(f["why"] in whys and len(f["goal"]) == 2 and isinstance(f["refused"], bool) for f in failures)
    # poses are rigid transforms, camera 1.25 m above the floor
    R = ep.poses[:, :3, :3]
    assert np.allclose(R @ R.transpose(0, 2, 1), np.eye(3), atol=1e-6)


def test_evaluate_recomputes_the_same_completion(episode):
    out, metrics = episode
    m = evaluate_episode(out, write=False)
    assert m["completion_ratio_pct"] == pytest.approx(metrics["completion_ratio_pct"], abs=1e-9)
    assert m["completion_cm"] == pytest.approx(metrics["completion_cm"], rel=1e-9)
    assert m["path_length_m"] == pytest.approx(metrics["path_length_m"])


def test_a_replay_gives_what_each_frame_saw_first(episode):
    out, metrics = episode
    m = replay_episode(read_episode(out), with_gain=True)
    gain = m["gain_by_frame"]
    assert len(gain) == metrics["steps"] + 1 and (gain >= 0).all()
    assert 100.0 * gain.sum() / m["n_gt_points"] == pytest.approx(metrics["completion_ratio_pct"], abs=1e-9)
    by_cause = metrics["completion_gain"]["by_cause"]  # the live run's split adds up the same frames
    assert sum(v["completion_pct"] for v in by_cause.values()) == pytest.approx(100.0 * gain.sum()
                                                                               / m["n_gt_points"])


def test_same_seed_same_actions(episode, tmp_path):
    out, _ = episode
    again = tmp_path / "again"
    run_exploration("small-0", policy="activesplat", steps=90, seed=1, out=again, **TINY)
    assert (again / "actions.txt").read_text() == (out / "actions.txt").read_text()


def test_one_thread_and_two_give_the_same_run(tmp_path, threads):
    """A run does not depend on the CPU thread count (docs/protocol.md §8): the whole loop, with a map past
    the 32768 elements from which torch splits an elementwise op among its threads. Whether an ulp at a
    split changes a run is a matter of luck (this run did not change with torch.sigmoid itself), so
    tests/splat/test_threads.py checks the opacities and a render directly."""
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba's thread pool has one thread on this machine")
    tiny = {**TINY, "sim_config": SimConfig(width=160, height=160)}
    runs = []
    for n in (1, 2):
        threads(n)
        runs.append(tmp_path / f"threads{n}")
        metrics = run_exploration("small-0", policy="activesplat", steps=90, seed=1, out=runs[-1], **tiny)
    assert metrics["n_gaussians"] > 32768
    for name in ("actions.txt", "poses.txt", "gaussians.ply"):
        assert (runs[0] / name).read_bytes() == (runs[1] / name).read_bytes(), name


def test_live_evaluation_on_a_worker_thread_gives_the_same_numbers(episode, tmp_path):
    import numba

    from activesplat.splat.raster import resolve_backend

    out, default = episode  # CoverageConfig.background None: on only where the map is on a GPU
    on_gpu = resolve_backend(TINY.get("backend", "auto")) == "gsplat"
    assert default["evaluation_background"] == (on_gpu and numba.get_num_threads() >= 2)
    runs = {}
    for background in (False, True):
        cfg = {**TINY, "coverage_config": CoverageConfig(n_gt_points=4000, batch_frames=10,
                                                         background=background)}
        runs[background] = run_exploration("small-0", policy="activesplat", steps=90, seed=1,
                                           out=tmp_path / str(background), **cfg)
    m, metrics = runs[True], runs[False]
    assert m["evaluation_background"] and not metrics["evaluation_background"]
    assert (tmp_path / "True" / "actions.txt").read_text() == (out / "actions.txt").read_text()
    for key in ("completion_ratio_pct", "completion_cm", "completion_cm_uncapped", "curve", "rooms",
                "completion_gain"):
        assert m[key] == metrics[key], key
    assert len(m["curve"]) == 10  # the reset (step 0), then a point every 10 actions, the last at step 90
    # each curve point carries the map's size then; the last one is the final map
    assert m["curve"][-1]["n_gaussians"] == m["n_gaussians"] <= m["peak_gaussians"]
    assert 0 < m["curve"][1]["n_gaussians"] and m["peak_rss_mb"] > 100
    assert m["evaluation_worker_ms_per_step"] > 0


def test_the_evaluation_worker_renders_on_its_own_thread(monkeypatch):
    from concurrent.futures import ThreadPoolExecutor

    from activesplat.live_completion import _evaluation_thread
    from activesplat.sim import sensor

    monkeypatch.setattr(sensor.numba, "get_num_threads", lambda: 2)
    n = 4 * sensor.BLOCK_PIXELS

    def blocks():
        calls = []
        sensor._in_blocks(lambda lo, hi: calls.append((lo, hi)), n)
        return sorted(calls)

    with ThreadPoolExecutor(1, initializer=_evaluation_thread) as worker:
        there = worker.submit(blocks).result()
    assert blocks() == [(0, n // 2), (n // 2, n)]  # the calling thread splits a large render over the pool
    assert there == [(0, n)]  # the evaluation worker renders on itself


def test_an_error_on_the_evaluation_worker_reaches_the_caller(tmp_path, monkeypatch):
    from activesplat.sim import Simulator

    def broken(self, pose, width, height):
        raise RuntimeError("ground truth unavailable")

    monkeypatch.setattr(Simulator, "depth", broken)
    cfg = {**TINY, "coverage_config": CoverageConfig(n_gt_points=4000, batch_frames=10, background=True)}
    with pytest.raises(RuntimeError, match="ground truth unavailable"):
        run_exploration("small-0", policy="activesplat", steps=30, seed=1, out=tmp_path / "e", **cfg)


def test_interrupted_run_leaves_a_consistent_partial_episode(tmp_path, monkeypatch):
    from activesplat.planning import activesplat as explorer_mod

    original = explorer_mod.ActiveSplatExplorer.act
    calls = {"n": 0}

    def act(self, obs):
        calls["n"] += 1
        if calls["n"] == 12:
            raise KeyboardInterrupt
        return original(self, obs)

    monkeypatch.setattr(explorer_mod.ActiveSplatExplorer, "act", act)
    from activesplat.errors import Interrupted

    out = tmp_path / "partial"
    with pytest.raises(Interrupted):  # its line printed: the command line adds none, exits with 130
        run_exploration("small-0", policy="activesplat", steps=50, seed=0, out=out, **TINY)
    assert not (out / "metrics.json").exists()
    ep = read_episode(out)
    assert not ep.complete and len(ep.actions) == 11 and len(ep.poses) == 12
    assert (out / "gaussians.ply").exists()
    m = evaluate_episode(out)
    assert m["steps"] == 11 and m["complete"] is False


def _ctrl_c(*args, **kwargs):
    raise KeyboardInterrupt


def test_ctrl_c_while_loading_the_scene_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys):
    from activesplat import sim

    monkeypatch.setattr(sim, "load_scene", _ctrl_c)
    out = tmp_path / "ep"
    code, err = _cli(capsys, "explore", "--scene", "small-0", "--steps", "5", "--no-progress",
                     "--out", str(out))
    assert code == 130  # as a Ctrl-C in the loop
    assert err.strip() == f"interrupted while loading the scene small-0: nothing written to {out}"
    assert not out.exists()


@pytest.mark.filterwarnings("ignore:a budget of")
def test_ctrl_c_in_the_set_up_or_the_first_step_leaves_the_folder_as_it_was(tmp_path, monkeypatch, capsys):
    """Before the first action is recorded nothing is written: no folder, and with --overwrite the episode
    already there is kept; the line says what was interrupted."""
    from activesplat import explore
    from activesplat.errors import Interrupted
    from activesplat.planning import activesplat as explorer_mod

    out = tmp_path / "ep"
    monkeypatch.setattr(explore, "warm_up_kernels", _ctrl_c)  # explore_setup's, as the loop looks it up
    with pytest.raises(Interrupted):
        run_exploration("small-0", steps=5, out=out, **TINY)
    assert "interrupted while loading the mapper's and the planner's kernels" in capsys.readouterr().err
    assert not out.exists()
    monkeypatch.undo()
    run_exploration("small-0", steps=2, out=out, **TINY)  # an episode already there
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    monkeypatch.setattr(explore, "warm_up_kernels", _ctrl_c)
    with pytest.raises(Interrupted):
        run_exploration("small-0", steps=5, out=out, overwrite=True, **TINY)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    monkeypatch.undo()
    monkeypatch.setattr(explorer_mod.ActiveSplatExplorer, "act", _ctrl_c)  # the first step, before its action
    capsys.readouterr()
    with pytest.raises(Interrupted):
        run_exploration("small-0", steps=5, out=tmp_path / "first", **TINY)
    err = capsys.readouterr().err.strip()
    assert err == f"interrupted in the first step, before its action: nothing written to {tmp_path / 'first'}"
    assert not (tmp_path / "first").exists()


def _cli(capsys, *argv):
    code = main(list(argv))
    err = capsys.readouterr().err
    return code, err


@pytest.mark.parametrize("argv, needle", [
    (["explore", "--policy", "nope", "--steps", "5"], "unknown policy 'nope'"),
    (["explore", "--steps", "0"], "--steps must be a positive"),
    (["explore", "--steps", "-3"], "--steps must be a positive"),
    (["explore", "--scene", "/does/not/exist.glb", "--steps", "5"], "/does/not/exist.glb"),
    (["explore", "--scene", "huge-3", "--steps", "5"], "huge-3"),
    (["explore", "--seed", "-1", "--steps", "5"], "--seed must be an integer >= 0"),
])
def test_explore_bad_input_is_one_line_error(capsys, tmp_path, argv, needle):
    out = tmp_path / "never"
    code, err = _cli(capsys, *argv, "--out", str(out))
    assert code == 2
    assert needle in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (out / "metrics.json").exists()


def test_complete_episode_is_not_overwritten(capsys, episode):
    out, _ = episode
    before = (out / "metrics.json").read_text()
    code, err = _cli(capsys, "explore", "--steps", "5", "--out", str(out))
    assert code == 2 and "--overwrite" in err
    assert (out / "metrics.json").read_text() == before


def test_evaluate_on_a_non_episode_folder(capsys, tmp_path):
    code, err = _cli(capsys, "evaluate", str(tmp_path))
    assert code == 2 and "not an episode" in err and len(err.strip().splitlines()) == 1
    code, err = _cli(capsys, "evaluate", str(tmp_path / "missing"))
    assert code == 2 and "not a folder" in err


@pytest.mark.parametrize("policy", ["fbe", "random"])
def test_baseline_policies_run_the_same_harness(tmp_path, policy):
    m = run_exploration("small-0", policy=policy, steps=110, seed=2, out=tmp_path / policy, **TINY)
    ep = read_episode(tmp_path / policy)
    assert ep.complete and len(ep.actions) == 110 and m["policy"] == policy
    # after the bootstrap the policy plans: the agent leaves its start
    assert ep.actions[72:].count("move_forward") > 0


def test_write_npz_reads_back_bit_for_bit_and_leaves_no_temporary(tmp_path):
    """The episode's npz writer (deflate level 1, through a temporary file): ``np.load`` reads every array
    back unchanged, compressed, and only the final file is left."""
    from activesplat.episode import write_npz

    rng = np.random.default_rng(0)
    arrays = {"rgb": rng.integers(0, 255, (3, 8, 8, 3), dtype=np.uint8),
              "depth": np.zeros((3, 64, 64), np.float32), "pose": rng.normal(size=(3, 4, 4)),
              "step": np.arange(3, dtype=np.int64)}
    write_npz(tmp_path / "keyframes.npz", **arrays)
    assert [p.name for p in tmp_path.iterdir()] == ["keyframes.npz"]
    with np.load(tmp_path / "keyframes.npz") as data:
        assert sorted(data.files) == sorted(arrays)
        for name, value in arrays.items():
            assert data[name].dtype == value.dtype
            np.testing.assert_array_equal(data[name], value)
    assert (tmp_path / "keyframes.npz").stat().st_size < arrays["depth"].nbytes // 4  # zeros compress


def test_a_curve_point_counts_the_frame_after_its_action(episode):
    """The point of step k holds the frames up to the one after action k: a replay of the first k actions
    gives its completion, and the last point is the episode's result."""
    from activesplat.episode import Episode

    out, metrics = episode
    curve = metrics["curve"]
    assert [p["step"] for p in curve] == list(range(0, 91, 10))  # the reset, every batch_frames actions
    assert curve[0]["path_length_m"] == 0 and curve[0]["n_gaussians"] == 0 < curve[0]["completion_ratio_pct"]
    assert curve[-1]["completion_ratio_pct"] == pytest.approx(metrics["completion_ratio_pct"], abs=1e-9)
    assert curve[-1]["n_gaussians"] == metrics["n_gaussians"]  # the final map, after the last frame
    ep = read_episode(out)
    for k in (0, 30, 80):
        cut = Episode(ep.dir, ep.meta, ep.actions[:k], ep.poses[: k + 1], False)
        point = next(p for p in curve if p["step"] == k)
        assert replay_episode(cut)["completion_ratio_pct"] == pytest.approx(point["completion_ratio_pct"],
                                                                             abs=1e-9)


def test_the_last_observation_reaches_the_mapper(episode):
    out, _ = episode  # 90 actions: the reset's frame and the 90 after them
    assert json.loads((out / "mapper.json").read_text())["frames"] == 91


def test_a_mesh_given_by_a_relative_path_is_recorded_by_its_absolute_path(tmp_path, monkeypatch):
    import trimesh

    room = tmp_path / "meshes"
    room.mkdir()
    box = trimesh.creation.box(extents=(4.0, 2.5, 4.0))  # a closed room, seen from inside
    box.invert()
    box.apply_translation((2.0, 1.25, 2.0))
    box.export(room / "room.ply")
    monkeypatch.chdir(room)
    out = tmp_path / "ep"
    run_exploration("room.ply", steps=3, seed=0, out=out, **TINY)
    assert json.loads((out / "episode.json").read_text())["scene"] == str(room / "room.ply")
    monkeypatch.chdir(tmp_path)  # elsewhere: the episode still finds its scene
    assert evaluate_episode(out, write=False)["steps"] == 3


def test_figures_of_a_mesh_scene_are_titled_by_its_file_name(tmp_path, monkeypatch):
    """The titles of topdown.png, completion.png and trajectory.png once began with the mesh's whole
    absolute path, which a deep dataset folder pushed out of the figure; they name the file."""
    import trimesh

    from activesplat.viz import plots, trajectory
    from activesplat.workspace import draw

    folder = tmp_path.joinpath(*["a_long_dataset_folder"] * 6)
    folder.mkdir(parents=True)
    box = trimesh.creation.box(extents=(4.0, 2.5, 4.0))
    box.invert()
    box.apply_translation((2.0, 1.25, 2.0))
    box.export(folder / "room.ply")
    titles = {}
    monkeypatch.setattr(draw, "draw_topdown", lambda *a, scene=None, **k: titles.update(topdown=scene))
    monkeypatch.setattr(plots, "draw_completion", lambda *a, title="", **k: titles.update(completion=title))
    monkeypatch.setattr(trajectory, "draw_trajectory",
                        lambda *a, title="", **k: titles.update(trajectory=title))
    run_exploration(str(folder / "room.ply"), steps=3, seed=0, out=tmp_path / "ep", **TINY)
    assert titles["topdown"] == "room.ply"
    assert titles["completion"].startswith("room.ply / ") and titles["trajectory"].startswith("room.ply / ")


def test_backend_gsplat_without_a_gpu_is_one_line_error_and_touches_no_folder(capsys, tmp_path):
    from activesplat.splat.raster import gsplat_available

    if gsplat_available():
        pytest.skip("this machine runs gsplat")
    out = tmp_path / "never"
    code, err = _cli(capsys, "explore", "--steps", "5", "--backend", "gsplat", "--out", str(out))
    assert code == 2 and "needs an NVIDIA GPU and gsplat" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_evaluate_with_a_corrupt_metrics_file_is_one_line_error(capsys, episode, tmp_path):
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(episode[0], out)
    (out / "metrics.json").write_text('{"completion')
    code, err = _cli(capsys, "evaluate", str(out))
    assert code == 2 and "metrics.json is unreadable" in err and len(err.strip().splitlines()) == 1
    assert (out / "metrics.json").read_text() == '{"completion'  # left for the user to look at


def test_ctrl_c_in_evaluate_is_one_line_and_leaves_metrics_json_as_it_was(capsys, episode, tmp_path,
                                                                         monkeypatch):
    """In the replay or in the write of metrics.json: one line saying nothing was written, exit code 130,
    metrics.json as it was and no temporary file beside it."""
    import shutil

    from activesplat.eval import evaluate

    out = shutil.copytree(episode[0], tmp_path / "copy")
    before = (out / "metrics.json").read_bytes()
    line = (f"evaluate interrupted: nothing written ({out / 'metrics.json'} as it was); run the same command "
            f"again")
    monkeypatch.setattr(evaluate, "replay_coverage", _ctrl_c)
    code, err = _cli(capsys, "evaluate", str(out))
    assert (code, err.strip()) == (130, line)
    monkeypatch.setattr(evaluate, "replay_episode", lambda ep: dict.fromkeys(evaluate.COMPLETION_KEYS, 1))
    monkeypatch.setattr("activesplat.episode.os.replace", _ctrl_c)  # its temporary file is written
    code, err = _cli(capsys, "evaluate", str(out))
    assert (code, err.strip()) == (130, line)
    assert (out / "metrics.json").read_bytes() == before
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in episode[0].iterdir())


def test_a_budget_inside_the_first_look_around_is_warned_about(tmp_path):
    with pytest.warns(UserWarning, match="within the first look-around"):
        run_exploration("small-0", steps=4, seed=0, out=tmp_path / "short", **TINY)


def test_summary_says_when_the_timings_include_numba_compiling(tmp_path):
    from activesplat.explore import format_summary

    metrics = {"scene": "small-0", "policy": "activesplat", "seed": 0, "steps": 150, "ms_per_step": 213.0,
               "evaluation_ms_per_step": 26.0, "wall_time_s": 32.0, "backend_setup_s": 18.0,
               "completion_ratio_pct": 63.0, "completion_cm": 12.4, "completion_cm_uncapped": 12.5,
               "path_length_m": 2.2, "n_gaussians": 1, "timing_ms": dict.fromkeys(TIMING_KEYS, 1.0)}
    cold = format_summary({**metrics, "jit_compile_s": 17.2}, tmp_path)
    assert ("(213 ms/step of which 26 live evaluation; 32 s wall, after 18 s loading the kernels; 17 "
            "s of the wall time compiling numba kernels: the first run after an install or a "
            "code change, later runs are faster)") in cold
    for warm in ({**metrics, "jit_compile_s": 0.2}, metrics):  # little or none; an episode from before
        assert "compiling" not in format_summary(warm, tmp_path)


NEW_IN_THE_LOOP = """
import sys

from numba.core.registry import CPUDispatcher

import activesplat.explore as explore
import activesplat.timing as timing
from activesplat.eval.coverage import CoverageConfig
from activesplat.planning.explorer_config import ExplorerConfig
from activesplat.sim import SimConfig


def compiled():
    return {(name, attr, sig) for name, module in list(sys.modules.items()) if name.startswith("activesplat")
            for attr, obj in list(vars(module).items()) if isinstance(obj, CPUDispatcher)
            for sig in obj.signatures}


at_start = set()
enter = timing.JitCompileClock.__enter__


def clock_starts(self):
    at_start.update(compiled())
    return enter(self)


timing.JitCompileClock.__enter__ = clock_starts
explore.run_exploration("small-0", steps=30, seed=1, out=sys.argv[1],
                        sim_config=SimConfig(width=64, height=64),
                        coverage_config=CoverageConfig(n_gt_points=4000, batch_frames=10), progress=False,
                        backend="numba", explorer_config=ExplorerConfig(bootstrap_yaw_deg=90.0))
print(sorted({f"{name}.{attr}" for name, attr, _ in compiled() - at_start}))
"""


def test_no_numba_kernel_is_first_used_inside_the_timed_loop(tmp_path):
    """Every numba kernel (and type signature) the loop runs is loaded, or compiled in the first run after an
    install or a code change, before the clock starts, so that the step times of a fresh process hold no
    compiling: a fresh process (the kernels not in its memory yet, whatever numba's on-disk cache holds)
    lists the kernels that got a new signature inside the loop (without the warm-up: the mapper's, the
    planner's grid DBSCAN, the panorama scoring's coarser map). The look-around is cut to 90 degrees so
    that 30 actions reach the policy's planning."""
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-c", NEW_IN_THE_LOOP, str(tmp_path / "ep")], capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().splitlines()[-1] == "[]"
