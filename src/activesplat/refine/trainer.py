"""Offline refinement of an episode's map from its keyframe buffer (paper sec. III-D4).

``refine(DIR, method, iters)`` loads the online map (``gaussians.ply``), the keyframes (``keyframes.npz``)
and the mapper's settings (``mapper.json``: intrinsics, learning rates) of an episode folder and runs
``iters`` Adam iterations (the folder is read by :mod:`activesplat.refine.episode_map`). Each iteration
renders one keyframe drawn uniformly at random and minimises

    L = w_c ((1 - lambda) L1(C) + lambda (1 - SSIM(C))) + w_d L1(D)   (+ the 2DGS regularisers)

over the pixels with valid depth (the mapper's :func:`~activesplat.splat.losses.mapping_loss` with the
3DGS weights of :class:`~activesplat.refine.config.RefineConfig`), with 3DGS adaptive density control
(:mod:`activesplat.refine.adc`) and the 3DGS position learning-rate decay. 3DGS renders depth the way
the online map was trained (planar depth when its mapper.json says so, ``MapperConfig.planar_depth``);
refine.json records it, and render-eval renders the refined map the same way.

Outputs, in ``DIR/refined_<method>/``: ``gaussians.ply`` (the refined map), ``render_metrics.json``
(train / test PSNR, SSIM, LPIPS, depth L1 from :func:`activesplat.eval.render_eval.render_eval`),
``refine.json`` (settings, timing, loss / PSNR history, density-control totals) and ``checkpoint.pt``.

Resuming: a checkpoint is written every ``checkpoint_every`` iterations, at the end, and when Ctrl-C stops
the run; running the same command again continues from it and gives the same map as an uninterrupted run
(:mod:`activesplat.refine.checkpoint`); ``restart=True`` (``--restart``) starts over. What the command
prints is :mod:`activesplat.refine.summary`.
"""

from __future__ import annotations

import json
import math
import time
import warnings
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch

from activesplat.errors import ActiveSplatError, EpisodeError, check_output_folder, interrupted
from activesplat.refine.adc import DensifyStats, DensityControl, reset_opacity, scene_extent
from activesplat.refine.checkpoint import CHECKPOINT, CtrlC, load_checkpoint, save_checkpoint
from activesplat.refine.config import RefineConfig
from activesplat.refine.episode_map import check_arguments, load_episode_map, rerender_keyframes
from activesplat.refine.methods import make_method
from activesplat.splat.gaussians import GaussianMap
from activesplat.splat.losses import mapping_loss
from activesplat.splat.ply import save_ply
from activesplat.splat.raster import backend_device
from activesplat.timing import progress_bar

HISTORY_EVERY = 50  # iterations between entries of refine.json's loss / PSNR history
OUTPUT_FILES = ("gaussians.ply", "render_metrics.json", "render_grid.png", "refine.json", CHECKPOINT,
                "checkpoint.tmp", "render_budget.json", "render_budget.png")
"""What a run (and render-eval of its folder) writes into DIR/refined_<method>/: --restart removes it all."""


@dataclass
class RefineResult:
    """What a refinement produced."""

    out_dir: Path
    method: str
    iterations: int  # iterations done (== iters unless stopped early)
    iters: int  # iterations asked for
    n_gaussians_initial: int
    n_gaussians: int
    train_seconds: float  # optimisation wall time, summed over resumed sessions
    loss: float  # running mean (EMA) of the loss at the end
    psnr: float  # running mean (EMA) of the PSNR of the trained keyframes (valid-depth pixels)
    densify: dict = field(default_factory=dict)  # totals: cloned, split, pruned
    metrics: dict | None = None  # render_metrics.json, None when not evaluated
    not_evaluated: str | None = None  # why the map was not evaluated although evaluation was asked for

    @property
    def complete(self) -> bool:
        return self.iterations >= self.iters


def output_dir(episode_dir: str | Path, method: str) -> Path:
    """``DIR/refined_<method>``."""
    return Path(episode_dir) / f"refined_{method}"


def _psnr(rgb: torch.Tensor, obs_rgb: torch.Tensor, valid: torch.Tensor) -> float:
    """PSNR (dB, peak 1) over the ``valid`` pixels of a rendered (clamped) image."""
    err = ((rgb.detach().clamp(0.0, 1.0) - obs_rgb) ** 2).mean(dim=2)[valid]
    mse = float(err.mean()) if err.numel() else 0.0
    return 10.0 * math.log10(1.0 / max(mse, 1e-10))


class Refiner:
    """One refinement run of an episode's map (see the module docstring)."""

    def __init__(self, episode_dir: str | Path, method: str = "3dgs", iters: int = 2000,
                 config: RefineConfig | None = None, seed: int = 0, backend: str = "auto",
                 restart: bool = False, progress: bool = True, out_dir: str | Path | None = None,
                 image_size: int | None = None):
        self.episode_dir = check_arguments(episode_dir, method, iters)
        self.method_name, self.iters, self.seed = method, int(iters), int(seed)
        self.cfg = config if config is not None else RefineConfig()
        self.backend, self.progress = backend, progress
        self.out_dir = Path(out_dir) if out_dir is not None else output_dir(self.episode_dir, method)
        # before loading and training: a read-only DIR, or a file named like the output folder, failed at the
        # first checkpoint, after up to ``checkpoint_every`` iterations, or at the end
        check_output_folder(self.out_dir)
        # 3DGS refinement runs where its rasterizer does (the GPU with gsplat); 2DGS surfels on the CPU
        self.device = backend_device(backend) if method == "3dgs" else torch.device("cpu")
        mapper = load_episode_map(self.episode_dir, self.device)
        self.image_size = None if image_size is None else int(image_size)
        if self.image_size is not None:
            mapper = rerender_keyframes(self.episode_dir, mapper, self.image_size)
        self.width, self.height = mapper.width, mapper.height
        self.rgb, self.depth, poses = mapper.rgb, mapper.depth, mapper.poses
        self.n_keyframes = len(poses)
        self.K = torch.from_numpy(mapper.K.astype(np.float32)).to(self.device)
        self.viewmats = torch.from_numpy(np.linalg.inv(poses).astype(np.float32)).to(self.device)
        lam = self.cfg.lambda_dssim
        self.loss_cfg = replace(mapper.config, lambda_l1=1.0 - lam, lambda_ssim=lam,
                                weight_color=self.cfg.weight_color, weight_depth=self.cfg.weight_depth)
        self.lr, self.adam_eps = mapper.config.lr, mapper.config.adam_eps
        planar = mapper.config.planar_depth if self.cfg.planar_depth is None else self.cfg.planar_depth
        self.method = make_method(method, self.cfg, self.iters, backend, planar)
        self.densify_until = self.cfg.densify_until(self.iters)
        extent = scene_extent(torch.from_numpy(poses[:, :3, 3]), self.cfg.extent_margin)
        if restart:
            for name in OUTPUT_FILES:
                (self.out_dir / name).unlink(missing_ok=True)
        if (self.out_dir / CHECKPOINT).is_file():
            load_checkpoint(self, self.out_dir / CHECKPOINT)
            self.resumed = True
        else:
            self._fresh_state(mapper.gaussians, extent)
            self.resumed = False

    # ------------------------------------------------------------------ state
    def _fresh_state(self, online: GaussianMap, extent: float) -> None:
        self.gmap = self.method.prepare(online)
        self.optimizer = self.gmap.make_optimizer(self.lr, self.adam_eps)
        self.adc = DensityControl(self.cfg, extent, len(self.gmap), self.device)
        self.iteration = 0
        self.rng = np.random.default_rng(self.seed)
        self.generator = torch.Generator().manual_seed(self.seed)
        self.ema_loss = self.ema_psnr = None
        self.history: list[dict] = []
        self.totals = {"cloned": 0, "split": 0, "pruned": 0}
        self.train_seconds = 0.0
        self.n_initial = len(self.gmap)
        self.saved_iteration: int | None = None  # the iteration of the checkpoint on disk

    def save_checkpoint(self) -> Path:
        """Write ``checkpoint.pt`` atomically (:func:`activesplat.refine.checkpoint.save_checkpoint`)."""
        return save_checkpoint(self)

    # ------------------------------------------------------------------ training
    def _set_means_lr(self, iteration: int) -> None:
        """3DGS position schedule: log-linear from the mapper's rate to ``means_lr_final_ratio`` x it."""
        t = (iteration - 1) / self.iters
        lr = self.lr.means * self.cfg.means_lr_final_ratio ** t
        for group in self.optimizer.param_groups:
            if group["name"] == "means":
                group["lr"] = lr

    def _observation(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Keyframe ``i``: rgb (H,W,3) in [0,1] and depth (H,W) in metres (0 = invalid)."""
        rgb = torch.from_numpy(self.rgb[i]).to(self.device, torch.float32) / 255.0
        return rgb, torch.from_numpy(self.depth[i]).to(self.device)

    def step(self) -> tuple[float, float]:
        """One iteration (1-based ``self.iteration`` after it); returns (loss, PSNR) of the view."""
        cfg, it = self.cfg, self.iteration + 1
        self._set_means_lr(it)
        idx = int(self.rng.integers(self.n_keyframes))
        obs_rgb, obs_depth = self._observation(idx)
        densifying = it < self.densify_until
        viewmat = self.viewmats[idx]
        out = self.method.render(self.gmap, viewmat, self.K, self.width, self.height, track_grad2d=densifying)
        terms = mapping_loss(out.rgb, out.depth, obs_rgb, obs_depth, self.loss_cfg)
        extra, _ = self.method.regularisers(out, it, self.K)
        loss = terms.total + extra
        self.optimizer.zero_grad(set_to_none=True)
        if torch.isfinite(loss):
            loss.backward()
            if densifying:
                grads, visible = self.method.grad_stats(out, self.gmap, viewmat, self.K, self.width,
                                                        self.height)
                self.adc.accumulate(grads, visible)
            self.optimizer.step()
        else:
            warnings.warn(f"refine: non-finite loss at iteration {it}, step skipped", stacklevel=2)
        if densifying:
            if it > cfg.densify_from_iter and it % cfg.densify_interval == 0:
                stats = self.adc.densify_and_prune(self.gmap, self.optimizer, self.generator,
                                                   prune_big=it > cfg.opacity_reset_interval)
                self._count(stats)
            if it % cfg.opacity_reset_interval == 0:
                reset_opacity(self.gmap, self.optimizer, cfg.opacity_reset_value)
        self.iteration = it
        return float(loss.detach()), _psnr(out.rgb, obs_rgb, obs_depth > 0)

    def _count(self, stats: DensifyStats) -> None:
        for key in self.totals:
            self.totals[key] += getattr(stats, key)

    def _track(self, loss: float, psnr: float) -> None:
        a = self.cfg.psnr_ema
        if math.isfinite(loss):
            self.ema_loss = loss if self.ema_loss is None else a * self.ema_loss + (1 - a) * loss
        self.ema_psnr = psnr if self.ema_psnr is None else a * self.ema_psnr + (1 - a) * psnr
        if self.iteration % HISTORY_EVERY == 0 or self.iteration == self.iters:
            self.history.append({"iteration": self.iteration, "loss": self.ema_loss, "psnr": self.ema_psnr,
                                 "n_gaussians": len(self.gmap)})

    def train(self, stop_at: int | None = None) -> None:
        """Run the remaining iterations (up to ``stop_at`` if given), checkpointing on the way."""
        end = self.iters if stop_at is None else min(self.iters, int(stop_at))
        if self.iteration >= end:
            return
        bar = progress_bar(self.iters, f"refine {self.method_name}", "it", self.progress,
                           initial=self.iteration)
        try:
            with CtrlC(self, bar) as ctrl_c:
                t0 = time.perf_counter()
                while self.iteration < end:
                    loss, psnr = self.step()
                    self._track(loss, psnr)
                    if bar is not None:
                        bar.update(1)
                        if self.iteration % 10 == 0 or self.iteration == end:
                            bar.set_postfix(loss=f"{self.ema_loss:.4f}", psnr=f"{self.ema_psnr:.2f}",
                                            n=len(self.gmap), refresh=False)
                    checkpoint = self.iteration % self.cfg.checkpoint_every == 0 or self.iteration == end
                    if checkpoint or ctrl_c.requested:
                        now = time.perf_counter()
                        self.train_seconds += now - t0
                        t0 = now
                        self.save_checkpoint()
                    if ctrl_c.requested:
                        ctrl_c.stop()
        finally:
            if bar is not None:
                bar.close()

    def keyframe_metrics(self, indices=None) -> dict:
        """Mean PSNR (dB), depth L1 (m) and loss of the current map over keyframes (all by default),
        valid-depth pixels only, without the regularisers. A diagnostic: renders every view."""
        psnrs, depth_l1, losses = [], [], []
        with torch.no_grad():
            for i in range(self.n_keyframes) if indices is None else indices:
                obs_rgb, obs_depth = self._observation(i)
                out = self.method.render(self.gmap, self.viewmats[i], self.K, self.width, self.height)
                terms = mapping_loss(out.rgb, out.depth, obs_rgb, obs_depth, self.loss_cfg)
                psnrs.append(_psnr(out.rgb, obs_rgb, obs_depth > 0))
                depth_l1.append(terms.depth_l1)
                losses.append(float(terms.total))
        return {"psnr": float(np.mean(psnrs)), "depth_l1_m": float(np.mean(depth_l1)),
                "loss": float(np.mean(losses))}

    # ------------------------------------------------------------------ outputs
    def result(self, metrics: dict | None = None) -> RefineResult:
        return RefineResult(self.out_dir, self.method_name, self.iteration, self.iters, self.n_initial,
                            len(self.gmap), self.train_seconds, float(self.ema_loss or float("nan")),
                            float(self.ema_psnr or float("nan")), dict(self.totals), metrics)

    def write_outputs(self) -> Path:
        """``gaussians.ply`` and ``refine.json``; returns the PLY path."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        ply = save_ply(self.method.export(self.gmap), self.out_dir / "gaussians.ply")
        res = self.result()
        rate = self.iteration / res.train_seconds if res.train_seconds else None
        info = {
            "method": self.method_name, "iters": self.iters, "iterations": self.iteration, "seed": self.seed,
            "backend": self.backend, "image_size": [self.width, self.height],
            "n_keyframes": self.n_keyframes, "n_gaussians_initial": res.n_gaussians_initial,
            "n_gaussians": res.n_gaussians, "train_seconds": round(res.train_seconds, 3),
            "iterations_per_second": rate,
            "densify": res.densify, "densify_until": self.densify_until,
            "loss_ema": res.loss, "psnr_ema": res.psnr, "ply_layout": self.method.ply_layout,
            "eval_renderer": self.method.eval_renderer(),
            "planar_depth": bool(getattr(self.method, "planar_depth", False)),
            "config": asdict(self.cfg), "history": self.history,
        }
        (self.out_dir / "refine.json").write_text(json.dumps(info, indent=1))
        return ply

    def evaluate(self, ply: Path, **kwargs) -> dict:
        """Train / test rendering metrics of the refined map, written to ``render_metrics.json``."""
        from activesplat.eval.render_eval import render_eval

        options = {"backend": self.backend, "progress": self.progress, **self.method.eval_kwargs(), **kwargs}
        if self.image_size is not None:  # ground truth at the size the map was refined at
            options["sim_overrides"] = {**options.get("sim_overrides", {}), "width": self.image_size,
                                        "height": self.image_size}
        return render_eval(self.episode_dir, gaussians_path=ply, out_dir=self.out_dir, **options)


def evaluation_blocker(episode_dir: Path) -> str | None:
    """Checked before training: why the refined map of ``episode_dir`` cannot be evaluated (an episode
    explored in an environment without ground truth, e.g. a robot: refined without evaluation), None when
    it can. EpisodeError when the evaluation would fail on a broken episode (no or an unreadable
    episode.json, a scene that does not load), which used to surface only after the last iteration."""
    from activesplat.episode import has_no_ground_truth, is_recorded_map, read_meta
    from activesplat.eval.evaluate import simulated_scene
    from activesplat.eval.render_eval import locate

    locate(episode_dir)
    meta = read_meta(episode_dir)
    if has_no_ground_truth(meta):
        return (f"{episode_dir} was explored in an environment without ground truth ({meta.get('scene')}), "
                f"so there is nothing to render-evaluate the refined map against")
    if not is_recorded_map(meta):
        try:  # the ground truth's scene loads (e.g. a mesh file still where the episode says)
            simulated_scene(meta, episode_dir)
        except ActiveSplatError as err:
            raise EpisodeError(f"{err} (the evaluation after training renders the ground truth from the "
                               f"episode's scene)") from None
    return None


def _metrics_match(metrics: dict, eval_kwargs: dict, size: tuple[int, int]) -> bool:
    """Whether a refined folder's render_metrics.json was measured as this call asks (LPIPS on or off, the
    number of views, the image ``size`` refined at): a completed run then reuses it instead of evaluating
    again."""
    if (metrics.get("width"), metrics.get("height")) != size:
        return False
    wanted_lpips = eval_kwargs.get("lpips", True)
    measured_lpips = not str(metrics.get("protocol", {}).get("lpips", "")).startswith("not measured")
    views = {split: metrics.get(split, {}).get("n_views") for split in ("train", "test")}
    return (measured_lpips == wanted_lpips and views["train"] == eval_kwargs.get("n_train", views["train"])
            and views["test"] == eval_kwargs.get("n_test", views["test"]))


def refine(episode_dir: str | Path, method: str = "3dgs", iters: int = 2000, *,
           config: RefineConfig | None = None, seed: int = 0, backend: str = "auto", restart: bool = False,
           progress: bool = True, evaluate: bool = True, stop_at: int | None = None,
           eval_kwargs: dict | None = None, out_dir: str | Path | None = None,
           image_size: int | None = None) -> RefineResult:
    """Refine the map of ``episode_dir`` offline (see the module docstring); returns what it produced.

    ``stop_at`` stops after that iteration with a checkpoint, as Ctrl-C would (a later call resumes);
    ``evaluate=False`` skips render_metrics.json (so does an episode without ground truth, see
    :func:`evaluation_blocker`; ``RefineResult.not_evaluated`` says why); ``eval_kwargs`` go to
    ``render_eval`` (e.g. n_test); ``out_dir`` replaces ``DIR/refined_<method>`` (e.g. one folder per
    iteration count in a benchmark); ``image_size`` refines (and evaluates) at that square size, the
    keyframes rendered again by the simulator (:func:`rerender_keyframes`; the paper: 512). A completed run
    is not trained again, and its render_metrics.json is reused when it was measured as ``eval_kwargs``
    ask (LPIPS, views), else measured again.
    """
    eval_kwargs = dict(eval_kwargs or {})
    folder = check_arguments(episode_dir, method, iters)
    check_output_folder(out_dir if out_dir is not None else output_dir(folder, method))  # before the scene
    blocker = evaluation_blocker(folder) if evaluate else None
    evaluate = evaluate and blocker is None
    try:
        refiner = Refiner(episode_dir, method, iters, config, seed, backend, restart, progress, out_dir,
                          image_size)
    except KeyboardInterrupt:
        raise interrupted(f"refine: interrupted while loading the map and keyframes of {folder}: nothing "
                          f"written; run the same command again") from None
    metrics_path = refiner.out_dir / "render_metrics.json"
    done_before = refiner.iteration >= refiner.iters and (refiner.out_dir / "gaussians.ply").is_file()
    refiner.train(stop_at)
    if refiner.iteration < refiner.iters:
        return refiner.result()
    saved = json.loads(metrics_path.read_text()) if metrics_path.is_file() else None
    size = (refiner.width, refiner.height)
    if done_before and (not evaluate or (saved is not None and _metrics_match(saved, eval_kwargs, size))):
        return replace(refiner.result(saved), not_evaluated=blocker)
    try:
        ply = refiner.write_outputs()
        metrics = refiner.evaluate(ply, **eval_kwargs) if evaluate else None
    except KeyboardInterrupt:
        raise interrupted(f"refine: interrupted while writing and evaluating the refined map; its "
                          f"{refiner.iters} iterations are saved in {refiner.out_dir / CHECKPOINT}: the same "
                          f"command writes and evaluates it without training again") from None
    return replace(refiner.result(metrics), not_evaluated=blocker)


__all__ = ["CHECKPOINT", "RefineResult", "Refiner", "check_arguments", "evaluation_blocker", "output_dir",
           "refine"]
