"""`activesplat explore`: the closed loop of the README ("What happens in an exploration"), one episode.

Simulator -> posed RGB-D -> online mapper -> policy (workspace, Voronoi graph, viewpoints, hierarchical
planning) -> action -> simulator, until the step budget is spent. The episode folder is written as the
run goes (see `activesplat.episode`); completion is measured on the fly with the evaluation protocol
(docs/protocol.md §6) so the progress bar shows it, and `activesplat evaluate DIR` recomputes it from
the action log alone.
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import numpy as np

from activesplat.env import ActionSizeCheck
from activesplat.episode import ENVIRONMENT_SOURCE, EpisodeWriter, software, write_json_atomic
from activesplat.errors import Interrupted, interrupted
from activesplat.eval.behaviour import action_counts, completion_gain, rotation_causes, rotation_pct
from activesplat.timing import progress_bar

TIMING_KEYS = ("mapper", "workspace", "voronoi", "subregions", "rotation_selection", "position_selection",
               "planner")
"""Per-module mean ms per step, as the paper's Tab. VI."""


def _default_out(scene: str, policy: str, seed: int) -> Path:
    stem = Path(scene).stem if any(c in scene for c in "/\\.") else scene
    return Path("runs") / f"{stem}-{policy}-s{seed}"


def run_exploration(scene="small-0", policy: str = "activesplat", steps: int | None = None,
                    seed: int = 0, out: str | Path | None = None, overwrite: bool = False,
                    z_up: bool | None = None, backend: str | None = None, progress: bool = True,
                    explorer_config=None, mapper_config=None, coverage_config=None, sim_config=None,
                    viewer=None, config=None, floor=None) -> dict:
    """Explore `scene` (a built-in name, a mesh path or a `Scene`) with `policy` for `steps` actions and write
    the episode folder; returns the metrics (also written to metrics.json).

    `config` (an `activesplat.config.RunConfig`) gives every setting the other arguments do not: scene,
    policy, steps and seed always come from the arguments, z_up, backend and the groups (`sim_config`, ...)
    when given. `viewer` (e.g. a `viz.viewer.LiveViewer`) gets `update(step, obs, mapper, explorer,
    final=...)` after every step; None (the default) costs nothing."""
    from activesplat.config import RunConfig
    from activesplat.sim import Scene

    scene_obj = scene if isinstance(scene, Scene) else None
    changes = {"scene": scene_obj.name if scene_obj is not None else str(scene), "policy": policy,
               "steps": steps, "seed": seed}
    for name, value in (("z_up", z_up), ("floor", floor), ("backend", backend), ("sim", sim_config),
                        ("mapper", mapper_config),
                        ("explorer", explorer_config), ("coverage", coverage_config)):
        if value is not None:
            changes[name] = value
    run = (config or RunConfig()).replace(**changes)
    return explore_episode(run, out=out, overwrite=overwrite, progress=progress, viewer=viewer,
                           scene=scene_obj)


def explore_episode(run, out: str | Path | None = None, overwrite: bool = False, progress: bool = True,
                    viewer=None, scene=None) -> dict:
    """The episode of a `RunConfig` into `out` (default runs/SCENE-POLICY-sSEED); returns its metrics.
    episode.json records `run` (its step budget resolved), which `load_run_config` reads back. `scene`: the
    already loaded `Scene` of `run.scene`, if any. The simulator is the environment, and completion is
    measured on the fly from its ground truth."""
    from activesplat.episode import check_episode_folder

    out_dir = Path(out) if out is not None else _default_out(run.scene, run.policy, run.seed)
    check_episode_folder(out_dir, overwrite)  # before the scene is loaded: a refusal comes at once
    with _SetUp(out_dir) as setup:
        from activesplat.eval.coverage import CoverageAccumulator
        from activesplat.sim import Simulator, load_scene
        from activesplat.sim.scene import BUILTIN_PATTERN, scene_label

        setup.phase = f"loading the scene {run.scene}"
        scene_obj = scene if scene is not None else load_scene(run.scene, z_up=run.z_up, floor=run.floor)
        steps = int(run.steps or scene_obj.default_steps)
        run = run.replace(steps=steps)
        if scene is None and not BUILTIN_PATTERN.match(str(run.scene)) and Path(run.scene).is_file():
            # a mesh file by its absolute path: evaluate, render-eval and --config work from any folder
            run = run.replace(scene=str(Path(run.scene).resolve()))
        setup.phase = "building the simulator (navigability map, sensor)"
        sim = Simulator(scene_obj, seed=run.seed, config=run.sim)
        setup.phase = "sampling the ground truth for the completion measure"
        cov_cfg = run.coverage
        coverage = CoverageAccumulator(scene_obj.sample_surface(cov_cfg.n_gt_points, seed=cov_cfg.seed),
                                       cov_cfg)
        meta = {"scene": run.scene, "scene_name": scene_obj.name, "z_up": run.z_up,
                "start_pose": sim.start_pose.tolist(),
                "floor": run.floor}  # storey choice of a multi-storey mesh (None: its only storey)
        evaluator = _Completion(sim, coverage, run)
    metrics = explore_environment(sim, run, out_dir, overwrite=overwrite, progress=progress, viewer=viewer,
                                  evaluator=evaluator, meta=meta, name=scene_obj.name)
    evaluator.draw_trajectory(out_dir / "trajectory.png", metrics.get("rooms"),
                              title=f"{scene_label(scene_obj.name)} / {run.policy} seed {run.seed}: "
                              f"trajectory over the floor plan")
    return metrics


def explore_environment(env, run, out: str | Path, overwrite: bool = False, progress: bool = True,
                        viewer=None, evaluator=None, meta: dict | None = None,
                        name: str = "environment") -> dict:
    """The exploration loop against any `activesplat.env.Environment` (the simulator, a robot bridge, a
    user's own), for `run.steps` actions with `run`'s policy and settings; writes the episode folder `out`
    (episode.json with `meta` added, actions, poses, map, topdown.png, metrics.json) and returns the metrics.
    `evaluator` (the simulator's completion measurement, or None where there is no ground truth) sees every
    observation's pose and adds its metrics.

    The README's "What happens in an exploration", step by step (`_Exploration`): reset the environment and
    start the episode folder; then, for every action of the budget, map the current observation (sec.
    III-A), let the policy choose the next action from the map (workspace, viewpoints and planning, sec.
    III-A to III-C; the first ones are the bootstrap look-around), have the environment take it and record
    it; map the last observation too; then the metrics, the map and the figures. Ctrl-C leaves a partial
    episode that `activesplat evaluate` reads; before the first action is recorded (the set-up: reset,
    mapper, policy, kernels; the first step) it leaves `out` as it was, and says so in one line."""
    with _SetUp(Path(out), evaluator) as setup:
        episode = _Exploration(env, run, Path(out), overwrite=overwrite, progress=progress, viewer=viewer,
                               evaluator=evaluator, meta=meta, name=name, setup=setup)
    try:
        try:
            for step in range(1, episode.steps + 1):
                episode.step(step)
            episode.end()
        except KeyboardInterrupt:
            raise episode.interrupted() from None
        return episode.finish()
    finally:
        episode.jit.close()


class _Exploration:
    """One episode of `explore_environment` under way: the environment's latest observation, the map, the
    policy, the episode writer, and what the loop counts (actions and their causes, forward moves, timings,
    the completion curve)."""

    def __init__(self, env, run, out_dir: Path, *, overwrite: bool, progress: bool, viewer, evaluator,
                 meta: dict | None, name: str, setup: _SetUp):
        """Set up the run: check the step budget, the backend and the episode folder, reset the environment,
        build the mapper and the policy on the floor the agent starts on, describe the episode (episode.json,
        written with the first action: until then the folder is not touched), load the kernels, start the
        clock and the progress bar, and hand the reset's frame to the evaluation (the curve's step 0).
        `setup.phase` says what it is doing, for the line Ctrl-C prints."""
        import torch

        from activesplat.env import check_observation
        from activesplat.episode import check_episode_folder
        from activesplat.errors import InvalidInputError
        from activesplat.planning.policies import make_policy
        from activesplat.sim.scene import scene_label
        from activesplat.splat import Mapper
        from activesplat.splat.raster import resolve_backend
        from activesplat.timing import JitCompileClock, Timers

        if not isinstance(run.steps, int) or run.steps <= 0:
            raise InvalidInputError(f"an environment needs a step budget > 0 (run.steps), got {run.steps}")
        self.env, self.run, self.out_dir, self.viewer, self.evaluator = env, run, out_dir, viewer, evaluator
        self.steps, self.name, self.overwrite = run.steps, name, overwrite
        resolve_backend(run.backend)  # a backend this machine cannot run fails before the folder is touched
        check_episode_folder(out_dir, overwrite)
        self.writer: EpisodeWriter | None = None  # the episode folder is written from the first action on
        torch.manual_seed(run.seed)
        setup.phase = "resetting the environment (its first observation)"
        self.obs = env.reset()
        check_observation(self.obs, env.width, env.height, "reset()")
        setup.phase = "building the mapper and the policy"
        self.mapper = Mapper(env.K, env.width, env.height, config=run.mapper, backend=run.backend)
        self.timers = Timers()
        # the floor height comes from the agent's own start pose (its sensor height is known), not the mesh
        self.floor_height = float(self.obs.pose[1, 3] - run.sim.sensor_height)
        self.explorer = make_policy(run.policy, self.mapper, self.floor_height, cfg=run.explorer,
                                    timers=self.timers, frontier=run.frontier)
        _warn_if_no_choice(run, stacklevel=4)  # attributed to the caller of explore_environment
        self.meta = self._episode_meta(meta)
        self.start_pose = np.array(self.obs.pose, dtype=np.float64)

        self.actions: list[str] = []
        self.causes: list[str] = []  # why each action was taken (the explorer's `last_cause`)
        self.forward = 0  # forward moves so far (the path length)
        # an environment other than the run's own simulator: are its moves the sizes the planner assumes?
        self.sizes = ActionSizeCheck(run.sim) if getattr(env, "config", None) != run.sim else None
        self.mapper_phases: dict[str, float] = {}  # ms over the episode, per phase of Mapper._map_frame
        self.curve: list[dict] = []
        compiling = "(compiling them: the first run after an install or a code change)"
        setup.phase = f"loading the rasterizer's kernels {compiling}"
        self.setup_s = _prepare_rasterizer(self.mapper, run, progress)  # kept out of the per-step timings
        setup.phase = f"loading the mapper's and the planner's kernels {compiling}"
        self.setup_s += _warm_up_kernels(run, self.mapper.backend)
        setup.phase = "measuring the completion of the first observation"
        # a kernel the warm-ups missed would compile on first use, inside the timed loop: measured
        self.jit = JitCompileClock(self.timers).__enter__()  # closed by explore_environment
        self.t_start = time.perf_counter()
        self.label = scene_label(name)  # in the progress bar and figure titles
        self.bar = progress_bar(self.steps, f"{self.label} {run.policy}", "step", progress)
        if evaluator is not None:  # the reset's frame (poses.txt holds steps + 1 frames): the curve's step 0
            try:
                self.timers.time("evaluation", evaluator.observe, self.obs.pose)
                self.timers.time("evaluation", evaluator.curve_point, 0,
                                 {"path_length_m": 0.0, "n_gaussians": 0})
            except BaseException:
                self.jit.close()
                if self.bar is not None:
                    self.bar.close()
                raise

    def _episode_meta(self, meta: dict | None) -> dict:
        """episode.json: the run (scene, seed, policy, budget, start pose, settings), the caller's `meta` on
        top, and what the loop found (the floor height, the backend, the camera)."""
        env, run, obs = self.env, self.run, self.obs
        meta = {
            "scene": self.name, "scene_name": self.name, "seed": run.seed, "policy": run.policy,
            "steps": self.steps, "start_pose": np.asarray(obs.pose).tolist(), **(meta or {}),
            "floor_height": self.floor_height, "backend": self.mapper.backend, "config": run.to_dict(),
            # the camera the run saw (run.sim describes the simulator's; a robot's may differ)
            "camera": {"width": env.width, "height": env.height, "K": np.asarray(env.K).tolist()},
            "software": software(),  # the package version, and the git commit of a checkout
        }
        not_used = _config_not_used(env, run, self.evaluator is not None)
        if not_used:
            meta["config_not_used"] = not_used
        if self.evaluator is None:  # no ground truth: evaluate and render-eval's scene checks say so
            meta["source"] = ENVIRONMENT_SOURCE
        return meta

    @property
    def path_length_m(self) -> float:
        return self.forward * self.run.sim.forward_step

    # ------------------------------------------------------------------ the loop
    def step(self, step: int) -> None:
        """Action `step` of the budget: map the current observation, choose the next action, take it and
        record it; then the viewer and the curve point when one is due (after the last action they wait for
        its frame's mapping: `end`), and the progress bar."""
        self.map_observation()
        action = self.choose_action(step)
        self.take_action(step, action)
        if step < self.steps:
            if self.viewer is not None:
                self.viewer.update(step, self.obs, self.mapper, self.explorer, final=False)
            if self.evaluator is not None and self.evaluator.curve_due(step, self.steps):
                self.add_curve_point(step)
        self.show_progress(step)

    def map_observation(self) -> None:
        """Sec. III-A, mapping: the current observation into the Gaussian map (densify, optimize over the
        keyframe window, prune), with the denser schedule while the policy asks for it (not travelling);
        its time and the time of each of its phases counted."""
        obs = self.obs
        frame = self.timers.time("mapper", self.mapper.add_frame, obs.rgb, obs.depth, obs.pose,
                                 dense=self.explorer.dense_mapping)
        for phase, ms in frame.timings.items():
            self.mapper_phases[phase] = self.mapper_phases.get(phase, 0.0) + ms

    def choose_action(self, step: int) -> str:
        """Sec. III-B/C, the policy: it takes in the mapped observation (high-loss samples, eq. 10), learns
        how many actions are left (counting this one), and chooses the next action: the bootstrap
        look-around first, then from its workspace, viewpoints and hierarchical plan. A base with its own
        controller (`env.waypoint`) is told where the planner's path heads."""
        explorer = self.explorer
        explorer.observe_mapping(self.obs, self.env.K)
        explorer.steps_left = self.steps - step + 1
        action = explorer.act(self.obs)
        if hasattr(self.env, "waypoint"):  # a base with its own controller: the planner's next waypoint
            self.env.waypoint(_next_waypoint(explorer))
        return action

    def take_action(self, step: int, action: str) -> None:
        """The environment takes `action` and observes; the action, why it was taken and the new pose go
        to the episode folder (actions.txt, poses.txt), the new pose to the evaluation."""
        before = self.obs.pose
        self.obs = self.timers.time("simulator", self.env.step, action)
        self.forward += action == "move_forward"
        if self.sizes is not None:
            self.sizes.observe(action, before, self.obs.pose, bool(getattr(self.obs, "collided", False)))
        self.actions.append(action)
        self.causes.append(getattr(self.explorer, "last_cause", "") or "policy")
        if self.writer is None:  # the first action: the episode folder is written from here on
            self.writer = EpisodeWriter(self.out_dir, overwrite=self.overwrite)
            self.writer.start(self.meta, self.start_pose)
        self.writer.record(step, action, self.obs.pose)
        if self.evaluator is not None:  # the frame after action `step`: in the curve's point at `step`
            self.timers.time("evaluation", self.evaluator.observe, self.obs.pose)

    def add_curve_point(self, step: int) -> None:
        """A point of the completion curve (docs/protocol.md §6) at `step`: the completion of the frames up
        to the one after action `step`, the path length and the map's size then."""
        at_step = {"path_length_m": self.path_length_m, "n_gaussians": len(self.mapper.gaussians)}
        self.timers.time("evaluation", self.evaluator.curve_point, step, at_step)

    def show_progress(self, step: int) -> None:
        """The progress bar: completion so far (where there is ground truth), time per step, map size."""
        if self.bar is None:
            return
        self.bar.update(1)
        elapsed = time.perf_counter() - self.t_start
        point = self.evaluator.latest() if self.evaluator is not None else None
        done = f"completion {point['completion_ratio_pct']:.1f}% | " if point else ""
        self.bar.set_postfix_str(f"{done}{1000 * elapsed / step:.0f} ms/step | "
                                 f"{len(self.mapper.gaussians)} gaussians")

    def end(self) -> None:
        """After the last action: its observation is mapped too, as every other one (the map's train views);
        the viewer's final update; the last curve point, the episode's result with the final map's size,
        and the evaluation's remaining work waited for (the curve)."""
        self.map_observation()
        if self.viewer is not None:
            self.viewer.update(self.steps, self.obs, self.mapper, self.explorer, final=True)
        if self.evaluator is not None:
            self.add_curve_point(self.steps)
            self.curve = self.timers.time("evaluation", self.evaluator.finish)

    # ------------------------------------------------------------------ the end of the episode
    def interrupted(self) -> Interrupted:
        """Ctrl-C: the episode folder is left consistent and incomplete (the actions and poses so far, the
        map as it is, no metrics.json), the evaluation's worker and the progress bar are stopped, and the
        user is told how to evaluate it; before the first action was recorded, the folder is left as it
        was. Returns the exception to raise, its line printed."""
        if self.evaluator is not None:
            self.evaluator.close()
        if self.bar is not None:
            self.bar.close()
        if self.writer is None:
            return _interrupted("in the first step, before its action", self.out_dir)
        self.writer.close()
        self.save_map()
        return interrupted(f"interrupted after {len(self.actions)} steps: partial episode in {self.out_dir} "
                           f"(evaluate it with: activesplat evaluate {self.out_dir})")

    def finish(self) -> dict:
        """The finished episode: its metrics (`metrics`), the map (`save_map`), completion.png where there is
        a curve, coverage.npz where completion was measured, and last metrics.json, which marks the episode
        complete. Returns the metrics."""
        if self.bar is not None:
            self.bar.close()
        metrics = self.metrics(wall=time.perf_counter() - self.t_start)
        self.save_map()
        if self.curve:
            from activesplat.viz.plots import draw_completion

            draw_completion(self.out_dir / "completion.png", {self.run.policy: self.curve},
                            title=f"{self.label} / {self.run.policy}")
        if self.evaluator is not None:
            self.evaluator.save(self.out_dir)
        self.writer.finish(metrics)
        return metrics

    def metrics(self, wall: float) -> dict:
        """The evaluation's metrics (completion, rooms; none without ground truth), then the behaviour
        (actions by kind and by cause, path length) and the costs (the paper's Tab. VI timings per step,
        the mapper's phases, the map's size, memory), and where completion was measured, the share of it
        each action's frame brought."""
        from activesplat.timing import peak_rss_mb

        steps, run, timers, evaluator = self.steps, self.run, self.timers, self.evaluator
        actions, causes = self.actions, self.causes
        metrics = evaluator.metrics() if evaluator is not None else {}
        per_step = timers.per_step(steps)
        metrics.update({
            "action_counts": action_counts(actions),
            "rotation_pct": rotation_pct(actions),
            "rotation_causes": rotation_causes(actions, causes),
            "path_length_m": self.path_length_m,
            "steps": steps,
            "wall_time_s": wall,
            "ms_per_step": 1000.0 * wall / steps,
            "backend_setup_s": self.setup_s,
            "jit_compile_s": self.jit.total_s,
            "jit_compile_s_by_module": dict(sorted(self.jit.by_module.items())),
            "evaluation_ms_per_step": per_step.get("evaluation", 0.0),
            "simulator_ms_per_step": per_step.get("simulator", 0.0),
            "timing_ms": {k: per_step.get(k, 0.0) for k in TIMING_KEYS},
            "mapper_phases_ms": {k: v / steps for k, v in self.mapper_phases.items()},
            "n_gaussians": len(self.mapper.gaussians),
            "peak_gaussians": self.mapper.peak_gaussians,
            "peak_rss_mb": peak_rss_mb(),
            "scene": self.name, "policy": run.policy, "seed": run.seed,
            "curve": self.curve,
        })
        if self.sizes is not None:  # another environment: what its poses say, beside what the loop assumed
            metrics["measured_action_sizes"] = self.sizes.metrics()
            metrics["path_length_poses_m"] = self.sizes.path_length_m
        if evaluator is not None:
            metrics["evaluation_worker_ms_per_step"] = evaluator.worker_ms / steps
            metrics["evaluation_background"] = evaluator.background
            cov = evaluator.coverage
            metrics["completion_gain"] = completion_gain(cov.gain_by_frame(), actions, causes, len(cov.gt))
        return metrics

    def save_map(self) -> None:
        """gaussians.ply (+ keyframes), the policy's stops.json and topdown.png (the workspace and graph of
        the map as it is now, with the trajectory and the current path) after `len(actions)` actions."""
        from activesplat.planning.controller import floor_xz
        from activesplat.workspace.draw import draw_topdown
        from activesplat.workspace.plan import build_plan

        mapper, explorer = self.mapper, self.explorer
        mapper.save(self.out_dir)
        if getattr(explorer, "failures", None) is not None:
            write_json_atomic(self.out_dir / "stops.json", {"stops": getattr(explorer, "stops", []),
                                                            "replans": getattr(explorer, "replans", []),
                                                            "failures": explorer.failures})
        if len(mapper.gaussians) == 0:
            return
        traj = np.array(explorer.visited) if explorer.visited else None
        here = traj[-1] if traj is not None else floor_xz(np.eye(4))
        plan = build_plan(mapper.gaussians, self.floor_height, here, explorer.cfg.workspace)
        path = explorer.plan.path if explorer.follower is not None else None
        draw_topdown(self.out_dir / "topdown.png", plan.grids, plan.workspace, plan.graph, path=path,
                     trajectory=traj, scene=self.label, step=len(self.actions), policy=explorer.name)


class _SetUp:
    """An exploration's set-up under way (``with _SetUp(out_dir) as setup:``), before the episode folder is
    touched: what it is doing (`phase`, set as it goes) for the one line a Ctrl-C prints; that line says
    that nothing was written, and the command exits with 130 without a line of its own (`Interrupted`). Any
    error stops the live evaluation's worker (`evaluator`), if there is one."""

    def __init__(self, out_dir: Path, evaluator=None):
        self.out_dir, self.evaluator = out_dir, evaluator
        self.phase = "starting"

    def __enter__(self) -> _SetUp:
        return self

    def __exit__(self, kind, exc, tb) -> None:
        if exc is None:
            return
        if self.evaluator is not None:
            self.evaluator.close()
        if isinstance(exc, KeyboardInterrupt) and not isinstance(exc, Interrupted):
            raise _interrupted(f"while {self.phase}", self.out_dir) from None


def _interrupted(when: str, out_dir: Path) -> Interrupted:
    """The `Interrupted` of a Ctrl-C before the first action (`when`), its line printed on stderr."""
    return interrupted(f"interrupted {when}: nothing written to {out_dir}")


def _config_not_used(env, run, ground_truth: bool) -> list[str]:
    """The settings of `run` (dotted paths in its config) an exploration in `env` does not use: in an
    environment other than the run's own simulator, the ``sim`` fields of the simulated camera, renderer
    and navigability (the environment's camera is episode.json's ``camera``; the loop takes from ``sim``
    only the agent's body, sensor height and action sizes, `config.DERIVED`); without ground truth,
    ``coverage``."""
    from dataclasses import fields

    from activesplat.config import DERIVED

    out = []
    if getattr(env, "config", None) != run.sim:
        out += [f"sim.{f.name}" for f in fields(run.sim) if f.name not in DERIVED.values()]
    if not ground_truth:
        out.append("coverage")
    return out


def _warn_if_no_choice(run, stacklevel: int) -> None:
    """A budget that ends within the first look-around leaves the policy nothing to choose: warned about."""
    from activesplat.planning.explorer import bootstrap_actions

    look_around = len(bootstrap_actions(run.explorer))
    if run.steps <= look_around:
        warnings.warn(f"a budget of {run.steps} actions ends within the first look-around ({look_around} "
                      f"actions, the same for every policy): no policy gets to choose anything",
                      stacklevel=stacklevel)


def _prepare_rasterizer(mapper, run, progress: bool) -> float:
    """The one-time loading / compiling of the rasterizer's kernels (announced on a GPU, where gsplat's JIT
    build can take minutes, silently); its seconds."""
    from activesplat.splat.raster import prepare_backend

    if progress and mapper.device.type == "cuda":
        print("loading gsplat's CUDA kernels (the first use after an install compiles them: 1-2 minutes)",
              file=sys.stderr)
    return prepare_backend(mapper.backend, planar_depth=run.mapper.planar_depth)


WARM_UP_SIZE = 32
"""Image side of the made-up view `_warm_up_kernels` maps (pixels)."""


def _warm_up_kernels(run, backend: str) -> float:
    """The kernels the loop would otherwise compile on its first use of them (numba's, in the first run
    after an install or a code change), loaded or compiled before the clock starts: a throwaway map of a
    made-up 32 x 32 view of a slanted wall, seen from three poses with the run's mapper settings, a
    coarser copy of it rendered (the policies' panorama scoring), and the planner's own kernels on tiny
    inputs. The run's random state (torch's) is left as it was, so the actions do not change. Its seconds."""
    import torch

    from activesplat.geometry import intrinsics, voxel_keys
    from activesplat.planning.clusters import grid_dbscan
    from activesplat.splat import Mapper

    t0 = time.perf_counter()
    n = WARM_UP_SIZE
    K = intrinsics(n, n, 90.0)
    v, u = np.mgrid[0:n, 0:n].astype(np.float32)
    depth = (2.0 + (u - n / 2) / n).astype(np.float32)  # a wall 1.5-2.5 m away, slanted
    rgb = np.stack([u * 255 / n, v * 255 / n, np.full_like(u, 128)], axis=-1).astype(np.uint8)
    torch_state = torch.random.get_rng_state()  # the mapper's own generator is its own
    try:
        mapper = Mapper(K, n, n, config=run.mapper, backend=backend)
        for k in range(3):
            yaw = math.radians(5.0 * k)
            pose = np.eye(4)
            pose[[0, 0, 2, 2], [0, 2, 0, 2]] = [math.cos(yaw), math.sin(yaw), -math.sin(yaw), math.cos(yaw)]
            mapper.add_frame(rgb, depth, pose, dense=k % 2 == 0)
        lod = run.explorer.planning.panorama.score_lod_voxel_m
        mapper.snapshot(lod_voxel_m=lod if lod is not None else 0.05)(pose, front_alpha=True)
        grid_dbscan(np.eye(8, dtype=bool), 1.5, 2)
        voxel_keys(np.zeros((2, 3)), 0.05)
        voxel_keys(np.zeros((2, 3), dtype=np.float32), 0.05)
    finally:
        torch.random.set_rng_state(torch_state)
    return time.perf_counter() - t0


def _next_waypoint(explorer) -> np.ndarray | None:
    """The (x, z) world waypoint the explorer's path follower heads for, None when it follows no path."""
    follower = getattr(explorer, "follower", None)
    if follower is None or follower.done:
        return None
    return np.asarray(follower.waypoints[0], dtype=np.float64)


def _evaluation_thread() -> None:
    """Set-up of the live evaluation's worker thread: its ground-truth renders run on itself, not on the
    simulator's shared pool, which stays the loop's."""
    from activesplat.sim.sensor import render_on_this_thread

    render_on_this_thread()


class _Completion:
    """Completion measured on the fly (docs/protocol.md §6): evaluation, not the robot's work; ground-truth
    depth at 128 x 128 rendered by the simulator at every observed pose.

    The loop hands over poses (`observe`) and asks for curve points (`curve_point`); the ground-truth
    renders and KD-tree updates run by batches of `CoverageConfig.batch_frames` poses, in order, either at
    once or on a worker thread (`CoverageConfig.background`), so both give the same numbers. `finish`
    waits for the worker and returns the curve."""

    def __init__(self, sim, coverage, run):
        from activesplat.geometry import intrinsics

        self.sim, self.coverage, self.cfg, self.sim_config = sim, coverage, run.coverage, run.sim
        self.K = intrinsics(self.cfg.resolution, self.cfg.resolution, run.sim.hfov_deg)
        self.positions: list[tuple[float, float]] = []
        self.curve: list[dict] = []
        self.worker_ms = 0.0
        """Milliseconds spent on the renders and KD-tree updates, wherever they ran."""
        self._pending: list[np.ndarray] = []
        background = self.cfg.background
        if background is None:  # only where the map is on a GPU: see CoverageConfig.background
            import numba

            from activesplat.splat.raster import resolve_backend

            background = numba.get_num_threads() >= 2 and resolve_backend(run.backend) == "gsplat"
        self._worker = ThreadPoolExecutor(1, thread_name_prefix="live-evaluation",
                                          initializer=_evaluation_thread) if background else None
        self._jobs: list[Future] = []

    @property
    def background(self) -> bool:
        return self._worker is not None

    def observe(self, pose) -> None:
        self._pending.append(np.array(pose, dtype=np.float64))
        self.positions.append((float(pose[0, 3]), float(pose[2, 3])))

    def curve_due(self, step: int, steps: int) -> bool:
        """A curve point every ``batch_frames`` actions and at the last one."""
        return step % self.cfg.batch_frames == 0 or step == steps

    def curve_point(self, step: int, at_step: dict) -> None:
        """Fold the poses observed so far in, then add the curve point of `step` (`curve`): its completion
        and what the loop knows at that step (`at_step`: path length, the map's size)."""
        self._submit(step, at_step)

    def latest(self) -> dict | None:
        """The newest curve point computed so far (behind by a batch while the worker runs)."""
        return self.curve[-1] if self.curve else None

    def finish(self) -> list[dict]:
        """Fold the remaining poses in, wait for the worker; the curve."""
        self._submit(None, {})
        self._wait()
        return self.curve

    def close(self) -> None:
        """Stop the worker (an interrupted episode): queued batches are dropped."""
        if self._worker is not None:
            self._worker.shutdown(wait=True, cancel_futures=True)

    def _submit(self, step: int | None, at_step: dict) -> None:
        poses, self._pending = self._pending, []
        if self._worker is None:
            self._fold(poses, step, at_step)
            return
        done = [job.done() for job in self._jobs]  # one look at each: a job may finish meanwhile
        for job in (job for job, d in zip(self._jobs, done, strict=True) if d):
            job.result()  # a worker's error surfaces at the next batch, not at the end of the episode
        self._jobs = [job for job, d in zip(self._jobs, done, strict=True) if not d]
        self._jobs.append(self._worker.submit(self._fold, poses, step, at_step))

    def _wait(self) -> None:
        for job in self._jobs:
            job.result()
        self._jobs = []
        if self._worker is not None:
            self._worker.shutdown(wait=True)

    def _fold(self, poses: list[np.ndarray], step: int | None, at_step: dict) -> None:
        t0 = time.perf_counter()
        res = self.cfg.resolution
        for pose in poses:
            self.coverage.add_frame(self.sim.depth(pose, res, res), pose, self.K)
        if step is not None:
            self.curve.append(_curve_point(step, self.coverage, at_step))
        self.worker_ms += 1000.0 * (time.perf_counter() - t0)

    def metrics(self) -> dict:
        """Completion, and for a built-in house the rooms entered and per-room completion."""
        from activesplat.eval.behaviour import room_behaviour

        out = self.coverage.metrics()
        house = self.sim.scene.house
        if house is not None:
            out.update(room_behaviour(house, np.array(self.positions), self.coverage.gt,
                                      self.coverage.completed()))
        return out

    def save(self, out_dir: Path) -> None:
        """coverage.npz: which ground-truth points were completed (packed bits, in sample order), so the
        per-room and ceiling measures can be recomputed later (eval/behaviour.py)."""
        completed = self.coverage.completed()
        np.savez_compressed(out_dir / "coverage.npz", completed=np.packbits(completed), n=len(completed),
                            threshold_m=self.cfg.threshold_m, seed=self.cfg.seed)

    def draw_trajectory(self, out_png: Path, rooms: dict | None, title: str) -> None:
        """trajectory.png; `rooms`: the episode's ``rooms`` metrics (built-in houses), else None."""
        from activesplat.viz.trajectory import draw_trajectory, room_labels

        scene = self.sim.scene
        labels = {}
        if rooms is not None:
            labels = room_labels(scene.house, rooms, {name: room["completion_ratio_pct"]
                                                      for name, room in rooms.get("completion", {}).items()})
        draw_trajectory(out_png, scene.navmap_for(self.sim_config), np.array(self.positions),
                        house=scene.house, room_labels=labels, title=title)


def _curve_point(step: int, coverage, at_step: dict) -> dict:
    m = coverage.metrics(uncapped=False)
    return {"step": step, "completion_ratio_pct": m["completion_ratio_pct"],
            "completion_cm": m["completion_cm"], **at_step}


def format_summary(metrics: dict, out_dir: Path) -> str:
    t = metrics["timing_ms"]
    lines = [
        f"episode      {out_dir}",
        f"scene        {metrics['scene']}  policy {metrics['policy']}  seed {metrics['seed']}",
        f"steps        {metrics['steps']}  ({metrics['ms_per_step']:.0f} ms/step of which "
        f"{metrics['evaluation_ms_per_step']:.0f} live evaluation{_worker_note(metrics)}; "
        f"{metrics['wall_time_s']:.0f} s wall{_setup(metrics)}{_jit(metrics)})",
        f"completion   {metrics['completion_ratio_pct']:.2f} %  |  {metrics['completion_cm']:.2f} cm "
        f"(uncapped {_fmt(metrics['completion_cm_uncapped'])} cm)",
        f"path length  {metrics['path_length_m']:.2f} m",
        f"gaussians    {metrics['n_gaussians']}",
        "time/step    " + "  ".join(f"{k} {t[k]:.1f}" for k in TIMING_KEYS)
        + f"  simulator {metrics.get('simulator_ms_per_step', 0.0):.1f} (ms)",
    ]
    return "\n".join(lines)


def _worker_note(metrics: dict) -> str:
    """The live evaluation's own time, where it ran on a worker thread (the loop waited only for part)."""
    if not metrics.get("evaluation_background"):
        return ""
    return f" (waiting; {metrics['evaluation_worker_ms_per_step']:.0f} on its worker thread)"


JIT_NOTE_S = 1.0
"""Seconds of numba compiling inside the timed loop from which the summary and the benchmark's tables say
that the timings include it."""


def _jit(metrics: dict) -> str:
    """The numba compiling inside the timed loop (the first run after an install or a code change)."""
    jit = metrics.get("jit_compile_s") or 0.0
    if jit < JIT_NOTE_S:
        return ""
    return (f"; {jit:.0f} s of the wall time compiling numba kernels: the first run after an install or a "
            "code change, later runs are faster")


def _setup(metrics: dict) -> str:
    """The kernels' one-time setup before the clock, where it was long enough to matter (a gsplat build,
    numba compiling in the first run after an install or a code change)."""
    setup = metrics.get("backend_setup_s", 0.0)
    return f", after {setup:.0f} s loading the kernels" if setup >= 1.0 else ""


def _fmt(v) -> str:
    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.2f}"


def explore_from_command(cmd) -> int:
    """`activesplat explore`: the episode of an `activesplat.config.ExploreCommand`, and its summary."""
    run = cmd.run
    out = Path(cmd.out) if cmd.out else _default_out(run.scene, run.policy, run.seed)
    viewer = None
    if cmd.viewer:  # viser is imported only here
        from activesplat.viz.viewer import LiveViewer, ViewerConfig

        viewer = LiveViewer(port=cmd.viewer_port, config=ViewerConfig(max_splats=cmd.max_splats))
    try:
        metrics = explore_episode(run, out=out, overwrite=cmd.overwrite, progress=cmd.progress, viewer=viewer)
        print(format_summary(metrics, out))
        if viewer is not None:
            viewer.hold()  # keeps serving the final state until Ctrl-C
    finally:
        if viewer is not None:
            viewer.close()
    return 0
