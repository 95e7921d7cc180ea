"""`activesplat explore`: the closed loop of the README ("What happens in an exploration"), one episode.

Simulator -> posed RGB-D -> online mapper -> policy (workspace, Voronoi graph, viewpoints, hierarchical
planning) -> action -> simulator, until the step budget is spent. The episode folder is written as the
run goes (see `activesplat.episode`); completion is measured on the fly with the evaluation protocol
(docs/protocol.md §6) so the progress bar shows it, and `activesplat evaluate DIR` recomputes it from
the action log alone.

This module holds the entry points (`run_exploration`, `explore_episode`, `explore_environment`,
`explore_from_command`) and the loop itself (`_Exploration`). Beside it: `activesplat.explore_setup`, the
set-up before the first step (checks, kernels, the Ctrl-C line before anything is written);
`activesplat.live_completion`, the completion measured against the simulator's ground truth as the loop
goes; `activesplat.explore_summary`, the lines printed after it (`format_summary`, also importable from
here).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from activesplat.env import ActionSizeCheck
from activesplat.episode import ENVIRONMENT_SOURCE, EpisodeWriter, software, write_json_atomic
from activesplat.errors import Interrupted, interrupted
from activesplat.eval.behaviour import action_counts, completion_gain, rotation_causes, rotation_pct
from activesplat.explore_setup import (
    SetUp,
    config_not_used,
    interrupted_before_writing,
    prepare_rasterizer,
    warm_up_kernels,
    warn_if_no_choice,
)
from activesplat.explore_summary import TIMING_KEYS, format_summary
from activesplat.live_completion import LiveCompletion
from activesplat.timing import progress_bar


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
    with SetUp(out_dir) as setup:
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
        evaluator = LiveCompletion(sim, coverage, run)
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
    with SetUp(Path(out), evaluator) as setup:
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
                 meta: dict | None, name: str, setup: SetUp):
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
        warn_if_no_choice(run, stacklevel=4)  # attributed to the caller of explore_environment
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
        self.setup_s = prepare_rasterizer(self.mapper, run, progress)  # kept out of the per-step timings
        setup.phase = f"loading the mapper's and the planner's kernels {compiling}"
        self.setup_s += warm_up_kernels(run, self.mapper.backend)
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
        env_seed = getattr(env, "seed", None)  # a simulator's seed chose its start pose, not run.seed
        if isinstance(env_seed, int) and env_seed != run.seed:
            meta["environment_seed"] = env_seed
        not_used = config_not_used(env, run, self.evaluator is not None)
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
        point = self.evaluator.latest() if self.evaluator is not None else None
        self.bar.set_postfix_str(self._progress_text(step, point), refresh=False)
        self.bar.update(1)

    def _progress_text(self, step: int, point: dict | None) -> str:
        elapsed = time.perf_counter() - self.t_start
        done = f"completion {point['completion_ratio_pct']:.1f}% | " if point else ""
        return f"{done}{1000 * elapsed / step:.0f} ms/step | {len(self.mapper.gaussians)} gaussians"

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
        if self.bar is not None:  # its last line shows the final completion, not the last point it had
            self.bar.set_postfix_str(self._progress_text(self.steps, self.curve[-1] if self.curve else None),
                                     refresh=False)

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
            return interrupted_before_writing("in the first step, before its action", self.out_dir)
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


def _next_waypoint(explorer) -> np.ndarray | None:
    """The (x, z) world waypoint the explorer's path follower heads for, None when it follows no path."""
    follower = getattr(explorer, "follower", None)
    if follower is None or follower.done:
        return None
    return np.asarray(follower.waypoints[0], dtype=np.float64)


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
