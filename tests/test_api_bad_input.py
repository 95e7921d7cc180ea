"""The README's Python API given bad input as a user would type it in a notebook: one clear exception of
the project's (an ActiveSplatError, a ValueError too) whose one-line message names the problem, before
any work is done; never a numba/torch/numpy traceback or a silently wrong result."""

import numpy as np
import pytest
import torch

from activesplat.config import RunConfig
from activesplat.errors import ActiveSplatError, InvalidActionError, InvalidInputError, SceneError
from activesplat.explore import explore_environment, run_exploration
from activesplat.sim import SimConfig, Simulator, box_room, load_scene
from activesplat.splat import Mapper, rasterize

SIZE = 32


@pytest.fixture(scope="module")
def sim():
    return Simulator(box_room(), seed=0, config=SimConfig(width=SIZE, height=SIZE))


@pytest.fixture(scope="module")
def obs(sim):
    return sim.reset()


def _raises(error, match, call):
    with pytest.raises(error, match=match) as info:
        call()
    assert isinstance(info.value, ActiveSplatError) and isinstance(info.value, ValueError)
    assert "\n" not in str(info.value)
    return info.value


def _mirrored(pose):
    return pose @ np.diag([-1.0, 1.0, 1.0, 1.0])


def _scaled(pose):
    return pose @ np.diag([2.0, 2.0, 2.0, 1.0])


FRAMES = {
    # name: (rgb, depth, pose) as a function of the observation, and the message's words
    "depth of another shape": (lambda o: (o.rgb, o.depth[:, :-4], o.pose),
                               r"depth must have shape \(32, 32\), got \(32, 28\)"),
    "depth (H, W, 1)": (lambda o: (o.rgb, o.depth[..., None], o.pose), r"depth must have shape"),
    "rgb (3, H, W)": (lambda o: (o.rgb.transpose(2, 0, 1), o.depth, o.pose),
                      r"rgb must have shape \(32, 32, 3\)"),
    "rgb float 0-255": (lambda o: (o.rgb.astype(np.float32), o.depth, o.pose),
                        r"float rgb must be in \[0, 1\]"),
    "rgb uint16": (lambda o: (o.rgb.astype(np.uint16) * 257, o.depth, o.pose), r"rgb must be uint8 or"),
    "depth mm uint16": (lambda o: ((o.depth * 1000).astype(np.uint16),),
                        r"depth must be float metres.*millimetres"),
    "depth mm float": (lambda o: (o.depth * 1000,), r"depth must be in metres.*millimetres"),
    "pose 3x4": (lambda o: (o.rgb, o.depth, o.pose[:3]), r"pose must be a 4x4.*\(3, 4\)"),
    "pose non-rigid": (lambda o: (o.rgb, o.depth, _scaled(o.pose)), r"pose must be rigid"),
    "pose mirrored": (lambda o: (o.rgb, o.depth, _mirrored(o.pose)), r"pose must be a proper rotation"),
    "pose NaN": (lambda o: (o.rgb, o.depth, np.full((4, 4), np.nan)), r"pose must be finite"),
    "pose text": (lambda o: (o.rgb, o.depth, "identity"), r"pose must be a 4x4 .* of numbers, got str"),
    "pose ragged": (lambda o: (o.rgb, o.depth, [[1, 0], [0, 1, 0]]), r"pose must be a 4x4 .* of numbers"),
}


@pytest.mark.parametrize("case", FRAMES)
def test_add_frame_names_what_is_wrong_with_the_frame(sim, obs, case):
    make, match = FRAMES[case]
    args = make(obs)
    if len(args) == 1:  # the depth alone replaced
        args = (obs.rgb, args[0], obs.pose)
    mapper = Mapper(sim.K, SIZE, SIZE, backend="numba")
    _raises(InvalidInputError, "mapper: frame 0: " + match, lambda: mapper.add_frame(*args))
    assert len(mapper.gaussians) == 0 and mapper.received == 0  # nothing was taken


def test_add_frame_takes_rgb_as_uint8_or_floats_in_0_1_and_nan_depth_as_invalid(sim, obs):
    ints, floats = Mapper(sim.K, SIZE, SIZE, backend="numba"), Mapper(sim.K, SIZE, SIZE, backend="numba")
    torch.manual_seed(0)
    ints.add_frame(obs.rgb, obs.depth, obs.pose)
    torch.manual_seed(0)
    floats.add_frame(obs.rgb / 255.0, obs.depth, obs.pose)
    assert torch.equal(ints.gaussians.params["means"], floats.gaussians.params["means"])
    depth = obs.depth.copy()
    depth[:4] = np.nan
    with pytest.warns(UserWarning, match=r"frame 1: 128 depth pixels are NaN"):
        stats = ints.add_frame(obs.rgb, depth, obs.pose)
    assert not stats.skipped and ints.broken_depth_frames == 1
    with pytest.warns(UserWarning, match="frame 2 has no valid depth, skipped"):
        assert ints.add_frame(obs.rgb, np.full_like(depth, np.nan), obs.pose).skipped


def test_mapper_and_render_name_a_bad_camera(sim, obs):
    _raises(InvalidInputError, r"image size must be positive, got None", lambda: Mapper(sim.K, None, SIZE))
    _raises(InvalidInputError, r"intrinsics K must be a 3x3 matrix of numbers, got str",
            lambda: Mapper("K", SIZE, SIZE))
    _raises(InvalidInputError, r"intrinsics K must be a finite 3x3", lambda: Mapper(sim.K[:2], SIZE, SIZE))
    mapper = Mapper(sim.K, SIZE, SIZE, backend="numba")
    _raises(InvalidInputError, r"render size must be positive", lambda: mapper.render(obs.pose, width="wide"))
    _raises(InvalidInputError, r"pose must be a 4x4", lambda: mapper.render(obs.pose[:3]))


def test_simulator_names_a_bad_action_scene_or_seed(sim):
    _raises(InvalidActionError, r"unknown action 'forward': expected one of move_forward, turn_left",
            lambda: sim.step("forward"))
    _raises(InvalidInputError, r"Simulator takes a Scene, got str: load_scene\('small-0'\) first",
            lambda: Simulator("small-0"))
    _raises(InvalidInputError, r"seed must be an integer >= 0, got 'one'",
            lambda: Simulator(box_room(), "one"))
    _raises(SceneError, r"unknown scene 'medium-x': expected small-<seed>, medium-<seed>",
            lambda: load_scene("medium-x"))


def test_run_exploration_refuses_a_bad_policy_budget_or_group_before_it_starts(tmp_path):
    out = tmp_path / "run"
    _raises(InvalidInputError, r"unknown policy 'nearest'; choose one of: activesplat",
            lambda: run_exploration("small-0", policy="nearest", steps=5, out=out))
    for steps in (0, -3, 1.5, "100", True):
        _raises(InvalidInputError, rf"RunConfig.steps must be a positive number of actions .*got {steps!r}",
                lambda steps=steps: run_exploration("small-0", steps=steps, out=out))
    _raises(InvalidInputError, r"RunConfig.sim must be a SimConfig, got dict \(use SimConfig\(\*\*that",
            lambda: run_exploration("small-0", steps=5, sim_config={"width": 64}, out=out))
    _raises(SceneError, r"unknown scene 'medium-x'", lambda: run_exploration("medium-x", steps=5, out=out))
    assert not out.exists()


def test_run_config_takes_numpy_integers_as_ints():
    run = RunConfig(seed=np.int64(3), steps=np.int32(40))
    assert (run.seed, run.steps) == (3, 40) and type(run.seed) is int and type(run.steps) is int
    assert RunConfig.from_dict(run.to_dict()) == run


def test_explore_environment_needs_a_budget(sim, tmp_path):
    _raises(InvalidInputError, r"needs a step budget > 0", lambda: explore_environment(sim, RunConfig(),
                                                                                        tmp_path / "run"))
    assert not (tmp_path / "run").exists()


def _gaussians(n=6):
    g = torch.Generator().manual_seed(0)
    means = torch.rand(n, 3, generator=g) + torch.tensor([-0.5, -0.5, 2.0])
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0]]).repeat(n, 1)
    return [means, quats, torch.full((n, 3), 0.05), torch.full((n,), 0.5), torch.rand(n, 3, generator=g)]


@pytest.mark.parametrize("which", range(5))
@pytest.mark.parametrize("backend", ["numba", "torch"])
def test_rasterize_names_the_tensor_whose_length_is_not_that_of_means(which, backend):
    params = _gaussians()
    names = ["means", "quats", "scales", "opacities", "colors"]
    params[which] = params[which][:4]
    K = torch.tensor([[SIZE, 0.0, SIZE / 2], [0.0, SIZE, SIZE / 2], [0.0, 0.0, 1.0]])
    if which == 0:  # 4 means: the next tensor is the first of another length
        match = r"quats must have shape \(Nx4\) with N = 4, the rows of means, got \(6, 4\)"
    else:
        match = rf"{names[which]} must have shape \(N(x\d)?\) with N = 6, the rows of means, got \(4"
    _raises(InvalidInputError, "rasterize: " + match,
            lambda: rasterize(*params, torch.eye(4), K, SIZE, SIZE, backend=backend))
