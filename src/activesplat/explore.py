"""`activesplat explore`: the closed loop of DESIGN.md, one episode.

Simulator -> posed RGB-D -> online mapper -> policy (workspace, Voronoi graph, viewpoints, hierarchical
planning) -> action -> simulator, until the step budget is spent. The episode folder is written as the
run goes (see `activesplat.episode`); completion is measured on the fly with the evaluation protocol
(REFERENCE.md section 6) so the progress bar shows it, and `activesplat evaluate DIR` recomputes it from
the action log alone.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

from activesplat.episode import EpisodeWriter
from activesplat.errors import InvalidInputError

TIMING_KEYS = ("mapper", "workspace", "voronoi", "subregions", "rotation_selection", "position_selection",
               "planner")
"""Per-module mean ms per step, as the paper's Tab. VI."""


def _default_out(scene: str, policy: str, seed: int) -> Path:
    stem = Path(scene).stem if any(c in scene for c in "/\\.") else scene
    return Path("runs") / f"{stem}-{policy}-s{seed}"


def run_exploration(scene="small-0", policy: str = "activesplat", steps: int | None = None,
                    seed: int = 0, out: str | Path | None = None, overwrite: bool = False, z_up: bool = False,
                    backend: str = "auto", progress: bool = True, explorer_config=None, mapper_config=None,
                    coverage_config=None, sim_config=None, viewer=None, floor=None) -> dict:
    """Explore `scene` (a built-in name, a mesh path or a `Scene`) with `policy` for `steps` actions and write
    the episode folder; returns the metrics (also written to metrics.json). `viewer` (e.g. a
    `viz.viewer.LiveViewer`) gets `update(step, obs, mapper, explorer, final=...)` after every step; None
    (the default) costs nothing."""
    import torch

    from activesplat.eval.coverage import CoverageAccumulator, CoverageConfig
    from activesplat.geometry import intrinsics
    from activesplat.planning.explorer import Timers
    from activesplat.planning.policies import POLICY_NAMES, make_policy
    from activesplat.sim import Scene, SimConfig, Simulator, load_scene
    from activesplat.splat import Mapper

    if policy not in POLICY_NAMES:
        raise InvalidInputError(f"unknown policy {policy!r}; choose one of: {', '.join(POLICY_NAMES)}")
    if steps is not None and steps <= 0:
        raise InvalidInputError(f"--steps must be a positive number of actions, got {steps}")
    scene_obj = scene if isinstance(scene, Scene) else load_scene(scene, z_up=z_up, floor=floor)
    scene = scene_obj.name if isinstance(scene, Scene) else scene
    steps = int(steps or scene_obj.default_steps)
    sim_config = sim_config or SimConfig()
    sim = Simulator(scene_obj, seed=seed, config=sim_config)
    out_dir = Path(out) if out is not None else _default_out(scene, policy, seed)
    writer = EpisodeWriter(out_dir, overwrite=overwrite)

    torch.manual_seed(seed)
    obs = sim.reset()
    mapper = Mapper(sim.K, sim.width, sim.height, config=mapper_config, backend=backend)
    timers = Timers()
    # the floor height comes from the agent's own start pose (its sensor height is known), not the mesh
    floor_height = float(obs.pose[1, 3] - sim_config.sensor_height)
    explorer_config = explorer_config or _explorer_config_for(sim_config)
    explorer = make_policy(policy, mapper, floor_height, cfg=explorer_config, timers=timers)
    cov_cfg = coverage_config or CoverageConfig()
    coverage = CoverageAccumulator(scene_obj.sample_surface(cov_cfg.n_gt_points, seed=cov_cfg.seed), cov_cfg)
    K_eval = intrinsics(cov_cfg.resolution, cov_cfg.resolution, sim_config.hfov_deg)
    meta = {
        "scene": scene, "scene_name": scene_obj.name, "z_up": z_up, "seed": seed, "policy": policy,
        "steps": steps, "start_pose": sim.start_pose.tolist(), "floor_height": floor_height,
        "backend": mapper.backend,
        "floor": floor,  # storey choice of a multi-storey mesh (None: its only storey)
        "config": {"sim": dataclasses.asdict(sim_config), "explorer": _config_dict(explorer.cfg),
                   "mapper": _config_dict(mapper.config), "coverage": dataclasses.asdict(cov_cfg)},
    }
    writer.start(meta, obs.pose)

    curve: list[dict] = []
    forward = 0
    t_start = time.perf_counter()
    bar = _progress(steps, scene_obj.name, policy, progress)
    step = 0
    try:
        for step in range(1, steps + 1):
            _observe(obs, mapper, explorer, coverage, sim, K_eval, cov_cfg, timers)
            action = explorer.act(obs)
            obs = sim.step(action)
            forward += action == "move_forward"
            writer.record(step, action, obs.pose)
            if viewer is not None:
                viewer.update(step, obs, mapper, explorer, final=step == steps)
            if coverage.frames % cov_cfg.batch_frames == 0 or step == steps:
                curve.append(timers.time("evaluation", _curve_point, step, coverage, forward, sim_config))
            if bar is not None:
                bar.update(1)
                elapsed = time.perf_counter() - t_start
                done = curve[-1]["completion_ratio_pct"] if curve else 0.0
                bar.set_postfix_str(f"completion {done:.1f}% | {1000 * elapsed / step:.0f} ms/step | "
                                    f"{len(mapper.gaussians)} gaussians")
        # the last observation counts too (poses.txt holds steps + 1 frames)
        timers.time("evaluation", _count_coverage, coverage, sim, obs.pose, K_eval, cov_cfg)
    except KeyboardInterrupt:
        writer.close()
        if bar is not None:
            bar.close()
        _save_map(mapper, explorer, out_dir, floor_height)
        print(f"\ninterrupted after {step - 1} steps: partial episode in {out_dir} "
              f"(evaluate it with: activesplat evaluate {out_dir})", file=sys.stderr)
        raise
    if bar is not None:
        bar.close()
    wall = time.perf_counter() - t_start
    metrics = coverage.metrics()
    metrics.update({
        "path_length_m": forward * sim_config.forward_step,
        "steps": steps,
        "wall_time_s": wall,
        "ms_per_step": 1000.0 * wall / steps,
        "evaluation_ms_per_step": timers.per_step(steps).get("evaluation", 0.0),
        "timing_ms": {k: timers.per_step(steps).get(k, 0.0) for k in TIMING_KEYS},
        "n_gaussians": len(mapper.gaussians),
        "scene": scene_obj.name, "policy": policy, "seed": seed,
        "curve": curve,
    })
    _save_map(mapper, explorer, out_dir, floor_height)
    from activesplat.viz.plots import draw_completion

    draw_completion(out_dir / "completion.png", {policy: curve}, title=f"{scene_obj.name} / {policy}")
    writer.finish(metrics)
    return metrics


def _observe(obs, mapper, explorer, coverage, sim, K_eval, cov_cfg, timers) -> None:
    """Map the observation, let the policy see the mapping result, and count it for coverage."""
    timers.time("mapper", mapper.add_frame, obs.rgb, obs.depth, obs.pose, dense=explorer.dense_mapping)
    explorer.observe_mapping(obs, sim.K)
    timers.time("evaluation", _count_coverage, coverage, sim, obs.pose, K_eval, cov_cfg)


def _explorer_config_for(sim_config):
    """The planner's knowledge of its own body and actions comes from the robot's configuration."""
    from activesplat.planning.controller import ControllerConfig
    from activesplat.planning.explorer import ExplorerConfig
    from activesplat.workspace.config import WorkspaceConfig

    return ExplorerConfig(
        controller=ControllerConfig(turn_deg=sim_config.turn_deg, look_deg=sim_config.look_deg,
                                    forward_m=sim_config.forward_step),
        workspace=WorkspaceConfig(agent_radius=sim_config.agent_radius, agent_height=sim_config.agent_height),
        panorama_height_m=sim_config.sensor_height)


def _count_coverage(coverage, sim, pose, K_eval, cov_cfg) -> None:
    """Evaluation, not the robot's work: ground-truth depth at 128 x 128 into the completion metric."""
    coverage.add_frame(sim.render(pose, cov_cfg.resolution, cov_cfg.resolution)[1], pose, K_eval)


def _curve_point(step: int, coverage, forward: int, sim_config) -> dict:
    m = coverage.metrics(uncapped=False)
    return {"step": step, "completion_ratio_pct": m["completion_ratio_pct"],
            "completion_cm": m["completion_cm"], "path_length_m": forward * sim_config.forward_step}


def _save_map(mapper, explorer, out_dir: Path, floor_height: float) -> None:
    """gaussians.ply (+ keyframes) and topdown.png of the map as it is now."""
    from activesplat.planning.controller import floor_xz
    from activesplat.planning.explorer import build_plan
    from activesplat.workspace.draw import draw_topdown

    mapper.save(out_dir)
    traj = np.array(explorer.visited) if explorer.visited else None
    here = traj[-1] if traj is not None else floor_xz(np.eye(4))
    if len(mapper.gaussians) == 0:
        return
    plan = build_plan(mapper.gaussians, floor_height, here, explorer.cfg.workspace)
    path = explorer.plan.path if explorer.follower is not None else None
    draw_topdown(out_dir / "topdown.png", plan.grids, plan.workspace, plan.graph, path=path, trajectory=traj,
                 title=f"{explorer.name}: map, Voronoi graph (subregions), trajectory")


def _config_dict(cfg) -> dict:
    try:
        return dataclasses.asdict(cfg)
    except TypeError:
        return {}


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
        f"{metrics['evaluation_ms_per_step']:.0f} live evaluation; {metrics['wall_time_s']:.0f} s wall)",
        f"completion   {metrics['completion_ratio_pct']:.2f} %  |  {metrics['completion_cm']:.2f} cm "
        f"(uncapped {_fmt(metrics['completion_cm_uncapped'])} cm)",
        f"path length  {metrics['path_length_m']:.2f} m",
        f"gaussians    {metrics['n_gaussians']}",
        "time/step    " + "  ".join(f"{k} {t[k]:.1f}" for k in TIMING_KEYS) + " (ms)",
    ]
    return "\n".join(lines)


def _fmt(v) -> str:
    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.2f}"


def explore_from_args(args: argparse.Namespace) -> int:
    out = Path(args.out) if args.out else _default_out(args.scene, args.policy, args.seed)
    viewer = None
    if getattr(args, "viewer", False):  # viser is imported only here
        from activesplat.viz.viewer import LiveViewer

        viewer = LiveViewer(port=args.viewer_port)
    try:
        metrics = run_exploration(scene=args.scene, policy=args.policy, steps=args.steps, seed=args.seed,
                                  out=out, overwrite=args.overwrite, z_up=args.z_up,
                                  floor=getattr(args, "floor", None),
                                  backend=getattr(args, "backend", "auto"),
                                  progress=not getattr(args, "no_progress", False), viewer=viewer)
        print(format_summary(metrics, out))
        if viewer is not None:
            viewer.hold()  # keeps serving the final state until Ctrl-C
    finally:
        if viewer is not None:
            viewer.close()
    return 0
