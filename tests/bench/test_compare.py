"""`activesplat compare`: runs paired by scene and seed across two roots (or two policies of one), the mean
difference with its paired standard error, identical action logs, sweep ceilings, and bad input."""

import json

import pytest

from activesplat.bench.compare import _signed, at_step, compare_report, pair_runs, read_ceilings
from activesplat.cli import main


def _run(root, scene, policy, seed, ratio, steps=2000, rooms=(80.0, 60.0), actions="move_forward\n"):
    out = root / scene / policy / f"s{seed}"
    out.mkdir(parents=True)
    curve = [{"step": s, "completion_ratio_pct": ratio * s / steps} for s in (0, steps // 2, steps)]
    metrics = {"completion_ratio_pct": ratio, "steps": steps, "rotation_pct": 40.0, "path_length_m": 50.0,
               "rooms_entered": 2, "rooms_total": 2, "curve": curve,
               "rooms": {"completion": {f"room {i + 1}": {"completion_ratio_pct": r}
                                        for i, r in enumerate(rooms)}}}
    (out / "metrics.json").write_text(json.dumps(metrics))
    (out / "actions.txt").write_text(actions)
    return out


def test_runs_pair_by_scene_and_seed_and_the_summary_is_the_paired_difference(tmp_path, capsys):
    base, new = tmp_path / "base", tmp_path / "new"
    for seed, (b, n) in enumerate([(80.0, 82.0), (85.0, 84.0), (90.0, 93.0)]):
        _run(base, "medium-0", "activesplat", seed, b, actions=f"turn_left\n{seed}\n")
        _run(new, "medium-0", "activesplat", seed, n, actions="move_forward\n")
    _run(base, "medium-1", "activesplat", 0, 70.0, actions="a\n")
    _run(new, "medium-1", "activesplat", 0, 70.0, actions="a\n")  # the same run
    _run(new, "medium-2", "activesplat", 0, 75.0)  # NEW only
    pairs, unpaired = pair_runs(base, new)
    assert [(p.scene, p.seed, round(p.delta, 2), p.same_actions) for p in pairs] == [
        ("medium-0", 0, 2.0, False), ("medium-0", 1, -1.0, False), ("medium-0", 2, 3.0, False),
        ("medium-1", 0, 0.0, True)]
    assert unpaired == ["only in NEW: medium-2 seed 0"]
    md = compare_report(pairs, unpaired=unpaired)
    # differences 2, -1, 3, 0: mean 1.00, sample std 1.826, standard error 0.91
    assert ("**+1.00 points** (paired standard error 0.91; 2 higher, 1 lower, 1 the same, 1 of them with "
            "the same actions)") in md
    assert "| medium-0 | 1 | 85.00 → 84.00 | 42.50 → 42.00 |" in md  # completion, then at step 1000
    assert "| medium-1 | 0 | 70.00 → 70.00 |" in md and "| +0.00 | yes |" in md
    assert "Not compared: only in NEW: medium-2 seed 0." in md and "of ceiling" not in md
    assert "room's own points" in md

    # through the command line, and one policy against another in the same root
    _run(base, "medium-0", "no-hp", 0, 78.0)
    argv = ["compare", str(base), str(base), "--base-policy", "no-hp", "--out", str(tmp_path / "c.md")]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "(no-hp)" in out and "**+2.00 points** (paired standard error n/a" in out
    assert (tmp_path / "c.md").read_text() == out


def test_sweep_ceilings_give_the_share_of_the_ceiling_and_the_worst_room_of_its_own(tmp_path):
    base, new, tops = tmp_path / "base", tmp_path / "new", tmp_path / "tops"
    _run(base, "medium-0", "activesplat", 0, 80.0, rooms=(80.0, 60.0))
    _run(new, "medium-0", "activesplat", 0, 88.0, rooms=(90.0, 45.0))
    (tops / "medium-0").mkdir(parents=True)
    (tops / "medium-0" / "sweep.json").write_text(json.dumps({
        "completion_ratio_pct": 88.0, "rooms": {"room 1": {"completion_ratio_pct": 90.0, "points": 1000},
                                                "room 2": {"completion_ratio_pct": 50.0, "points": 1000}}}))
    for root, psnr in ((base, 28.0), (new, 29.5)):  # render-eval's numbers, when both have them
        (root / "medium-0" / "activesplat" / "s0" / "render_metrics.json").write_text(json.dumps({
            "test": {"psnr": psnr, "lpips": 0.25, "depth_l1_cm": 4.0}, "train": {"psnr": psnr + 3}}))
    pairs, _ = pair_runs(base, new)
    ceilings = read_ceilings({"medium-0"}, [new, base, tops])
    md = compare_report(pairs, ceilings)
    # of ceiling 80 / 88 -> 90.9 %, 100 %; at step 1000 40 / 44 of 88; worst room 88.9 / 90 % of its ceiling
    assert "| medium-0 | 0 | 80.00 → 88.00 | 90.9 → 100.0 | 40.00 → 44.00 | 45.5 → 50.0 |" in md
    assert "| 88.9 → 90.0 | 28.00 → 29.50 | 0.250 → 0.250 | 4.00 → 4.00 | 31.00 → 32.50 | +8.00 | yes |" in md
    assert "room's own sweep ceiling" in md
    # the same actions with another completion (other settings) is not the same run
    assert "1 higher, 0 lower, 0 the same);" in md
    assert at_step({"curve": [{"step": 0, "completion_ratio_pct": 1.0}]}, 10) == 1.0
    assert at_step({"curve": []}, 10) is None
    assert (_signed(-0.001), _signed(-1.234), _signed(0.5)) == ("+0.00", "-1.23", "+0.50")  # no "-0.00"


@pytest.mark.parametrize("setup, argv, needle", [
    (lambda t: None, ["compare", "{t}/nope", "{t}/nope"], "no such benchmark folder"),
    (lambda t: _run(t / "a", "small-0", "fbe", 0, 80.0), ["compare", "{t}/a", "{t}/a"],
     "holds no complete run of policy 'activesplat' (policies with complete runs there: fbe)"),
    (lambda t: (_run(t / "a", "small-0", "activesplat", 0, 80.0),
                _run(t / "b", "small-1", "activesplat", 0, 80.0)),
     ["compare", "{t}/a", "{t}/b"], "no scene and seed is in both: BASE has small-0 s0, NEW has small-1 s0"),
    (lambda t: _run(t / "a", "small-0", "activesplat", 0, 80.0),
     ["compare", "{t}/a", "{t}/a", "--out", "{t}/a/small-0/activesplat/s0/metrics.json/c.md"],
     "cannot write --out"),
    (lambda t: (_run(t / "a", "small-0", "activesplat", 0, 80.0),
                (t / "a" / "small-0" / "sweep.json").write_text("[]")),
     ["compare", "{t}/a", "{t}/a"], "sweep.json is not a sweep ceiling (no completion_ratio_pct)"),
    (lambda t: (_run(t / "a", "small-0", "activesplat", 0, 80.0, steps=1000),
                _run(t / "b", "small-0", "activesplat", 0, 80.0)),
     ["compare", "{t}/a", "{t}/b"], "BASE ran 1000 steps and NEW 2000"),
])
def test_bad_input_is_a_one_line_error(tmp_path, capsys, setup, argv, needle):
    setup(tmp_path)
    assert main([a.format(t=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1, err


def test_the_mean_row_averages_both_sides_over_the_same_pairs(tmp_path):
    """A run without render-eval on one side leaves its pair out of the render columns' means."""
    base, new = tmp_path / "base", tmp_path / "new"
    for seed, (psnr_b, psnr_n) in enumerate([(28.0, 29.0), (None, 20.0), (27.0, 30.0)]):
        _run(base, "medium-0", "activesplat", seed, 80.0)
        _run(new, "medium-0", "activesplat", seed, 81.0)
        for root, psnr in ((base, psnr_b), (new, psnr_n)):
            if psnr is not None:
                (root / "medium-0" / "activesplat" / f"s{seed}" / "render_metrics.json").write_text(
                    json.dumps({"test": {"psnr": psnr}}))
    pairs, _ = pair_runs(base, new)
    md = compare_report(pairs)
    assert "| medium-0 | 1 |" in md and "n/a → 20.00" in md  # the row shows what each side has
    # seeds 0 and 2: 27.5 → 29.5 (NEW over all three would be 26.33)
    assert "| 27.50 → 29.50 (2 of 3) |" in md
    assert "| **mean of 3** |  | 80.00 → 81.00 |" in md  # complete columns: no count


def test_settings_that_differ_between_the_roots_are_listed(tmp_path):
    # two roots run with other image sizes and another rule: the completion differences come with them
    base, new = tmp_path / "base", tmp_path / "new"
    for root, width, threshold in ((base, 64, 5.0), (new, 256, 10.0)):
        for seed in (0, 1):
            out = _run(root, "small-0", "activesplat", seed, 50.0 + width / 64)
            config = {"version": 1, "scene": "small-0", "policy": "activesplat", "seed": seed, "steps": 2000,
                      "sim": {"width": width, "height": 64}, "explorer": {"local_score_threshold": threshold}}
            (out / "episode.json").write_text(json.dumps({"config": config}))
    md = compare_report(pair_runs(base, new)[0])
    assert ("Settings that differ (BASE → NEW): explorer.local_score_threshold 5.0 → 10.0; "
            "sim.width 64 → 256.") in md
    same = compare_report(pair_runs(base, base)[0])
    assert "Settings that differ" not in same
