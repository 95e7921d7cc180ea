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

from activesplat.episode import EpisodeWriter, write_json_atomic
from activesplat.eval.behaviour import action_counts, completion_gain, rotation_causes, rotation_pct

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
    from activesplat.eval.coverage import CoverageAccumulator
    from activesplat.sim import Simulator, load_scene
    from activesplat.sim.scene import BUILTIN_PATTERN, scene_label

    scene_obj = scene if scene is not None else load_scene(run.scene, z_up=run.z_up, floor=run.floor)
    steps = int(run.steps or scene_obj.default_steps)
    run = run.replace(steps=steps)
    if scene is None and not BUILTIN_PATTERN.match(str(run.scene)) and Path(run.scene).is_file():
        # a mesh file by its absolute path: evaluate, render-eval and --config work from any folder
        run = run.replace(scene=str(Path(run.scene).resolve()))
    sim = Simulator(scene_obj, seed=run.seed, config=run.sim)
    out_dir = Path(out) if out is not None else _default_out(run.scene, run.policy, run.seed)
    cov_cfg = run.coverage
    coverage = CoverageAccumulator(scene_obj.sample_surface(cov_cfg.n_gt_points, seed=cov_cfg.seed), cov_cfg)
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
    observation's pose and adds its metrics."""
    import torch

    from activesplat.env import check_observation
    from activesplat.errors import InvalidInputError
    from activesplat.planning.explorer import bootstrap_actions
    from activesplat.planning.policies import make_policy
    from activesplat.sim.scene import scene_label
    from activesplat.splat import Mapper
    from activesplat.splat.raster import prepare_backend, resolve_backend
    from activesplat.timing import Timers, peak_rss_mb

    if not isinstance(run.steps, int) or run.steps <= 0:
        raise InvalidInputError(f"an environment needs a step budget > 0 (run.steps), got {run.steps}")
    steps, seed, policy = run.steps, run.seed, run.policy
    out_dir = Path(out)
    resolve_backend(run.backend)  # a backend this machine cannot run fails before the folder is touched
    writer = EpisodeWriter(out_dir, overwrite=overwrite)
    torch.manual_seed(seed)
    obs = env.reset()
    check_observation(obs, env.width, env.height, "reset()")
    mapper = Mapper(env.K, env.width, env.height, config=run.mapper, backend=run.backend)
    timers = Timers()
    # the floor height comes from the agent's own start pose (its sensor height is known), not the mesh
    floor_height = float(obs.pose[1, 3] - run.sim.sensor_height)
    explorer = make_policy(policy, mapper, floor_height, cfg=run.explorer, timers=timers,
                           frontier=run.frontier)
    look_around = len(bootstrap_actions(run.explorer))
    if steps <= look_around:
        warnings.warn(f"a budget of {steps} actions ends within the first look-around ({look_around} "
                      f"actions, the same for every policy): no policy gets to choose anything", stacklevel=2)
    meta = {
        "scene": name, "scene_name": name, "seed": seed, "policy": policy, "steps": steps,
        "start_pose": np.asarray(obs.pose).tolist(), **(meta or {}), "floor_height": floor_height,
        "backend": mapper.backend, "config": run.to_dict(),
        # the camera the run saw (run.sim describes the simulator's; a robot's may differ)
        "camera": {"width": env.width, "height": env.height, "K": np.asarray(env.K).tolist()},
    }
    if evaluator is None:  # no ground truth: evaluate and render-eval's scene checks say so
        meta["source"] = "environment"
    writer.start(meta, obs.pose)

    curve: list[dict] = []
    actions: list[str] = []
    causes: list[str] = []
    forward = 0
    mapper_phases: dict[str, float] = {}  # ms summed over the episode, per phase of Mapper._map_frame
    # one-time loading / compiling of the rasterizer's kernels, kept out of the per-step timings
    if progress and mapper.device.type == "cuda":  # gsplat's JIT build can take minutes, silently
        print("loading gsplat's CUDA kernels (the first use after an install compiles them: 1-2 minutes)",
              file=sys.stderr)
    setup_s = prepare_backend(mapper.backend, planar_depth=run.mapper.planar_depth)
    t_start = time.perf_counter()
    label = scene_label(name)  # in the progress bar and figure titles
    bar = _progress(steps, label, policy, progress)

    def add_frame() -> None:  # the current observation into the map, its phases timed
        frame = timers.time("mapper", mapper.add_frame, obs.rgb, obs.depth, obs.pose,
                            dense=explorer.dense_mapping)
        for phase, ms in frame.timings.items():
            mapper_phases[phase] = mapper_phases.get(phase, 0.0) + ms

    if evaluator is not None:  # the reset's frame (poses.txt holds steps + 1 frames): the curve's step 0
        timers.time("evaluation", evaluator.observe, obs.pose)
        timers.time("evaluation", evaluator.curve_point, 0, {"path_length_m": 0.0, "n_gaussians": 0})
    try:
        for step in range(1, steps + 1):
            add_frame()
            explorer.observe_mapping(obs, env.K)
            explorer.steps_left = steps - step + 1
            action = explorer.act(obs)
            if hasattr(env, "waypoint"):  # a base with its own controller: the planner's next waypoint
                env.waypoint(_next_waypoint(explorer))
            obs = timers.time("simulator", env.step, action)
            forward += action == "move_forward"
            actions.append(action)
            causes.append(getattr(explorer, "last_cause", "") or "policy")
            writer.record(step, action, obs.pose)
            if evaluator is not None:  # the frame after action `step`: counted in the curve's point at `step`
                timers.time("evaluation", evaluator.observe, obs.pose)
            if viewer is not None and step < steps:  # the last update follows the last frame's mapping
                viewer.update(step, obs, mapper, explorer, final=False)
            if evaluator is not None and step < steps and evaluator.curve_due(step, steps):
                at_step = {"path_length_m": forward * run.sim.forward_step,
                           "n_gaussians": len(mapper.gaussians)}
                timers.time("evaluation", evaluator.curve_point, step, at_step)
            if bar is not None:
                bar.update(1)
                elapsed = time.perf_counter() - t_start
                point = evaluator.latest() if evaluator is not None else None
                done = f"completion {point['completion_ratio_pct']:.1f}% | " if point else ""
                bar.set_postfix_str(f"{done}{1000 * elapsed / step:.0f} ms/step | "
                                    f"{len(mapper.gaussians)} gaussians")
        add_frame()  # the last observation is mapped too, as every other one (the map's train views)
        if viewer is not None:
            viewer.update(steps, obs, mapper, explorer, final=True)
        if evaluator is not None:  # the last curve point: the episode's result, with the final map's size
            timers.time("evaluation", evaluator.curve_point, steps, {
                "path_length_m": forward * run.sim.forward_step, "n_gaussians": len(mapper.gaussians)})
            curve = timers.time("evaluation", evaluator.finish)
    except KeyboardInterrupt:
        writer.close()
        if evaluator is not None:
            evaluator.close()
        if bar is not None:
            bar.close()
        _save_map(mapper, explorer, out_dir, floor_height, scene=label, step=len(actions))
        print(f"\ninterrupted after {len(actions)} steps: partial episode in {out_dir} "
              f"(evaluate it with: activesplat evaluate {out_dir})", file=sys.stderr)
        raise
    if bar is not None:
        bar.close()
    wall = time.perf_counter() - t_start
    metrics = evaluator.metrics() if evaluator is not None else {}
    metrics.update({
        "action_counts": action_counts(actions),
        "rotation_pct": rotation_pct(actions),
        "rotation_causes": rotation_causes(actions, causes),
        "path_length_m": forward * run.sim.forward_step,
        "steps": steps,
        "wall_time_s": wall,
        "ms_per_step": 1000.0 * wall / steps,
        "backend_setup_s": setup_s,
        "evaluation_ms_per_step": timers.per_step(steps).get("evaluation", 0.0),
        "simulator_ms_per_step": timers.per_step(steps).get("simulator", 0.0),
        "timing_ms": {k: timers.per_step(steps).get(k, 0.0) for k in TIMING_KEYS},
        "mapper_phases_ms": {k: v / steps for k, v in mapper_phases.items()},
        "n_gaussians": len(mapper.gaussians),
        "peak_gaussians": mapper.peak_gaussians,
        "peak_rss_mb": peak_rss_mb(),
        "scene": name, "policy": policy, "seed": seed,
        "curve": curve,
    })
    if evaluator is not None:
        metrics["evaluation_worker_ms_per_step"] = evaluator.worker_ms / steps
        metrics["evaluation_background"] = evaluator.background
        cov = evaluator.coverage
        metrics["completion_gain"] = completion_gain(cov.gain_by_frame(), actions, causes, len(cov.gt))
    _save_map(mapper, explorer, out_dir, floor_height, scene=label, step=steps)
    if curve:
        from activesplat.viz.plots import draw_completion

        draw_completion(out_dir / "completion.png", {policy: curve}, title=f"{label} / {policy}")
    if evaluator is not None:
        evaluator.save(out_dir)
    writer.finish(metrics)
    return metrics


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


def _save_map(mapper, explorer, out_dir: Path, floor_height: float, scene: str | None = None,
              step: int | None = None) -> None:
    """gaussians.ply (+ keyframes) and topdown.png of the map as it is now."""
    from activesplat.planning.controller import floor_xz
    from activesplat.workspace.draw import draw_topdown
    from activesplat.workspace.plan import build_plan

    mapper.save(out_dir)
    if getattr(explorer, "failures", None) is not None:
        write_json_atomic(out_dir / "stops.json", {"stops": getattr(explorer, "stops", []),
                                                   "replans": getattr(explorer, "replans", []),
                                                   "failures": explorer.failures})
    traj = np.array(explorer.visited) if explorer.visited else None
    here = traj[-1] if traj is not None else floor_xz(np.eye(4))
    if len(mapper.gaussians) == 0:
        return
    plan = build_plan(mapper.gaussians, floor_height, here, explorer.cfg.workspace)
    path = explorer.plan.path if explorer.follower is not None else None
    draw_topdown(out_dir / "topdown.png", plan.grids, plan.workspace, plan.graph, path=path, trajectory=traj,
                 scene=scene, step=step, policy=explorer.name)


def _worker(metrics: dict) -> str:
    if not metrics.get("evaluation_background"):
        return ""
    return f" (waiting; {metrics['evaluation_worker_ms_per_step']:.0f} on its worker thread)"


def _progress(steps: int, scene: str, policy: str, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=steps, desc=f"{scene} {policy}", unit="step", dynamic_ncols=True,
                file=sys.stderr, mininterval=0.5)


def format_summary(metrics: dict, out_dir: Path) -> str:
    t = metrics["timing_ms"]
    lines = [
        f"episode      {out_dir}",
        f"scene        {metrics['scene']}  policy {metrics['policy']}  seed {metrics['seed']}",
        f"steps        {metrics['steps']}  ({metrics['ms_per_step']:.0f} ms/step of which "
        f"{metrics['evaluation_ms_per_step']:.0f} live evaluation{_worker(metrics)}; "
        f"{metrics['wall_time_s']:.0f} s wall{_setup(metrics)})",
        f"completion   {metrics['completion_ratio_pct']:.2f} %  |  {metrics['completion_cm']:.2f} cm "
        f"(uncapped {_fmt(metrics['completion_cm_uncapped'])} cm)",
        f"path length  {metrics['path_length_m']:.2f} m",
        f"gaussians    {metrics['n_gaussians']}",
        "time/step    " + "  ".join(f"{k} {t[k]:.1f}" for k in TIMING_KEYS)
        + f"  simulator {metrics.get('simulator_ms_per_step', 0.0):.1f} (ms)",
    ]
    return "\n".join(lines)


def _setup(metrics: dict) -> str:
    """The rasterizer's one-time setup, where it was long enough to matter (a gsplat build)."""
    setup = metrics.get("backend_setup_s", 0.0)
    return f", after {setup:.0f} s loading the rasterizer's kernels" if setup >= 1.0 else ""


def _fmt(v) -> str:
    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.2f}"


def explore_from_command(cmd) -> int:
    """`activesplat explore`: the episode of an `activesplat.config.ExploreCommand`, and its summary."""
    run = cmd.run
    out = Path(cmd.out) if cmd.out else _default_out(run.scene, run.policy, run.seed)
    viewer = None
    if cmd.viewer:  # viser is imported only here
        from activesplat.viz.viewer import LiveViewer

        viewer = LiveViewer(port=cmd.viewer_port)
    try:
        metrics = explore_episode(run, out=out, overwrite=cmd.overwrite, progress=cmd.progress, viewer=viewer)
        print(format_summary(metrics, out))
        if viewer is not None:
            viewer.hold()  # keeps serving the final state until Ctrl-C
    finally:
        if viewer is not None:
            viewer.close()
    return 0
