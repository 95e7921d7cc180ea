"""The error budget of a map (eval/render_error.py): pixel classes, the halving gain, the observed test,
on the hand-made look-around episodes of tests/eval/conftest.py."""

import math

import numpy as np
import pytest

from activesplat.errors import EpisodeError
from activesplat.eval.render_error import (
    PIXEL_CLASSES,
    ErrorBudgetConfig,
    classify_pixels,
    error_budget,
    observation_angle,
    squared_error,
    view_budget,
)
from activesplat.geometry import intrinsics

FAST = dict(n_train=3, n_test=4, progress=False, backend="numba")


def test_view_budget_halving_gain():
    gt = np.zeros((4, 4, 3))
    rgb = np.zeros((4, 4, 3))
    rgb[0, 0] = 0.5  # all the error in one pixel of class 0
    rgb[3, 3] = 0.5  # as much in one pixel of class 1
    label = np.full((4, 4), PIXEL_CLASSES.index("rest"))
    label[0, 0], label[3, 3] = 0, 1
    v = view_budget(squared_error(rgb, gt), label)
    assert v["psnr"] == pytest.approx(-10 * math.log10(2 * 0.25 / 16))
    assert v["squared_error"][PIXEL_CLASSES[0]] == pytest.approx(0.25)
    # half the error in class 0: halving it removes a quarter of the view's error
    assert v["psnr_if_halved"][PIXEL_CLASSES[0]] - v["psnr"] == pytest.approx(-10 * math.log10(0.75))
    assert v["psnr_if_halved"]["rest"] == pytest.approx(v["psnr"])  # no error there, no gain
    assert sum(v["pixels"].values()) == 16
    assert "depth_l1_cm" not in v


def test_view_budget_depth_parts_add_up_to_the_depth_l1():
    from activesplat.eval.render_error import depth_error

    gt_depth = np.full((4, 4), 2.0)
    gt_depth[3] = 0.0  # no ground truth on the last row: left out, as render-eval leaves it out
    depth = gt_depth.copy()
    depth[0, 0] = 0.0  # a hole: 2 m off
    depth[1, 1] = 2.1  # 10 cm off
    depth[3, 3] = 5.0  # no ground truth there: not counted
    label = np.full((4, 4), PIXEL_CLASSES.index("rest"))
    label[0, 0] = PIXEL_CLASSES.index("hole_unobserved")
    v = view_budget(np.zeros((4, 4)), label, depth_err=depth_error(depth, gt_depth))
    assert v["depth_l1_cm"] == pytest.approx(100.0 * 2.1 / 12)
    assert v["depth_l1_part_cm"]["hole_unobserved"] == pytest.approx(100.0 * 2.0 / 12)
    assert v["depth_l1_part_cm"]["rest"] == pytest.approx(100.0 * 0.1 / 12)
    assert sum(v["depth_l1_part_cm"].values()) == pytest.approx(v["depth_l1_cm"])


def test_observation_angle_checks_image_front_and_depth():
    K = intrinsics(8, 8, 90.0)
    pose = np.eye(4)  # camera at the origin looking along +z
    points = np.array([[0.0, 0.0, 2.0],     # seen: on the surface at depth 2
                       [0.0, 0.0, 3.0],     # behind the surface
                       [0.0, 0.0, -2.0],    # behind the camera
                       [10.0, 0.0, 2.0]])   # outside the image
    angle = observation_angle(points, [pose], lambda p: np.full((8, 8), 2.0), K, 8, 8, 0.05)
    assert angle.tolist() == [0.0, math.inf, math.inf, math.inf]
    assert observation_angle(points[:0], [pose], None, K, 8, 8, 0.05).shape == (0,)


def test_observation_angle_is_the_least_oblique_sighting():
    """A point on a floor (normal +y, either sign) seen from straight ahead and from above: the angle of the
    less oblique camera; a pose that misses it changes nothing."""
    K = intrinsics(8, 8, 90.0)
    point, normal = np.array([[0.0, 0.0, 2.0]]), np.array([[0.0, -1.0, 0.0]])
    level = np.eye(4)  # the point straight ahead, on the optical axis: 90 deg off the floor's normal
    above = np.eye(4)  # 2 m off the floor and 2 m back, looking at the point 45 deg off its normal
    c, sn = math.cos(math.radians(45)), math.sin(math.radians(45))
    above[:3, :3] = np.array([[1, 0, 0], [0, c, sn], [0, -sn, c]])  # its optical axis through the point
    above[:3, 3] = [0.0, -2.0, 0.0]  # 2 m off the floor's plane, 2 m back
    dist = math.hypot(2.0, 2.0)

    def depth(pose):
        return np.full((8, 8), 2.0 if pose is level else dist)

    one = observation_angle(point, [level], depth, K, 8, 8, 0.05, normal)
    assert one[0] == pytest.approx(90.0)
    both = observation_angle(point, [level, above], depth, K, 8, 8, 0.05, -normal)
    assert both[0] == pytest.approx(45.0)
    # a point without a normal counts as seen head-on
    assert observation_angle(point, [level], depth, K, 8, 8, 0.05, np.zeros((1, 3)))[0] == 0.0
    # with the enough-angle at 90 the first sighting settles it
    assert observation_angle(point, [level, above], depth, K, 8, 8, 0.05, normal, 90.0)[0] == \
        pytest.approx(90.0)


def test_classify_pixels_order():
    """Holes come first (split by the observed test), then translucency, depth errors, edges, floor."""
    cfg = ErrorBudgetConfig()
    H = W = 6
    gt_depth = np.full((H, W), 2.0)
    points = np.zeros((H, W, 3))
    points[..., 0], points[..., 2] = np.meshgrid(np.arange(W) * 0.1, np.arange(H) * 0.1)  # a floor at y 0
    alpha = np.ones((H, W))
    depth = gt_depth.copy()  # sum w z with opacity 1
    alpha[0, 0] = 0.1
    alpha[0, 1] = 0.1
    alpha[1, 0] = 0.8
    depth[1, 0] = 0.8 * 2.0
    depth[2, 2] = 1.5  # in front by 0.5 m
    depth[3, 3] = 2.5  # behind by 0.5 m
    alpha[0, 2] = 0.1
    # (0, 0) never seen, (0, 1) seen 30 deg off its normal, (0, 2) only 80 deg off it
    seen_at = {0.0: math.inf, 0.1: 30.0, 0.2: 80.0}
    observed = lambda pts, nrm: np.array([seen_at[round(p[0], 1)] for p in pts])  # noqa: E731
    label = classify_pixels(alpha, depth, gt_depth, points, np.array([0.3, 1.25, 0.3]), 0.0, observed, cfg)
    name = np.asarray(PIXEL_CLASSES)[label]
    assert name[0, 0] == "hole_unobserved" and name[0, 1] == "hole_observed" and name[0, 2] == "hole_grazing"
    assert name[1, 0] == "translucent"
    assert name[2, 2] == "depth_front" and name[3, 3] == "depth_behind"
    assert name[4, 4] == "floor"


def test_budget_of_a_full_and_a_quarter_look_around(episode, quarter_episode):
    full = error_budget(episode[0], **FAST)
    quarter = error_budget(quarter_episode[0], **FAST)
    for result in (full, quarter):
        for split in ("train", "test"):
            classes = result[split]["classes"]
            assert set(classes) == set(PIXEL_CLASSES)
            assert sum(c["pixels_pct"] for c in classes.values()) == pytest.approx(100.0)
            assert sum(c["error_pct"] for c in classes.values()) == pytest.approx(100.0)
            assert all(0.0 <= c["gain_db"] <= 10 * math.log10(2) + 1e-9 for c in classes.values())
            parts = sum(c["depth_l1_cm"] for c in classes.values())
            assert parts == pytest.approx(result[split]["depth_l1_cm"])
        # a train view is a frame of the trajectory: whatever it shows, the trajectory saw
        assert result["train"]["classes"]["hole_unobserved"]["pixels_pct"] == 0.0
    # the quarter turn never saw most walls: its test views are mostly holes nobody observed
    assert quarter["test"]["classes"]["hole_unobserved"]["pixels_pct"] > 20.0
    assert quarter["test"]["classes"]["hole_unobserved"]["pixels_pct"] > \
        5 * full["test"]["classes"]["hole_unobserved"]["pixels_pct"]
    assert quarter["test"]["psnr"] < full["test"]["psnr"]
    # and those holes hold most of its depth error (a hole renders ~0 m where the wall is metres away)
    test = quarter["test"]
    assert test["classes"]["hole_unobserved"]["depth_l1_cm"] > 0.5 * test["depth_l1_cm"]


def test_budget_refuses_what_it_cannot_measure(episode, tmp_path):
    with pytest.raises(EpisodeError, match="unknown split"):
        error_budget(episode[0], splits=("val",), **FAST)
    with pytest.raises(EpisodeError):
        error_budget(tmp_path, **FAST)


def test_render_eval_budget_option_writes_the_budget(episode, tmp_path, capsys):
    import shutil

    from activesplat.cli import main

    out = shutil.copytree(episode[0], tmp_path / "copy")
    code = main(["render-eval", str(out), "--n-train", "2", "--n-test", "2", "--backend", "numba",
                 "--no-progress", "--budget"])
    assert code == 0
    text = capsys.readouterr().out
    assert "hole_unobserved" in text and "render_budget.json" in text
    import json

    saved = json.loads((out / "render_budget.json").read_text())
    assert saved["train"]["n_views"] == 2 and set(saved["test"]["classes"]) == set(PIXEL_CLASSES)
    assert (out / "render_budget.png").stat().st_size > 10_000


def _ctrl_c(*args, **kwargs):
    raise KeyboardInterrupt


def test_ctrl_c_in_render_eval_is_one_line(episode, tmp_path, capsys, monkeypatch):
    """What is kept and what to run again, in one line (no generic "interrupted" after it), exit code 130:
    in the evaluation nothing is written; in the error budget, render_metrics.json is already there."""
    import shutil

    from activesplat.cli import main

    out = shutil.copytree(episode[0], tmp_path / "copy")
    argv = ["render-eval", str(out), "--n-train", "2", "--n-test", "2", "--backend", "numba", "--no-progress",
            "--no-lpips"]
    monkeypatch.setattr("activesplat.refine.maps.render_eval", _ctrl_c)
    assert main(argv) == 130
    assert capsys.readouterr().err.strip() == (f"render-eval interrupted: nothing measured is kept "
                                               f"({out / 'render_metrics.json'} as it was); run the same "
                                               f"command again")
    monkeypatch.undo()
    monkeypatch.setattr("activesplat.eval.render_error.error_budget", _ctrl_c)
    assert main([*argv, "--budget"]) == 130
    err = capsys.readouterr().err.strip()
    assert err == (f"render-eval interrupted in the error budget: {out / 'render_metrics.json'} is written, "
                   f"render_budget.json is not; run the same command again for it")
    assert (out / "render_metrics.json").is_file() and not (out / "render_budget.json").exists()
