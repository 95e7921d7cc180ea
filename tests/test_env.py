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


def test_the_simulator_and_a_user_environment_satisfy_the_interface():
    assert isinstance(Simulator(box_room(), config=SimConfig(width=16, height=16)), Environment)
    assert isinstance(TurntableCamera(), Environment)


def test_the_exploration_loop_runs_a_user_environment(tmp_path):
    run = RunConfig().replace(steps=6, sim=SimConfig(width=32, height=32), backend="numba")
    metrics = explore_environment(TurntableCamera(), run, tmp_path / "ep", progress=False, name="turntable")
    assert metrics["steps"] == 6 and "completion_ratio_pct" not in metrics  # no ground truth, no completion
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
