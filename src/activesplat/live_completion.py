"""Completion measured live, beside the loop (README "What happens in an exploration"): every observation's
pose, from the reset's to the one after the last action, goes to `LiveCompletion`, which renders the
simulator's ground-truth depth there and folds it into the completion measure (docs/protocol.md §6), so
that the progress bar shows completion as the run goes and the episode ends with its completion curve,
per-room measures, coverage.npz and trajectory.png.

It is evaluation, not the robot's work: the policy never sees it, an environment without ground truth (a
robot) has none, and `activesplat evaluate DIR` recomputes the same numbers from the action log alone.
`activesplat.explore.explore_episode` builds it for the simulator and hands it to the loop.
"""

from __future__ import annotations

import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import numpy as np


def _evaluation_thread() -> None:
    """Set-up of the live evaluation's worker thread: its ground-truth renders run on itself, not on the
    simulator's shared pool, which stays the loop's."""
    from activesplat.sim.sensor import render_on_this_thread

    render_on_this_thread()


class LiveCompletion:
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
