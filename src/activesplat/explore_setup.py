"""The set-up of an exploration, before the loop's first step (README "What happens in an exploration":
everything before the bootstrap's first action): the checks of the run and the environment that come
before anything is written, and the one-time loading of the kernels the loop uses.

`SetUp` follows what the set-up is doing, so that a Ctrl-C during it prints one line saying that nothing
was written (`interrupted_before_writing`); `config_not_used` lists the settings episode.json records as
unused; `warn_if_no_choice` warns about a budget that ends within the look-around; `prepare_rasterizer`
and `warm_up_kernels` load (or compile) the rasterizer's, the mapper's and the planner's kernels before
the clock starts, so that the per-step timings hold none of it. `activesplat.explore` calls them.
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from activesplat.errors import Interrupted, interrupted


class SetUp:
    """An exploration's set-up under way (``with SetUp(out_dir) as setup:``), before the episode folder is
    touched: what it is doing (`phase`, set as it goes) for the one line a Ctrl-C prints; that line says
    that nothing was written, and the command exits with 130 without a line of its own (`Interrupted`). Any
    error stops the live evaluation's worker (`evaluator`), if there is one."""

    def __init__(self, out_dir: Path, evaluator=None):
        self.out_dir, self.evaluator = out_dir, evaluator
        self.phase = "starting"

    def __enter__(self) -> SetUp:
        return self

    def __exit__(self, kind, exc, tb) -> None:
        if exc is None:
            return
        if self.evaluator is not None:
            self.evaluator.close()
        if isinstance(exc, KeyboardInterrupt) and not isinstance(exc, Interrupted):
            raise interrupted_before_writing(f"while {self.phase}", self.out_dir) from None


def interrupted_before_writing(when: str, out_dir: Path) -> Interrupted:
    """The `Interrupted` of a Ctrl-C before the first action (`when`), its line printed on stderr."""
    return interrupted(f"interrupted {when}: nothing written to {out_dir}")


def config_not_used(env, run, ground_truth: bool) -> list[str]:
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


def warn_if_no_choice(run, stacklevel: int) -> None:
    """A budget that ends within the first look-around leaves the policy nothing to choose: warned about."""
    from activesplat.planning.explorer import bootstrap_actions

    look_around = len(bootstrap_actions(run.explorer))
    if run.steps <= look_around:
        warnings.warn(f"a budget of {run.steps} actions ends within the first look-around ({look_around} "
                      f"actions, the same for every policy): no policy gets to choose anything",
                      stacklevel=stacklevel)


def prepare_rasterizer(mapper, run, progress: bool) -> float:
    """The one-time loading / compiling of the rasterizer's kernels (announced on a GPU, where gsplat's JIT
    build can take minutes, silently); its seconds."""
    from activesplat.splat.raster import prepare_backend

    if progress and mapper.device.type == "cuda":
        print("loading gsplat's CUDA kernels (the first use after an install compiles them: 1-2 minutes)",
              file=sys.stderr)
    return prepare_backend(mapper.backend, planar_depth=run.mapper.planar_depth)


WARM_UP_SIZE = 32
"""Image side of the made-up view `warm_up_kernels` maps (pixels)."""


def warm_up_kernels(run, backend: str) -> float:
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
