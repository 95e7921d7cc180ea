"""The environment interface: the simulator is one, and the exploration loop runs a user-written one (the
example of docs/robots.md) without knowing what is behind it."""

import json

import numpy as np
import pytest

from activesplat.config import RunConfig
from activesplat.env import ACTIONS, Environment, Observation
from activesplat.errors import InvalidInputError
from activesplat.explore import explore_environment
from activesplat.sim import SimConfig, Simulator, box_room


class TurntableCamera:
    """A user-written environment (docs/robots.md): a camera that can only turn on the spot, its images
    from some renderer (here the box room's, through a simulator it owns)."""

    def __init__(self, width=32, height=32):
        self._renderer = Simulator(box_room(), seed=0, config=SimConfig(width=width, height=height))
        self.K, self.width, self.height = self._renderer.K, width, height
        self.steps = 0

    def _observe(self, collided=False):
        rgb, depth = self._renderer.render(self._renderer.pose)
        return Observation(rgb, depth, self._renderer.pose, self.steps, collided)

    def reset(self):
        self.steps = 0
        self._renderer.reset()
        return self._observe()

    def step(self, action):
        assert action in ACTIONS
        self.steps += 1
        if action != "move_forward":
            self._renderer.act(action)
        return self._observe(collided=action == "move_forward")


class WalkingCamera(TurntableCamera):
    """A user-written environment that also walks, by its own action sizes (its simulator's ``sizes``)."""

    def __init__(self, width=32, height=32, **sizes):
        super().__init__(width, height)
        self._renderer = Simulator(box_room(), seed=0, config=SimConfig(width=width, height=height, **sizes))

    def step(self, action):
        self.steps += 1
        return self._observe(collided=self._renderer.act(action))


def _walk(tmp_path, env, steps=70):
    """`steps` actions of `env` with the default action sizes and a short look-around (60 deg): 14 forward
    moves in the box room. The warnings it gave, and its metrics."""
    import warnings
    from dataclasses import replace

    from activesplat.planning.explorer_config import ExplorerConfig

    run = RunConfig().replace(steps=steps, sim=SimConfig(width=32, height=32), backend="numba",
                              explorer=replace(ExplorerConfig(), bootstrap_yaw_deg=60.0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        metrics = explore_environment(env, run, tmp_path / "ep", progress=False, name="walker")
    return [str(w.message) for w in caught], metrics


def test_an_environment_that_steps_farther_than_configured_is_warned_about_once(tmp_path):
    """A robot that moves 0.1 m per move_forward where the run says 0.065 m: planning and path_length_m
    assume 0.065 m; the poses tell, and a warning names both sizes and the option (once, though more forward
    moves follow). metrics.json records the measured sizes and the path the poses walked."""
    caught, metrics = _walk(tmp_path, WalkingCamera(forward_step=0.1))
    assert caught == ["the environment's move_forward moved the camera by 0.100 m (median of 5), not the "
                      "configured 0.065 m the planner assumes (and path_length_m counts): configure the run "
                      "with the environment's own, --sim.forward-step 0.1 (SimConfig.forward_step)"]
    sizes = metrics["measured_action_sizes"]
    forward = metrics["action_counts"]["move_forward"]
    assert forward == sizes["forward_step"]["moves"] > 5 and sizes["forward_step"]["ignored"] == 0
    assert sizes["forward_step"]["measured"] == pytest.approx(0.1)
    assert sizes["forward_step"]["configured"] == 0.065
    assert sizes["turn_deg"]["measured"] == pytest.approx(10.0) and sizes["look_deg"]["measured"] == \
        pytest.approx(15.0)
    assert metrics["path_length_m"] == pytest.approx(0.065 * forward)  # what the loop assumed
    assert metrics["path_length_poses_m"] == pytest.approx(0.1 * forward)  # what the poses say
    saved = json.loads((tmp_path / "ep" / "metrics.json").read_text())
    assert saved["measured_action_sizes"] == sizes


def test_an_environment_of_the_configured_sizes_is_not_warned_about(tmp_path):
    caught, metrics = _walk(tmp_path, WalkingCamera())
    assert caught == []
    assert {kind: round(m["measured"], 6) for kind, m in metrics["measured_action_sizes"].items()} == {
        "forward_step": 0.065, "turn_deg": 10.0, "look_deg": 15.0}
    assert metrics["path_length_poses_m"] == pytest.approx(metrics["path_length_m"])


def test_the_run_s_own_simulator_is_not_measured(tmp_path):
    """The simulator of the run's own sim settings moves by them: no check, no new metrics."""
    sim = Simulator(box_room(), seed=0, config=SimConfig(width=32, height=32))
    run = RunConfig().replace(steps=3, sim=SimConfig(width=32, height=32), backend="numba")
    with pytest.warns(UserWarning, match="a budget of 3") as caught:
        metrics = explore_environment(sim, run, tmp_path / "ep", progress=False)
    assert len(caught) == 1
    assert "measured_action_sizes" not in metrics and "path_length_poses_m" not in metrics
    assert "environment_seed" not in json.loads((tmp_path / "ep" / "episode.json").read_text())


def test_a_simulator_of_another_seed_is_recorded_with_its_own(tmp_path):
    """episode.json's seed is the run's (torch, the planner); the simulator's own seed, which chose the start
    pose, is recorded beside it when it differs."""
    sim = Simulator(box_room(), seed=3, config=SimConfig(width=32, height=32))
    run = RunConfig().replace(steps=3, seed=1, sim=SimConfig(width=32, height=32), backend="numba")
    with pytest.warns(UserWarning, match="a budget of 3"):
        explore_environment(sim, run, tmp_path / "ep", progress=False)
    meta = json.loads((tmp_path / "ep" / "episode.json").read_text())
    assert meta["seed"] == 1 and meta["environment_seed"] == 3


def _pose(x=0.0, z=0.0, yaw_deg=0.0, pitch_deg=0.0):
    from activesplat.geometry import camera_pose

    return camera_pose([x, 1.25, z], np.radians(yaw_deg), np.radians(pitch_deg))


def test_blocked_moves_and_a_minority_of_short_ones_are_not_warned_about():
    """Forward moves the environment reports as collisions, moves that did not happen (a blocked base
    without collision reports, a tilt at the limit or of a base without a tilt unit) are left out, and the
    median shrugs off a few short ones; turns are measured about the world's vertical at any pitch."""
    import warnings

    from activesplat.env import ActionSizeCheck

    check = ActionSizeCheck(SimConfig())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        z = 0.0
        for k in range(12):
            if k % 3 == 0:  # blocked: reported, or not (it did not move)
                check.observe("move_forward", _pose(z=z), _pose(z=z + 0.002 * (k % 2)), collided=k % 2 == 0)
            step = 0.03 if k % 4 == 1 else 0.065  # a few stopped short
            check.observe("move_forward", _pose(z=z), _pose(z=z + step))
            z += step
            check.observe("turn_left", _pose(yaw_deg=10 * k, pitch_deg=-30), _pose(yaw_deg=10 * k + 10,
                                                                                  pitch_deg=-30))
            check.observe("look_down", _pose(pitch_deg=-45), _pose(pitch_deg=-45))  # at the limit
    m = check.metrics()
    assert m["forward_step"]["measured"] == pytest.approx(0.065) and m["forward_step"]["ignored"] == 4
    assert m["forward_step"]["moves"] == 12
    assert m["turn_deg"]["measured"] == pytest.approx(10.0)
    assert m["look_deg"] == {"measured": None, "configured": 15.0, "moves": 0, "ignored": 12}
    assert check.path_length_m == pytest.approx(z + 0.002 * 2)


def _off_axis(pose, ahead_m=0.15):
    """`pose` of a camera mounted `ahead_m` in front of the robot's turning axis (at `pose`'s position)."""
    pose = np.array(pose)
    pose[:3, 3] += ahead_m * pose[:3, 2]
    return pose


def test_the_path_from_the_poses_counts_forward_moves_not_a_mounted_camera_swinging_in_turns():
    """A camera 15 cm in front of the turning axis moves 2.6 cm sideways in every 10 degree turn on the spot;
    the path from the poses is the forward moves' translations only, as path_length_m counts them."""
    import warnings

    from activesplat.env import ActionSizeCheck

    check = ActionSizeCheck(SimConfig())
    x = z = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for k in range(12):
            yaw = 10.0 * k
            turned = _off_axis(_pose(x, z, yaw + 10))
            check.observe("turn_left", _off_axis(_pose(x, z, yaw)), turned)
            assert np.hypot(*(turned[[0, 2], 3] - _off_axis(_pose(x, z, yaw))[[0, 2], 3])) > 0.025
            x, z = np.array([x, z]) + 0.065 * turned[[0, 2], 2]  # a step along the heading
            check.observe("move_forward", turned, _off_axis(_pose(x, z, yaw + 10)))
            check.observe("look_up", _off_axis(_pose(x, z, yaw + 10)),
                          _off_axis(_pose(x, z, yaw + 10, pitch_deg=15)))  # a tilt swings it too
            check.observe("look_down", _off_axis(_pose(x, z, yaw + 10, pitch_deg=15)),
                          _off_axis(_pose(x, z, yaw + 10)))
    assert check.path_length_m == pytest.approx(12 * 0.065)
    m = check.metrics()
    assert m["forward_step"]["measured"] == pytest.approx(0.065) and m["turn_deg"]["measured"] == \
        pytest.approx(10.0)


def test_each_kind_is_warned_about_once_after_five_moves():
    from activesplat.env import ActionSizeCheck

    check = ActionSizeCheck(SimConfig())
    for _ in range(4):  # 4 tilts of 20 deg: not yet judged
        check.observe("look_up", _pose(pitch_deg=0), _pose(pitch_deg=20))
    with pytest.warns(UserWarning) as caught:
        for _ in range(10):
            check.observe("look_up", _pose(pitch_deg=0), _pose(pitch_deg=20))
            check.observe("turn_right", _pose(yaw_deg=5), _pose(yaw_deg=-3))  # 8 deg: within 25 % of 10
    assert [str(w.message) for w in caught] == [
        "the environment's look_up / look_down moved the camera by 20.0 deg (median of 5), not the "
        "configured 15 deg the planner assumes (and path_length_m counts): configure the run with the "
        "environment's own, --sim.look-deg 20 (SimConfig.look_deg)"]


def test_steps_shorter_than_a_collision_are_warned_about_once():
    """A robot whose steps are under half the configured one has every move reported as a collision (the
    bridge's rule): none is measured, so the sizes' check cannot see it; the collisions that moved say it."""
    from activesplat.env import ActionSizeCheck

    check = ActionSizeCheck(SimConfig())
    with pytest.warns(UserWarning) as caught:
        for k in range(12):
            check.observe("move_forward", _pose(z=0.02 * k), _pose(z=0.02 * (k + 1)), collided=True)
    assert [str(w.message) for w in caught] == [
        "5 of the environment's 5 move_forward actions were reported as collisions though the camera moved "
        "(median 0.020 m): its steps may be shorter than the configured 0.065 m the planner assumes; if so, "
        "configure the run with the environment's own, --sim.forward-step (SimConfig.forward_step)"]
    assert check.metrics()["forward_step"] == {"measured": None, "configured": 0.065, "moves": 0,
                                               "ignored": 12}


def test_a_few_real_collisions_are_not_warned_about():
    import warnings

    from activesplat.env import ActionSizeCheck

    check = ActionSizeCheck(SimConfig())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for k in range(20):  # every third move bumps into something after 2 cm
            bumped = k % 3 == 0
            check.observe("move_forward", _pose(z=0.0), _pose(z=0.02 if bumped else 0.065), collided=bumped)
    assert check.metrics()["forward_step"]["measured"] == pytest.approx(0.065)


def test_the_simulator_and_a_user_environment_satisfy_the_interface():
    assert isinstance(Simulator(box_room(), config=SimConfig(width=16, height=16)), Environment)
    assert isinstance(TurntableCamera(), Environment)


def test_the_exploration_loop_runs_a_user_environment(tmp_path):
    run = RunConfig().replace(steps=6, sim=SimConfig(width=32, height=32), backend="numba")
    metrics = explore_environment(TurntableCamera(), run, tmp_path / "ep", progress=False, name="turntable")
    assert metrics["steps"] == 6 and "completion_ratio_pct" not in metrics  # no ground truth, no completion
    # it turns by the configured 10 deg; its forward moves are all refused (collisions): none measured
    sizes = metrics["measured_action_sizes"]
    assert sizes["turn_deg"]["measured"] == pytest.approx(10.0)
    assert sizes["forward_step"]["measured"] is None and metrics["path_length_poses_m"] == 0.0
    assert metrics["n_gaussians"] > 0
    actions = (tmp_path / "ep" / "actions.txt").read_text().split()
    assert len(actions) == 6 and set(actions) <= set(ACTIONS)
    poses = np.loadtxt(tmp_path / "ep" / "poses.txt")
    assert poses.shape == (7, 17)
    meta = json.loads((tmp_path / "ep" / "episode.json").read_text())
    assert meta["scene"] == "turntable" and meta["config"]["steps"] == 6
    assert meta["source"] == "environment" and meta["camera"]["width"] == 32  # the camera it saw
    # the run's sim settings stay recorded (--config reruns them); those of the simulated camera, renderer and
    # navigability did not apply, nor did the completion measure without ground truth
    assert meta["config"]["sim"]["width"] == 32 and meta["config"]["sim"]["turn_deg"] == 10.0
    not_used = set(meta["config_not_used"])
    assert {"sim.width", "sim.height", "sim.hfov_deg", "sim.max_depth", "sim.texture_filter", "sim.nav_cell",
            "coverage"} <= not_used
    assert not {"sim.turn_deg", "sim.look_deg", "sim.forward_step", "sim.sensor_height", "sim.agent_radius",
                "sim.agent_height"} & not_used  # what the planner assumed: the environment should honour them
    for name in ("gaussians.ply", "keyframes.npz", "metrics.json"):
        assert (tmp_path / "ep" / name).is_file()
    from activesplat.errors import EpisodeError
    from activesplat.eval.evaluate import evaluate_episode

    with pytest.raises(EpisodeError, match="without ground truth .*needs a simulated episode"):
        evaluate_episode(tmp_path / "ep")  # no scene to replay: said so, not "unknown scene 'turntable'"


def test_a_bad_observation_is_named(tmp_path):
    env = TurntableCamera()
    env.width = 16  # says 16 px, delivers 32
    run = RunConfig().replace(steps=2, sim=SimConfig(width=32, height=32))
    with pytest.raises(InvalidInputError, match=r"reset\(\): observation of rgb"):
        explore_environment(env, run, tmp_path / "bad", progress=False)
