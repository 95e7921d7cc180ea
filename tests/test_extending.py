"""docs/extending.md runs as written: its policy registers and explores, its script runs an episode and a
benchmark with it, its environment drives the loop, and its entry point makes the policy a name on the
command line. The doc's own code blocks are executed (on tiny settings), so the page cannot go stale."""

import re
import sys
import tomllib
from pathlib import Path

import pytest

import activesplat.bench
import activesplat.config
import activesplat.explore
from activesplat.cli import main
from activesplat.errors import InvalidInputError
from activesplat.eval.coverage import CoverageConfig
from activesplat.planning import policies
from activesplat.planning.explorer import Explorer
from activesplat.planning.explorer_config import ExplorerConfig
from activesplat.sim import SimConfig

DOC = Path(__file__).resolve().parents[1] / "docs" / "extending.md"
STEPS = 24
"""Tiny runs: 64 x 64 frames, a 30-degree look-around (6 actions), then the policy's own choices."""
TINY_SIM = SimConfig(width=64, height=64)
TINY_EXPLORER = ExplorerConfig(bootstrap_yaw_deg=30)
TINY_COVERAGE = CoverageConfig(n_gt_points=3000, batch_frames=8)
TINY_CLI = ["--steps", str(STEPS), "--sim.width", "64", "--sim.height", "64", "--explorer.bootstrap-yaw-deg",
            "30", "--coverage.n-gt-points", "3000", "--backend", "numba", "--no-progress"]


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(), flags=re.S)


@pytest.fixture
def tiny(monkeypatch, tmp_path):
    """The doc's calls on tiny settings, in a scratch folder (its runs/... paths land there)."""
    monkeypatch.chdir(tmp_path)
    real_run = activesplat.explore.run_exploration

    def run_exploration(*args, **kwargs):
        kwargs.update(steps=STEPS, sim_config=TINY_SIM, explorer_config=TINY_EXPLORER,
                      coverage_config=TINY_COVERAGE, backend="numba", progress=False)
        return real_run(*args, **kwargs)

    def run_benchmark(scenes, policies, trials=1, **kwargs):  # one scene, one trial
        return real_benchmark(scenes[:1], policies, trials=1, **{**kwargs, "log": lambda line: None})

    real_benchmark = activesplat.bench.run_benchmark
    monkeypatch.setattr(activesplat.explore, "run_exploration", run_exploration)  # the benchmark's runs too
    monkeypatch.setattr(activesplat.bench, "run_benchmark", run_benchmark)
    return tmp_path


def _run_doc_policy() -> dict:
    namespace = {"__name__": "doc_policy"}
    exec(compile(_blocks("python")[0], f"{DOC}:policy", "exec"), namespace)
    return namespace


def test_the_docs_policy_registers_and_explores_with_its_own_goals(registry, tiny, capsys):
    _run_doc_policy()
    assert "nearest-node" in policies.policy_names()
    assert "nearest-node" in policies.describe_policies()
    namespace: dict = {}
    exec(compile(_blocks("python")[1], f"{DOC}:script", "exec"), namespace)
    metrics, report = namespace["metrics"], namespace["report"]
    assert metrics["policy"] == "nearest-node" and metrics["steps"] == STEPS
    # after the look-around the policy chose goals and followed paths to them
    causes = metrics["completion_gain"]["by_cause"]
    assert causes["bootstrap"]["actions"] == 6 and causes["path"]["actions"] > 0
    assert metrics["completion_ratio_pct"] > 0
    runs = {(r.spec.policy, r.status) for r in report.records}
    assert runs == {("nearest-node", "complete"), ("fbe", "complete")}
    assert "nearest-node" in report.markdown
    assert "completion" in capsys.readouterr().out


def test_the_docs_environment_drives_the_loop(registry, tiny, monkeypatch):
    real_config = activesplat.config.RunConfig

    def run_config(**kwargs):  # the doc's RunConfig(...) on tiny settings
        return real_config(**{**kwargs, "steps": STEPS, "sim": TINY_SIM, "explorer": TINY_EXPLORER,
                              "backend": "numba"})

    monkeypatch.setattr(activesplat.config, "RunConfig", run_config)
    _run_doc_policy()
    namespace: dict = {}
    exec(compile(_blocks("python")[2], f"{DOC}:environment", "exec"), namespace)
    env, metrics = namespace["env"], namespace["metrics"]
    assert sum(env.actions.values()) == STEPS == metrics["steps"]
    assert metrics["policy"] == "nearest-node" and "completion_ratio_pct" not in metrics  # no ground truth
    assert (tiny / "runs" / "counting-env" / "actions.txt").read_text().count("\n") >= STEPS


def _install_plugin(root: Path, monkeypatch, value: str | None = None) -> str:
    """The doc's pyproject.toml as an installed distribution (dist-info with its entry points) and its
    policy block as the module the entry point names, on sys.path. Returns the module name. `value`: another
    entry point, whose module is not written."""
    toml = tomllib.loads(_blocks("toml")[0])
    (name, target), = toml["project"]["entry-points"][policies.ENTRY_POINT_GROUP].items()
    module = (value or target).split(":")[0]
    if value is None:
        (root / f"{module}.py").write_text(_blocks("python")[0])
    target = value or target
    info = root / f"{toml['project']['name'].replace('-', '_')}-{toml['project']['version']}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {toml['project']['name']}\n"
                                   f"Version: {toml['project']['version']}\n")
    (info / "entry_points.txt").write_text(f"[{policies.ENTRY_POINT_GROUP}]\n{name} = {target}\n")
    monkeypatch.syspath_prepend(str(root))
    monkeypatch.delitem(sys.modules, module, raising=False)
    policies._entry_points.cache_clear()
    return module


def test_an_installed_entry_point_is_a_policy_of_the_command_line(registry, tiny, monkeypatch, capsys):
    (tiny / "site").mkdir()
    module = _install_plugin(tiny / "site", monkeypatch)
    assert "nearest-node" in policies.policy_names() and module not in sys.modules  # listed, not imported
    with pytest.raises(SystemExit):
        main(["explore", "--help"])
    assert "nearest-node" in capsys.readouterr().out
    from activesplat.bench.runner import plan_runs

    assert plan_runs(["small-0"], ["nearest-node", "fbe"], [0], STEPS, tiny / "bench")  # --policies takes it
    code = main(["explore", "--policy", "nearest-node", *TINY_CLI, "--out", str(tiny / "cli-run")])
    assert code == 0 and module in sys.modules
    meta = (tiny / "cli-run" / "episode.json").read_text()
    assert '"policy": "nearest-node"' in meta
    monkeypatch.delitem(sys.modules, module)


def test_an_entry_point_that_cannot_be_imported_is_one_line(registry, tiny, monkeypatch, capsys):
    (tiny / "site").mkdir()
    _install_plugin(tiny / "site", monkeypatch, value="no_such_module:NearestNode")
    code = main(["explore", "--policy", "nearest-node", *TINY_CLI, "--out", str(tiny / "never")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "entry point no_such_module:NearestNode" in err and "No module named 'no_such_module'" in err


def test_register_policy_refuses_what_would_break_a_run(registry):
    class Idle(Explorer):
        def replan(self, pose):
            self.idle(pose, False)

    with pytest.raises(InvalidInputError, match="built in"):
        policies.register_policy("fbe", Idle)
    for bad in ("", "a/b", "two words", "../up"):
        with pytest.raises(InvalidInputError, match="names folders"):
            policies.register_policy(bad, Idle)
    with pytest.raises(InvalidInputError, match="must be callable"):
        policies.register_policy("idle", "Idle")
    policies.register_policy("idle", Idle)
    explorer = policies.make_policy("idle", world=None, floor_height=0.0)
    assert isinstance(explorer, Idle) and explorer.name == "idle"
    policies.register_policy("idle", lambda world, floor, cfg, timers: object())  # again: replaced
    with pytest.raises(InvalidInputError, match="returned object, not an activesplat"):
        policies.make_policy("idle", world=None, floor_height=0.0)
    with pytest.raises(InvalidInputError, match="unknown policy 'nope'; choose one of: .*fbe, idle"):
        policies.make_policy("nope", world=None, floor_height=0.0)
