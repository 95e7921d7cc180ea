"""The typed run configuration: --GROUP.FIELD options, --help, one-line errors for bad input, derived robot
geometry, episode.json written and read back by --config (same actions), benchmark overrides."""

import dataclasses
import json
import re
import warnings
from pathlib import Path

import pytest

from activesplat import explore
from activesplat.cli import main
from activesplat.cli_options import parse_command
from activesplat.config import (
    ADDED,
    CONFIG_VERSION,
    DERIVED,
    BenchmarkCommand,
    ExploreCommand,
    RunConfig,
    load_run_config,
    option_paths,
)
from activesplat.errors import InvalidInputError
from activesplat.sim import SimConfig
from activesplat.splat.config import MapperConfig

TINY = ["--sim.width", "48", "--sim.height", "48", "--coverage.n-gt-points", "1000", "--coverage.resolution",
        "32", "--coverage.batch-frames", "5", "--backend", "numba", "--no-progress"]


def _run(capsys, *argv):
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_group_field_options_set_nested_fields():
    cmd = parse_command(ExploreCommand, ["--mapper.pixel-stride", "3", "--explorer.planning.score.w-o", "5",
                                         "--mapper.lr.means", "2e-3", "--policy", "fbe", "--steps", "40",
                                         "--explorer.bootstrap-pitch-deg", "30",
                                         "--mapper.densify-max-depth-m", "5", "--frontier.min-cluster-cells",
                                         "4", "--no-progress"], "activesplat explore")
    run = cmd.run
    assert run.mapper.pixel_stride == 3 and run.mapper.lr.means == 2e-3
    assert run.mapper.densify_max_depth_m == 5.0
    assert run.explorer.planning.score.w_o == 5.0 and run.frontier.min_cluster_cells == 4
    assert run.explorer.bootstrap_pitch_deg == 30.0
    assert (run.policy, run.steps, cmd.progress) == ("fbe", 40, False)
    assert run.sim == SimConfig() and run.mapper.init_opacity == MapperConfig().init_opacity


def test_robot_geometry_is_derived_from_the_sim_settings():
    run = parse_command(ExploreCommand, ["--sim.agent-radius", "0.2", "--sim.turn-deg", "15",
                                         "--sim.forward-step", "0.1", "--sim.sensor-height", "1.1"], "x").run
    ws, ctrl = run.explorer.workspace, run.explorer.controller
    assert (ws.agent_radius, ctrl.turn_deg, ctrl.forward_m) == (0.2, 15, 0.1)
    assert run.explorer.panorama_height_m == 1.1
    # Python callers get the same: the derived fields follow sim whatever the explorer group says
    assert RunConfig(sim=SimConfig(agent_height=1.2)).explorer.workspace.agent_height == 1.2
    assert not any(p in option_paths() for p in DERIVED)


def test_help_documents_each_field_with_its_default_and_source(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "120")
    with pytest.raises(SystemExit) as exc:
        main(["explore", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    assert "--mapper.pixel-stride" in text and "one Gaussian per stride x stride pixels" in text
    assert "--explorer.workspace.agent-radius" not in text and "--sim.agent-radius" in text
    for legacy in ("--scene", "--steps", "--policy", "--seed", "--out", "--overwrite", "--backend",
                   "--viewer", "--viewer-port", "--max-splats", "--z-up", "--no-progress", "--config"):
        assert re.search(rf"^\s+(--[\w-]+, )?{legacy}\b", text, re.M), legacy
    # every configuration field: a doc with its default and where the value comes from
    blocks, current = {}, None
    for line in text.splitlines():
        m = re.match(r"^\s{1,3}(--[a-z][\w.-]*)", line)
        if m:
            current = m.group(1)
            blocks[current] = line
        elif current and re.match(r"^\s{5,}\S", line):
            blocks[current] += " " + line.strip()
        else:
            current = None
    fields = {"--" + p.replace("_", "-") for p in option_paths() if "." in p}
    assert fields <= set(blocks), sorted(fields - set(blocks))[:5]
    source = re.compile(r"paper|release|ours|our choice|project|3DGS|2DGS|SplaTAM|Habitat|eq\.|"
                        r"protocol|Yamauchi", re.I)
    undocumented = [f for f in sorted(fields) if "(default:" not in blocks[f] or not source.search(blocks[f])]
    assert not undocumented, undocumented


def _help(capsys, *argv) -> str:
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--help"])
    assert exc.value.code == 0
    return capsys.readouterr().out


def _needless_breaks(text: str) -> list[str]:
    """Help lines broken before a word that would have fitted on them: a docstring's line break kept in the
    help. Lines are padded to the help's width, with a margin of one space (inside tyro's box, if drawn)."""
    rows = [line[1:-1] if line.startswith("│") and line.endswith("│") else line for line in text.splitlines()]
    bad = []
    for line, after in zip(rows, rows[1:], strict=False):
        if not (line.startswith(" " * 6) and after.startswith(" " * 6) and line.strip() and after.strip()):
            continue  # not two lines of one option's help
        if len(line.rstrip()) + 1 + len(after.split()[0]) <= len(line) - 1:
            bad.append(f"{line.strip()} / {after.strip()}")
    return bad


def _flat(text: str) -> str:
    return " ".join(text.replace("│", " ").split())


def test_help_reads_as_sentences_with_one_default(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    text = _help(capsys, "explore")
    assert not _needless_breaks(text), _needless_breaks(text)[:3]
    flat = _flat(text)
    assert "or a mesh file (.glb/.gltf/.ply/.obj). (default: small-0)" in flat
    assert "--out {None}|PATH Episode folder (default: runs/SCENE-POLICY-sSEED). --overwrite" in flat
    assert "--config {None}|PATH Rerun the configuration" in flat and "override it. (default: None)" in flat
    assert "coarse refresh (project;" in flat and "--- coarse" not in flat  # section comments lose dashes
    text = _help(capsys, "refine")
    assert not _needless_breaks(text), _needless_breaks(text)[:3]
    assert "3DGS and 2DGS train 30000). (default: 2000)" in _flat(text)
    kept = "\n".join(line.ljust(40) for line in ("        a line", "        broken (here)"))
    assert _needless_breaks(kept) == ["a line / broken (here)"]  # the check finds a kept break


@pytest.mark.parametrize("argv, needle", [
    (["--mapper.pixel-strid", "3"], "--mapper.pixel-strid (did you mean --mapper.pixel-stride?)"),
    (["--mapper.pixel-stride", "two"], "--mapper.pixel-stride expects INT"),
    (["--mapper.pixel-stride", "0"], "--mapper.pixel-stride must be >= 1, got 0"),
    (["--mapper.pixel-stride", "-1"], "--mapper.pixel-stride must be >= 1, got -1"),
    (["--mapper.refresh-coarse-factor", "-2"], "--mapper.refresh-coarse-factor must be > 1"),
    (["--explorer.bootstrap-pitch-deg", "200"], "--explorer.bootstrap-pitch-deg must be in [0, 90] degrees"),
    (["--explorer.bootstrap-pitch-deg", "-10"], "--explorer.bootstrap-pitch-deg must be in [0, 90] degrees"),
    (["--explorer.controller.max-pitch-deg", "200"], "--explorer.controller.max-pitch-deg must be in [0, 90"),
    (["--explorer.planning.high-loss.drop-within-deg", "270"], "drop-within-deg must be in [0, 180] degrees"),
    (["--explorer.planning.rotation.min-offset-deg", "-5"], "min-offset-deg must be in [0, 180] degrees"),
    (["--explorer.planning.panorama.back-face-margin-deg", "90"], "must be in [0, 90) degrees"),
    (["--sim.width", "-5"], "--sim.width must be > 0"),
    (["--mapper.init-opacity", "1.5"], "--mapper.init-opacity must be in (0, 1)"),
    (["--explorer.planning.score.preset", "best"], "--explorer.planning.score.preset: unknown value 'best'"),
    (["--explorer.workspace.agent-radius", "0.3"], "set --sim.agent-radius"),
    (["--sim.light-dir", "1", "2"], "--sim.light-dir: expects 3 value(s)"),
    (["--steps", "0"], "--steps must be a positive"),
    (["--policy", "nope"], "unknown policy 'nope'"),
])
def test_bad_options_are_one_line_errors_naming_the_field(capsys, tmp_path, argv, needle):
    code, _, err = _run(capsys, "explore", *argv, "--out", str(tmp_path / "never"))
    assert code == 2 and needle in err, err
    assert err.startswith("activesplat: error: ") and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err and not (tmp_path / "never").exists()


def _write_config(tmp_path, edit) -> str:
    data = RunConfig(steps=5).to_dict()
    edit(data)
    path = tmp_path / "episode.json"
    path.write_text(json.dumps({"scene": "small-0", "start_pose": [], "config": data}))
    return str(path)


@pytest.mark.parametrize("edit, needle", [
    (lambda d: d.update(version=CONFIG_VERSION + 1), f"config version {CONFIG_VERSION + 1}"),
    (lambda d: d.pop("version"), "config version None"),
    (lambda d: d["mapper"].update(pixel_strides=2), "unknown key mapper.pixel_strides"),
    (lambda d: d["mapper"]["lr"].update(means="fast"), "mapper.lr.means must be a number"),
    (lambda d: d["mapper"].update(pixel_stride=0), "mapper.pixel_stride must be >= 1"),
    (lambda d: d["explorer"]["workspace"].update(agent_radius=0.3),
     "explorer.workspace.agent_radius is derived"),
    (lambda d: d.update(policy="nope"), "policy must be one of"),
])
def test_bad_config_files_are_one_line_errors_naming_the_key(capsys, tmp_path, edit, needle):
    path = _write_config(tmp_path, edit)
    code, _, err = _run(capsys, "explore", "--config", path, "--out", str(tmp_path / "never"))
    assert code == 2 and needle in err and path in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_config_dict_round_trip_keeps_every_field():
    run = RunConfig(scene="small-2", policy="no-hp", seed=4, steps=77, sim=SimConfig(agent_radius=0.15),
                    mapper=MapperConfig(pixel_stride=3, densify_max_depth_m=5.0))
    again = RunConfig.from_dict(json.loads(json.dumps(run.to_dict())))
    assert again == run and again.explorer.workspace.agent_radius == 0.15
    with pytest.raises(InvalidInputError, match="scene must be a string"):
        RunConfig.from_dict({**run.to_dict(), "scene": 3})


def test_config_rerun_of_an_episode_takes_the_same_actions(capsys, tmp_path):
    first, again, other = tmp_path / "first", tmp_path / "again", tmp_path / "other"
    code, out, err = _run(capsys, "explore", "--steps", "10", "--seed", "3", "--policy", "random",
                          "--explorer.bootstrap-yaw-deg", "20", "--mapper.pixel-stride", "3",
                          "--out", str(first), *TINY)
    assert code == 0, err
    recorded = load_run_config(first)
    assert (recorded.steps, recorded.seed, recorded.policy) == (10, 3, "random")
    assert recorded.explorer.bootstrap_yaw_deg == 20.0 and recorded.mapper.pixel_stride == 3
    assert recorded.sim.width == 48 and recorded.backend == "numba"

    code, _, err = _run(capsys, "explore", "--config", str(first / "episode.json"), "--out", str(again),
                        "--no-progress")
    assert code == 0, err
    assert (again / "actions.txt").read_text() == (first / "actions.txt").read_text()
    assert load_run_config(again) == recorded

    # options override the file
    code, _, err = _run(capsys, "explore", "--config", str(first), "--steps", "4", "--coverage.n-gt-points",
                        "800", "--out", str(other), "--no-progress")
    assert code == 0, err
    changed = load_run_config(other)
    coverage = dataclasses.replace(recorded.coverage, n_gt_points=800)
    assert changed == recorded.replace(steps=4, coverage=coverage)
    assert len((other / "actions.txt").read_text().split()) == 4


def test_benchmark_overrides_reach_every_run(capsys, tmp_path, monkeypatch):
    seen = []

    def fake(scene, policy, steps, seed, out, overwrite, **options):
        seen.append((policy, seed, options["config"]))
        out.mkdir(parents=True, exist_ok=True)
        raise RuntimeError("not run")

    monkeypatch.setattr(explore, "run_exploration", fake)
    code, _, err = _run(capsys, "benchmark", "--scenes", "small-0", "--policies", "activesplat", "fbe",
                        "--trials", "2", "--steps", "5", "--root", str(tmp_path),
                        "--mapper.pixel-stride", "3", "--frontier.min-cluster-cells", "4",
                        "--sim.agent-radius", "0.12")
    assert code == 1  # every run failed (the stand-in raises)
    assert [(p, s) for p, s, _ in seen] == [("activesplat", 0), ("activesplat", 1), ("fbe", 0), ("fbe", 1)]
    for _, _, config in seen:
        assert config.mapper.pixel_stride == 3 and config.frontier.min_cluster_cells == 4
        assert config.explorer.workspace.agent_radius == 0.12


def test_benchmark_sets_scene_policy_seed_and_steps_itself(capsys, tmp_path):
    cmd = parse_command(BenchmarkCommand, ["--steps", "5", "--sim.width", "64"], "activesplat benchmark",
                        own=("scene", "policy", "seed", "steps"))
    assert cmd.steps == 5 and cmd.run.sim.width == 64
    code, _, err = _run(capsys, "benchmark", "--scene", "small-1", "--root", str(tmp_path / "r"))
    assert code == 2 and "unknown option --scene" in err and len(err.strip().splitlines()) == 1


def test_benchmark_refuses_a_root_run_with_other_settings(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(explore, "run_exploration", lambda *a, **k: pytest.fail("nothing should run"))
    out = tmp_path / "small-0" / "fbe" / "s0"
    out.mkdir(parents=True)
    config = RunConfig(scene="small-0", policy="fbe", steps=5, mapper=MapperConfig(pixel_stride=3))
    (out / "episode.json").write_text(json.dumps({"config": config.to_dict()}))
    (out / "metrics.json").write_text(json.dumps({"steps": 5}))
    argv = ["benchmark", "--scenes", "small-0", "--policies", "fbe", "--steps", "5", "--root", str(tmp_path),
            "--no-ceiling"]
    code, _, err = _run(capsys, *argv, "--mapper.pixel-stride", "2")
    assert code == 2 and "was run with mapper.pixel_stride = 3 but this benchmark asks for 2" in err, err
    assert len(err.strip().splitlines()) == 1
    code, out_text, err = _run(capsys, *argv, "--mapper.pixel-stride", "3")  # the same settings: complete
    assert "1 already complete, 0 to run" in out_text, (out_text, err)
    # the refine group takes no part in a benchmark's runs: another refine setting is the same run
    code, out_text, err = _run(capsys, *argv, "--mapper.pixel-stride", "3", "--refine.lambda-dssim", "0.3")
    assert "1 already complete, 0 to run" in out_text, (out_text, err)
    recorded = config.to_dict()  # a run older than an option: the option at its default is the same run
    del recorded["mapper"]["init_capped_fill"]
    (out / "episode.json").write_text(json.dumps({"config": recorded}))
    code, out_text, err = _run(capsys, *argv, "--mapper.pixel-stride", "3")
    assert "1 already complete, 0 to run" in out_text, (out_text, err)
    code, _, err = _run(capsys, *argv, "--mapper.pixel-stride", "3", "--mapper.init-capped-fill")
    assert code == 2 and ("was run before mapper.init_capped_fill existed (default False) but this "
                          "benchmark asks for True") in err, err
    # a run older than a field whose default changed what runs do (ADDED) ran as the old value: not the
    # same run as today's default, the same as the old value asked for
    del recorded["explorer"]["leave_when_cut_off"]
    (out / "episode.json").write_text(json.dumps({"config": recorded}))
    code, _, err = _run(capsys, *argv, "--mapper.pixel-stride", "3")
    assert code == 2 and ("was run before explorer.leave_when_cut_off existed (it ran as False) but this "
                          "benchmark asks for True") in err, err
    code, out_text, err = _run(capsys, *argv, "--mapper.pixel-stride", "3",
                               "--explorer.no-leave-when-cut-off")
    assert "1 already complete, 0 to run" in out_text, (out_text, err)


def test_refine_takes_the_recorded_settings_then_the_options(capsys, tmp_path, monkeypatch):
    import activesplat.refine as refine_module

    seen = []
    monkeypatch.setattr(refine_module, "refine_from_command", lambda cmd: seen.append(cmd) or 0)
    ep = tmp_path / "ep"
    ep.mkdir()
    run = RunConfig(steps=5, refine=dataclasses.replace(RunConfig().refine, lambda_dssim=0.3))
    (ep / "episode.json").write_text(json.dumps({"start_pose": [], "config": run.to_dict()}))
    assert main(["refine", str(ep), "--refine.percent-dense", "0.02", "--iters", "7"]) == 0
    cmd = seen[-1]
    assert (cmd.refine.lambda_dssim, cmd.refine.percent_dense, cmd.iters) == (0.3, 0.02, 7)
    (ep / "episode.json").write_text(json.dumps({"start_pose": [], "config": {}}))  # an older episode
    assert main(["refine", str(ep)]) == 0 and seen[-1].refine == RunConfig().refine
    code, _, err = _run(capsys, "refine", str(ep), "--refine.lambda-dssim", "2")
    assert code == 2 and "--refine.lambda-dssim must be in [0, 1]" in err and len(err.splitlines()) == 1


# --------------------------------------------------------------------------- files of older versions
def _old_episode(tmp_path, edit) -> Path:
    """An episode.json as an older version wrote it: today's record edited by ``edit``."""
    data = RunConfig(steps=5, refine=dataclasses.replace(RunConfig().refine, lambda_dssim=0.3)).to_dict()
    edit(data)
    ep = tmp_path / "old"
    ep.mkdir(exist_ok=True)
    (ep / "episode.json").write_text(json.dumps({"scene": "small-0", "start_pose": [], "config": data}))
    return ep


def test_a_removed_field_at_its_off_value_reads_and_any_other_value_is_refused(capsys, tmp_path):
    ep = _old_episode(tmp_path, lambda d: (d["mapper"].update(area_budget_slack=None, area_budget_cell_m=0.4),
                                           d["explorer"]["planning"]["score"].update(w_entry=0.0)))
    assert load_run_config(ep) == RunConfig(steps=5, refine=load_run_config(ep).refine)
    ep = _old_episode(tmp_path, lambda d: d["mapper"].update(
        densify_median_depth=False, densify_represented_tol=None, densify_represented_px=1,
        densify_represented_age=300, init_max_elongation=1.0, init_slant_fill=1, cull_occluded_masks=False))
    assert load_run_config(ep) == RunConfig(steps=5, refine=load_run_config(ep).refine)
    ep = _old_episode(tmp_path, lambda d: d["mapper"].update(init_slant_fill=4))
    code, _, err = _run(capsys, "explore", "--config", str(ep), "--out", str(tmp_path / "never"))
    assert code == 2 and "mapper.init_slant_fill was removed (2026-12-05" in err and "= 4" in err, err
    ep = _old_episode(tmp_path, lambda d: d["explorer"].update(front_faces_scores_after=0.5))
    code, _, err = _run(capsys, "explore", "--config", str(ep), "--out", str(tmp_path / "never"))
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "explorer.front_faces_scores_after was removed" in err and "0.5" in err
    assert not (tmp_path / "never").exists()


def test_options_measured_off_and_removed_read_at_their_off_value_and_refused_at_another(capsys, tmp_path):
    # an episode.json of the commit before their removal holds every one of them at its off value
    def off(d):
        e = d["explorer"]
        e.update(global_tour=False, route_memory_m=None, route_min_info=20.0, collision_fail_after=2,
                 unsampled_views=0, unsampled_voxel_m=0.1, flat_until_step=None)
        e["planning"]["score"].update(w_q=0.0, quality_in_local=True, inv_reference=None,
                                      vol_reference_m3=None)
        e["planning"]["panorama"].update(front_faces_scores=False, scores_back_face_seen=0.0)
        e["planning"]["high_loss"].update(forget_resolved=False, resolved_tolerance_m=0.3)
    ep = _old_episode(tmp_path, off)
    assert load_run_config(ep) == RunConfig(steps=5, refine=load_run_config(ep).refine)
    ep = _old_episode(tmp_path, lambda d: d["explorer"].update(global_tour=True))
    code, _, err = _run(capsys, "explore", "--config", str(ep), "--out", str(tmp_path / "never"))
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert ("explorer.global_tour was removed (2026-12-05, measured off and removed; last in commit "
            "9d426c9)") in err


@pytest.mark.parametrize("argv, flag", [
    (["--explorer.global-tour"], "--explorer.global-tour"),
    (["--explorer.no-global-tour"], "--explorer.no-global-tour"),
    (["--explorer.route-memory-m", "2"], "--explorer.route-memory-m"),
    (["--explorer.planning.score.w-q=10"], "--explorer.planning.score.w-q"),
])
def test_a_removed_option_on_the_command_line_says_when_it_was_removed(capsys, tmp_path, argv, flag):
    code, _, err = _run(capsys, "explore", *argv, "--out", str(tmp_path / "never"))
    assert code == 2 and err.strip() == (f"activesplat: error: {flag} was removed (2026-12-05, measured off "
                                         f"and removed; last in commit 9d426c9)"), err
    code, _, err = _run(capsys, "benchmark", *argv, "--root", str(tmp_path / "never"))
    assert code == 2 and f"{flag} was removed" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "never").exists()


def test_an_old_episode_reruns_with_the_values_of_its_version_for_later_fields(tmp_path):
    def old(d):
        del d["explorer"]["leave_when_cut_off"], d["explorer"]["way_back_m"], d["sim"]["texture_filter"]
    ep = _old_episode(tmp_path, old)
    with pytest.warns(UserWarning, match="way_back_m=null, explorer.leave_when_cut_off=false"):
        run = load_run_config(ep)
    assert (run.explorer.leave_when_cut_off, run.explorer.way_back_m, run.sim.texture_filter) == (
        False, None, "nearest")
    with pytest.warns(UserWarning):  # the options still override the file
        cmd = parse_command(ExploreCommand, ["--config", str(ep), "--explorer.leave-when-cut-off"], "t")
    assert cmd.run.explorer.leave_when_cut_off and cmd.run.explorer.way_back_m is None
    # a config file that is not an episode's record: what it leaves out takes today's defaults
    partial = tmp_path / "partial.json"
    partial.write_text(json.dumps({"version": CONFIG_VERSION, "seed": 2}))
    assert load_run_config(partial) == RunConfig(seed=2)


def test_an_old_episode_is_evaluated_against_the_camera_it_recorded_with(tmp_path):
    """evaluate / render-eval rebuild the simulator of episode.json: a field younger than the file takes the
    value its version ran with (texture_filter "nearest" before the area filter), not today's default."""
    from activesplat.eval.evaluate import recorded_sim_config

    ep = _old_episode(tmp_path, lambda d: d["sim"].pop("texture_filter"))
    meta = json.loads((ep / "episode.json").read_text())
    with pytest.warns(UserWarning, match="sim.texture_filter=\"nearest\""):
        assert recorded_sim_config(meta, source=ep).texture_filter == "nearest"
    with pytest.warns(UserWarning):  # overrides still win
        assert recorded_sim_config(meta, {"texture_filter": "area"}, ep).texture_filter == "area"
    meta["config"]["sim"]["texture_filter"] = "area"  # a file that records the field: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert recorded_sim_config(meta, source=ep).texture_filter == "area"
    assert recorded_sim_config({}, source=ep) == SimConfig()  # no recorded config: today's defaults


FIRST_RECORDED = Path(__file__).with_name("first_recorded_config.json")
"""The configuration an episode.json of the first version that recorded one (2026-11-23) holds: its defaults,
with a 1000-step budget."""


def test_the_first_recorded_configuration_reads_as_the_run_it_recorded(tmp_path):
    """Every field added since reads as that version ran: a field added with its new rule on, or added off
    and turned on later, is in `ADDED` with its off value. Several were missing and read as today's
    defaults: the mapper's flat Gaussians, back faces, depth edges, colour detail and occlusion culling,
    and the explorer's multi-stop spacing, detour, near nodes, retries, grown floor and high-loss cap."""
    ep = tmp_path / "first"
    ep.mkdir()
    config = json.loads(FIRST_RECORDED.read_text())
    (ep / "episode.json").write_text(json.dumps({"scene": "small-0", "start_pose": [], "config": config}))
    with pytest.warns(UserWarning, match=f"written before {len(ADDED)} field"):
        run = load_run_config(ep)
    for dotted, old in ADDED.items():
        value = run
        for name in dotted.split("."):
            value = getattr(value, name)
        assert value == old, dotted
    m, ex = run.mapper, run.explorer
    assert (m.init_normal_scale, m.densify_front_faces_only, m.edge_band_px, m.detail_colour_range,
            m.cull_occluded_margin_m, m.planar_depth) == (1.0, False, 0, None, None, False)
    assert (ex.multi_stop_spacing_m, ex.detour_m, ex.local_near_m, ex.retry_unreachable, ex.neck_margin_m,
            ex.planning.high_loss.max_targets) == (0.0, None, None, False, None, 0)
    # that version's mapper.json holds the same mapper settings, and reads as the same map's
    assert MapperConfig.from_dict(config["mapper"]) == m


def test_refine_keeps_an_old_episodes_settings_when_another_group_cannot_be_read(capsys, tmp_path,
                                                                                 monkeypatch):
    import activesplat.refine as refine_module

    seen = []
    monkeypatch.setattr(refine_module, "refine_from_command", lambda cmd: seen.append(cmd) or 0)
    ep = _old_episode(tmp_path, lambda d: d["explorer"].update(multi_stop_new_m=1.0))
    assert main(["refine", str(ep)]) == 0 and seen[-1].refine.lambda_dssim == 0.3
    ep = _old_episode(tmp_path, lambda d: d["refine"].update(lambda_dssim="x"))
    code, _, err = _run(capsys, "refine", str(ep))
    assert code == 2 and "refine.lambda_dssim must be a number" in err and len(err.strip().splitlines()) == 1


def test_refine_reads_an_old_episodes_refine_fields_added_since_as_its_version_ran(capsys, tmp_path,
                                                                                  monkeypatch):
    """`activesplat refine` starts from the recorded ``refine`` group: a field added to it later reads as
    the episode's version ran (`ADDED`), with the warning `load_run_config` gives, not as today's default."""
    import activesplat.config as config_module
    import activesplat.refine as refine_module

    seen = []
    monkeypatch.setattr(refine_module, "refine_from_command", lambda cmd: seen.append(cmd) or 0)
    monkeypatch.setitem(config_module.ADDED, "refine.percent_dense", 0.03)
    ep = _old_episode(tmp_path, lambda d: d["refine"].pop("percent_dense"))
    with pytest.warns(UserWarning, match=r"refine\.percent_dense=0\.03"):
        assert main(["refine", str(ep)]) == 0
    assert (seen[-1].refine.percent_dense, seen[-1].refine.lambda_dssim) == (0.03, 0.3)
    with pytest.warns(UserWarning):  # the options still override it
        assert main(["refine", str(ep), "--refine.percent-dense", "0.02"]) == 0
    assert seen[-1].refine.percent_dense == 0.02
    ep = _old_episode(tmp_path, lambda d: None)  # recorded with the field: its value, no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["refine", str(ep)]) == 0
    assert seen[-1].refine.percent_dense == RunConfig().refine.percent_dense


def test_an_episode_recorded_before_refine_planar_depth_refines_with_centre_depth(tmp_path, monkeypatch):
    """Refinement rendered centre depth before ``refine.planar_depth`` existed, also for a map trained with
    planar depth; today's default (None: as the map was trained) would refine such a map with planar depth."""
    import activesplat.refine as refine_module

    seen = []
    monkeypatch.setattr(refine_module, "refine_from_command", lambda cmd: seen.append(cmd) or 0)
    ep = _old_episode(tmp_path, lambda d: (d["refine"].pop("planar_depth"),  # a planar-depth map
                                           d["mapper"].update(planar_depth=True)))
    with pytest.warns(UserWarning, match="refine.planar_depth=false"):
        assert main(["refine", str(ep)]) == 0
    assert seen[-1].refine.planar_depth is False
    with pytest.warns(UserWarning):
        assert load_run_config(ep).refine.planar_depth is False
    assert RunConfig().refine.planar_depth is None  # a new episode records None and keeps it
    assert main(["refine", str(_old_episode(tmp_path, lambda d: None))]) == 0
    assert seen[-1].refine.planar_depth is None


def test_an_old_maps_settings_with_a_removed_field_still_read():
    d = dataclasses.asdict(MapperConfig())
    d.update(area_budget_slack=0.2, area_budget_cell_m=0.2, init_slant_fill=4, densify_represented_tol=0.02)
    del d["planar_depth"]
    assert MapperConfig.from_dict(d) == MapperConfig(planar_depth=False)
