"""The README's "Python API" block runs as written: every line of it is executed (on tiny settings, in a
scratch folder with a small recording in it), and what its comments promise (attribute names, shapes and
dtypes, the action names) is checked against what the calls return, so the block cannot go stale.

Tiny settings, by patching the package's own names as the block imports them (nothing in the text is
replaced): `Simulator` renders 64 x 64 frames unless given a SimConfig, `run_exploration` runs with a
small coverage sample, and every episode (`explore_environment`, which
`run_exploration` and `explore_episode` call too) is `STEPS` actions long whatever the block's budget."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
import torch

import activesplat.explore
import activesplat.sim
from activesplat.env import ACTIONS
from activesplat.eval.coverage import CoverageConfig
from activesplat.planning import policies
from activesplat.sim import SimConfig

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
STEPS = 2
"""Two actions of the look-around: every call of the block runs and writes its episode (the policies are built
and started; tests/test_extending.py and tests/test_explore.py run policies further)."""
SIZE = 64
TINY_SIM = SimConfig(width=SIZE, height=SIZE)
TINY_COVERAGE = CoverageConfig(n_gt_points=3000, batch_frames=8)
DRIVER_TOPICS = {"/camera/color/image_raw": "/rgb/image_raw",
                 "/camera/depth/image_raw": "/depth_to_rgb/image_raw",
                 "/camera/color/camera_info": "/rgb/camera_info"}
"""The tests' bag topics under the names the README's `open_recording` line gives (an Azure Kinect's)."""


def api_block() -> str:
    blocks = re.findall(r"^## Python API\n+```python\n(.*?)^```", README.read_text(), flags=re.S | re.M)
    assert len(blocks) == 1, "README.md: no ```python block right under '## Python API'"
    return blocks[0]


@pytest.fixture
def tiny(monkeypatch, tmp_path):
    """The block's calls on tiny settings, in a scratch folder (its runs/... paths land there)."""
    monkeypatch.chdir(tmp_path)
    real_sim, real_run = activesplat.sim.Simulator, activesplat.explore.run_exploration
    real_env = activesplat.explore.explore_environment

    class Simulator(real_sim):
        def __init__(self, scene, seed=0, start=None, config=None):
            super().__init__(scene, seed=seed, start=start, config=config or TINY_SIM)

    def run_exploration(*args, **kwargs):
        kwargs.update(sim_config=TINY_SIM, coverage_config=TINY_COVERAGE,
                      backend="numba", progress=False)
        return real_run(*args, **kwargs)

    def explore_environment(env, run, *args, **kwargs):
        return real_env(env, run.replace(steps=STEPS), *args, **{**kwargs, "progress": False})

    monkeypatch.setattr(activesplat.sim, "Simulator", Simulator)
    monkeypatch.setattr(activesplat.explore, "run_exploration", run_exploration)
    monkeypatch.setattr(activesplat.explore, "explore_environment", explore_environment)
    return tmp_path


def _write_walk(folder: Path) -> Path:
    """walk.mcap: a short walk through the box room as a bare MCAP file, with /tf poses and the README's
    topic names (tests/robot's bag writer)."""
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "robot"))
    try:
        from _bags import walk_frames, write_bag
    finally:
        sys.path.remove(str(ROOT / "tests" / "robot"))
    K, frames = walk_frames(8, 32)
    bag = write_bag(folder / "walk-bag", K, frames, fmt="mcap", pose="tf", rename=DRIVER_TOPICS)
    return next(bag.glob("*.mcap")).rename(folder / "walk.mcap")


@pytest.mark.filterwarnings("ignore:a budget of 2 actions ends within the first look-around")
def test_the_readme_python_api_block_runs_as_written(registry, tiny):
    block = api_block()
    _write_walk(tiny)
    ns: dict = {"__name__": "readme"}
    exec(compile(block, f"{README}:Python API", "exec"), ns)
    # the episodes the block writes, with the policies and seeds it asks for
    for folder, policy, seed in (("small-0", "activesplat", 0), ("small-0-s1", "activesplat", 1),
                                 ("any-env", "activesplat", 1), ("small-0-fbe-90", "fbe-90", 0)):
        meta = json.loads((tiny / "runs" / folder / "episode.json").read_text())
        assert (meta["config"]["policy"], meta["config"]["seed"]) == (policy, seed), folder
        assert (tiny / "runs" / folder / "actions.txt").read_text().count("\n") >= STEPS, folder
    assert ns["run"].seed == 1 and ns["metrics"]["policy"] == "fbe-90"
    assert "fbe-90" in policies.policy_names()
    walk = json.loads((tiny / "runs" / "walk" / "metrics.json").read_text())
    assert len(ns["rec"]) == walk["frames"] == 8 and walk["mapped_frames"] > 0


def test_the_readme_python_api_comments_say_what_the_calls_return(registry, tiny):
    block = api_block()
    ns: dict = {"__name__": "readme"}
    # the lines up to the first exploration: the simulator and the mapper (fast, no recording needed)
    exec(compile(block.split("from activesplat.explore")[0], f"{README}:Python API", "exec"), ns)
    # every obj.attr the block names (in code and comments) exists: sim.K, obs.pose, out.median_depth, ...
    named = set(re.findall(r"\b(scene|sim|obs|mapper|out)\.(\w+)", block))
    assert {("obs", "pose"), ("out", "median_depth"), ("sim", "K")} <= named
    for obj, attr in sorted(named):
        assert hasattr(ns[obj], attr), f"README: {obj}.{attr} does not exist"
    # shapes and dtypes in the comments, at the default image size (the test renders SIZE x SIZE)
    default = (SimConfig().height, SimConfig().width)
    claims = re.findall(r"\b(obs|out)\.(\w+) \((\d+(?:,\d+)*)\)(?: (uint8|float32))?", block)
    assert len(claims) >= 3
    for obj, attr, shape, dtype in claims:
        shape = tuple(int(d) for d in shape.split(","))
        assert shape[:2] == default, f"README: {obj}.{attr} {shape}: the default image is {default}"
        value = getattr(ns[obj], attr)
        assert tuple(value.shape) == (SIZE, SIZE, *shape[2:]), f"README: {obj}.{attr}"
        if dtype:
            assert value.dtype == np.dtype(dtype), f"README: {obj}.{attr} is {value.dtype}, not {dtype}"
    assert ns["obs"].pose.shape == (4, 4) and "obs.pose 4x4" in block
    assert "torch float32: out.rgb" in block
    for name in ("rgb", "depth", "alpha", "median_depth"):
        value = getattr(ns["out"], name)
        assert isinstance(value, torch.Tensor) and value.dtype == torch.float32, name
    actions = re.search(r"# (move_forward(?: \| \w+)+)", block)
    assert actions and tuple(actions.group(1).split(" | ")) == ACTIONS
    assert ns["sim"].width == ns["sim"].height == SIZE  # the tiny simulator, not the default one
