"""Online Gaussian mapper (paper sec. III-A), SplaTAM-style, from posed RGB-D with known poses.

Per accepted frame (``add_frame``), following the schedule of :class:`MapperConfig`:

1. the coarse refresh (a project rule, off by default): Gaussians this view sees whole and much finer
   are made transparent, to be covered anew by step 4 and removed in step 6;
2. render the current view from the map (no grad);
3. high-loss mask, eq. 10 (kept in :attr:`Mapper.high_loss_mask` for the planner; None after a frame that
   was not mapped, so that no one pairs an older frame's mask with the newest pose), before densifying;
4. densification, eq. 8: new Gaussians on the masked pixels;
5. a few Adam iterations over the mapping window (best-overlap keyframes + last keyframe + current
   frame), loss eqs. 5-7;
6. merging of alike Gaussians in the current view (a project rule, off by default), pruning of
   near-transparent and oversized Gaussians, and the Gaussian cap;
7. every ``keyframe_every`` frames, the frame joins the keyframe buffer.

Input checks (:mod:`activesplat.splat.frames`): wrong shapes/dtypes, non-finite poses or colours raise
InvalidInputError and leave the map untouched; NaN/inf/negative depth pixels are treated as invalid (set
to 0); a frame without any valid depth is skipped with a warning.

On disk (``save`` / ``load``): :mod:`activesplat.splat.persistence`.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from activesplat.errors import InvalidInputError
from activesplat.geometry import voxel_keys
from activesplat.splat.config import MapperConfig, Schedule
from activesplat.splat.densify import (
    cap_mask,
    coarse_mask,
    densification_mask,
    free_space_mask,
    gaussians_from_pixels,
    high_loss_mask,
    opacity_test_mask,
    prune_mask,
)
from activesplat.splat.frames import as_intrinsics, as_pose, check_frame, downsample_observation
from activesplat.splat.gaussians import (
    GaussianMap,
    activate,
    back_facing,
    f_dc_to_rgb,
    frustum_rows,
    rgb_to_f_dc,
)
from activesplat.splat.keyframes import Keyframe, mapping_window
from activesplat.splat.lod import LOD_INFLATE
from activesplat.splat.losses import mapping_loss
from activesplat.splat.merge import merge_alike
from activesplat.splat.optim import RowAdam, nonzero_rows
from activesplat.splat.persistence import load_mapper, save_mapper
from activesplat.splat.raster import backend_device
from activesplat.splat.snapshot import MapSnapshot
from activesplat.timing import LapClock


@dataclass
class FrameStats:
    """What one ``add_frame`` call did. ``ms`` is its wall time, ``timings`` per phase (ms)."""

    step: int
    mapped: bool
    keyframe: bool
    skipped: bool
    n_gaussians: int
    added: int = 0
    pruned: int = 0
    refreshed: int = 0  # coarse Gaussians made transparent for the coarse refresh (MapperConfig)
    merged: int = 0  # Gaussians merged into an alike one of the current view (MapperConfig "Merging")
    loss: float | None = None
    ms: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)


def _blank_render(width: int, height: int):
    """What rendering an empty map gives: all zeros (no colour, depth or opacity)."""
    return {"rgb": torch.zeros(height, width, 3), "depth": torch.zeros(height, width),
            "alpha": torch.zeros(height, width), "median_depth": torch.zeros(height, width)}


def _image_size(width, height, what: str) -> tuple[int, int]:
    """(width, height) as positive ints; InvalidInputError naming ``what`` (image, render) otherwise."""
    try:
        size = int(width), int(height)
    except (TypeError, ValueError):
        size = (0, 0)
    if min(size) <= 0:
        raise InvalidInputError(f"{what} size must be positive, got {width!r}x{height!r}")
    return size


class Mapper:
    """Incremental Gaussian map built from posed RGB-D frames (see module docstring)."""

    def __init__(self, K, width: int, height: int, config: MapperConfig | None = None, backend: str = "auto",
                 device: str | torch.device | None = None):
        self.width, self.height = _image_size(width, height, "image")
        self.K = as_intrinsics(K)
        self.config = config if config is not None else MapperConfig()
        self.backend = backend
        self.device = backend_device(backend) if device is None else torch.device(device)
        """Where the map and its optimisation live (default: the GPU with gsplat, else the CPU)."""
        self.gaussians = GaussianMap.empty(self.device)
        self.optimizer = self._make_optimizer()
        self.keyframes: list[Keyframe] = []
        self.high_loss_mask: np.ndarray | None = np.zeros((self.height, self.width), dtype=bool)
        """The eq. 10 mask of the latest frame added, None when that frame was not mapped (or skipped)."""
        self.frames = 0  # accepted (non-skipped) frames
        self.received = 0  # add_frame calls that passed the input checks (the frame index in messages)
        self.broken_depth_frames = 0  # frames with NaN / inf / negative depth pixels (made invalid)
        self.peak_gaussians = 0
        self._rng = np.random.default_rng(self.config.seed)

    # ------------------------------------------------------------------ rendering
    def render(self, pose, K=None, width: int | None = None, height: int | None = None,
               front_alpha: bool = False, behind_margin_deg: float = 0.0):
        """Render the map from camera-to-world ``pose`` (no grad); intrinsics default to the sensor's.

        ``front_alpha``: the returned ``alpha`` (and ``rgb``, grey) counts only what the camera sees of
        surfaces from the side that observed them. A flat Gaussian seen from behind (:func:`back_facing`:
        the far face of a wall, the back of an object) still hides what lies behind it, but adds nothing:
        from inside a room whose door wall was mapped only from the corridor, that wall reads as unseen,
        not as seen in the corridor's colours. Depths are those of every Gaussian. The planner's
        visibility (``PanoramaConfig.front_faces_targets``).
        ``behind_margin_deg``: how far behind a plane the camera must be for its Gaussian to count as seen
        from behind (:func:`back_facing`)."""
        pose, K, width, height = self._camera(pose, K, width, height)
        with torch.no_grad():
            if not front_alpha:
                return self._render(pose, K, width, height)
            rows, behind = self._facing_rows(pose, K, width, height, behind_margin_deg)
            return self._draw_front(pose, K, width, height, activate(self.gaussians.rows(rows)), behind)

    def _camera(self, pose, K, width: int | None,
                height: int | None) -> tuple[np.ndarray, np.ndarray, int, int]:
        """Checked pose and intrinsics of a render, the sensor's where not given."""
        K = self.K if K is None else as_intrinsics(K)
        width, height = _image_size(self.width if width is None else width,
                                    self.height if height is None else height, "render")
        return as_pose(pose), K, width, height

    def _draw_front(self, pose: np.ndarray, K: np.ndarray, width: int, height: int,
                    active: tuple[torch.Tensor, ...], behind: torch.Tensor):
        """The ``front_alpha`` render of :meth:`render` from the activated rows ``active``: colours white,
        black where ``behind`` (through the f_dc round trip of :func:`activate`), alpha = the red channel."""
        grey = f_dc_to_rgb(rgb_to_f_dc((~behind).to(torch.float32)[:, None].expand(-1, 3)))
        out = self._draw(pose, K, width, height, (*active[:4], grey))
        out.alpha = out.rgb[..., 0].clamp(0.0, 1.0)
        return out

    def _render(self, pose: np.ndarray, K: np.ndarray, width: int, height: int,
                rows: torch.Tensor | None = None, raw: dict[str, torch.Tensor] | None = None):
        """Render the Gaussians ``rows`` (default: those in the view frustum, :func:`frustum_rows`), from
        their raw parameters ``raw`` when given (a differentiable copy). The per-Gaussian outputs (radii,
        means2d, depths) are those of the rendered rows."""
        if rows is None:
            rows = self._view_rows(pose, K, width, height)
        if raw is None:
            raw = self.gaussians.rows(rows)
        return self._draw(pose, K, width, height, activate(raw))

    def _draw(self, pose: np.ndarray, K: np.ndarray, width: int, height: int,
              active: tuple[torch.Tensor, ...]):
        """Rasterize the activated parameters ``active`` (:func:`activate`) from camera-to-world ``pose``."""
        from activesplat.splat.rasterize import rasterize

        viewmat = torch.from_numpy(np.linalg.inv(pose).astype(np.float32)).to(self.device)
        Kt = torch.from_numpy(K.astype(np.float32)).to(self.device)
        return rasterize(*active, viewmat, Kt, width, height, backend=self.backend,
                         planar_depth=self.config.planar_depth)

    def snapshot(self, lod_voxel_m: float | None = None, lod_inflate: float = LOD_INFLATE) -> MapSnapshot:
        """A renderer of the map as it is now for many views in a row (a replan's panoramas): the same
        images as :meth:`render`, with the per-Gaussian work done once (``splat.snapshot.MapSnapshot``);
        with ``lod_voxel_m``, of a coarser copy of the map (``splat.lod.voxel_lod``)."""
        return MapSnapshot(self, lod_voxel_m, lod_inflate)

    def _view_rows(self, pose: np.ndarray, K: np.ndarray, width: int, height: int,
                   depth: torch.Tensor | None = None, candidates: torch.Tensor | None = None,
                   params: dict[str, torch.Tensor] | None = None) -> torch.Tensor:
        """The Gaussians a render of this view needs (:func:`frustum_rows`); with the view's observed
        ``depth`` ((height, width), 0 = invalid), not those it hides (``cull_occluded_margin_m``). With
        ``candidates``, only those rows are tested (a superset of the answer: see :func:`frustum_rows`).
        ``params``: other raw parameters than the map's (a snapshot's coarser copy)."""
        p, cfg = self.gaussians.params if params is None else params, self.config
        if cfg.cull_occluded_margin_m is None:
            depth = None
        return frustum_rows(p["means"], p["log_scales"], pose, K, width, height, depth,
                            cfg.cull_occluded_margin_m or 0.0, cfg.cull_window_px, candidates)

    def _make_optimizer(self):
        if self.config.sparse_adam:
            return RowAdam(self.gaussians, self.config.lr, self.config.adam_eps)
        return self.gaussians.make_optimizer(self.config.lr, self.config.adam_eps)

    # ------------------------------------------------------------------ input checks
    def _validate(self, rgb, depth, pose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Checked copies of one frame; InvalidInputError naming the frame (the index of the ``add_frame``
        call) on anything the map cannot take. NaN / inf / negative depth pixels are made invalid (0),
        with a warning the first time it happens."""
        try:
            rgb, depth, pose, broken = check_frame(rgb, depth, pose, self.height, self.width,
                                                   self.config.min_depth_m)
        except InvalidInputError as exc:
            raise InvalidInputError(f"mapper: frame {self.received}: {exc}") from None
        if broken:
            if self.broken_depth_frames == 0:
                warnings.warn(f"mapper: frame {self.received}: {broken} depth pixels are NaN, inf or "
                              f"negative; treated as invalid (later frames are counted in "
                              f"Mapper.broken_depth_frames, not reported)", stacklevel=3)
            self.broken_depth_frames += 1
        return rgb, depth, pose

    # ------------------------------------------------------------------ the per-frame pipeline
    def add_frame(self, rgb, depth, pose, dense: bool = False) -> FrameStats:
        """One simulator step (see module docstring). ``dense`` selects the look-around schedule."""
        t0 = time.perf_counter()
        rgb, depth, pose = self._validate(rgb, depth, pose)
        self.received += 1
        self.high_loss_mask = None  # set again only if this frame is mapped
        if not (depth > 0).any():
            warnings.warn(f"mapper: frame {self.received - 1} has no valid depth, skipped", stacklevel=2)
            return FrameStats(self.frames, False, False, True, len(self.gaussians))
        schedule = self.config.dense_schedule if dense else self.config.schedule
        step = self.frames
        self.frames += 1
        is_map, is_keyframe = step % schedule.map_every == 0, step % schedule.keyframe_every == 0
        stats = FrameStats(step, is_map, is_keyframe, False, 0)
        if stats.mapped:
            self._map_frame(rgb, depth, pose, step, schedule, stats)
        if stats.keyframe:
            self.keyframes.append(Keyframe(rgb, depth, pose, step))
        stats.n_gaussians = len(self.gaussians)
        stats.ms = 1000.0 * (time.perf_counter() - t0)
        return stats

    def _map_frame(self, rgb: np.ndarray, depth: np.ndarray, pose: np.ndarray, step: int, schedule: Schedule,
                   stats: FrameStats) -> None:
        clock = LapClock(stats.timings, sync=torch.cuda.synchronize if self.device.type == "cuda" else None)
        cfg = self.config
        obs_rgb = torch.from_numpy(rgb).to(self.device, torch.float32) / 255.0
        obs_depth = torch.from_numpy(depth).to(self.device)
        coarse, footprint = self._retire_coarse(pose, obs_depth)
        stats.refreshed = int(coarse.numel())
        clock.lap("refresh")
        frustum = front = None
        with torch.no_grad():
            if cfg.densify_front_faces_only:
                frustum, behind = self._facing_rows(pose, self.K, self.width, self.height)
                front = frustum[~behind]
            out = self._render_or_blank(pose, front)
            hl = high_loss_mask(out["alpha"], out["median_depth"], obs_depth, cfg)
            self.high_loss_mask = hl.cpu().numpy()
            new_mask = densification_mask(out["alpha"], out["depth"], obs_depth, cfg)
            if footprint is not None:  # the retired Gaussians' footprint is covered anew, whatever is behind
                new_mask |= footprint & (obs_depth > 0)
        clock.lap("render_masks")
        occupied = self._occupied(pose, front)
        exempt = None
        if occupied is not None and cfg.densify_voxel_depth_test_only:
            exempt = opacity_test_mask(out["alpha"], obs_depth, cfg)
        raw = gaussians_from_pixels(new_mask, obs_rgb, obs_depth, pose, self.K, cfg, occupied, exempt)
        before = len(self.gaussians)
        stats.added = self._append(raw)
        clock.lap("densify")
        window = mapping_window(depth, pose, self.K, self.keyframes, cfg.window_overlap, cfg.overlap_pixels,
                                cfg.overlap_border_px, self._rng)
        clock.lap("window")
        current = (obs_rgb, obs_depth, pose)
        views = [self._pick_view(i, window, current) for i in range(schedule.iterations)]
        candidates = None  # the view's frustum is known: test those rows and the ones added since
        if frustum is not None:
            candidates = torch.cat([frustum, torch.arange(before, len(self.gaussians), dtype=frustum.dtype,
                                                           device=frustum.device)])
        current_rows = self._view_rows(pose, self.K, self.width, self.height, obs_depth, candidates)
        trained = [current_rows]  # the current view is pruned whether or not an iteration trains it
        losses = []
        for i, view in enumerate(views):  # before the first step, the current view's rows are those above
            same = i == 0 and view is current and self.config.train_downscale == 1
            loss, rows = self._optimize_view(view, current_rows if same else None)
            losses.append(loss)
            trained.append(rows)
        stats.loss = float(np.mean(losses)) if losses else None
        clock.lap("optimize")
        touched = torch.zeros(len(self.gaussians), dtype=torch.bool, device=self.device)
        for rows in trained:
            touched[rows] = True
        merged = self._merge(current_rows)
        stats.merged = int(merged.numel())
        stats.pruned = self._prune(torch.nonzero(touched, as_tuple=True)[0], pose, obs_depth, coarse, merged)
        clock.lap("prune")

    def _occupied(self, pose: np.ndarray, rows: torch.Tensor | None) -> np.ndarray | None:
        """Sorted voxel keys (``densify_voxel_m``) of the centres of ``rows`` (default: the view's frustum),
        for the voxel budget; None when it is off."""
        size = self.config.densify_voxel_m
        if size is None:
            return None
        if rows is None:
            rows = self._view_rows(pose, self.K, self.width, self.height)
        means = self.gaussians.params["means"].detach().index_select(0, rows).cpu().numpy()
        return np.unique(voxel_keys(means, size))

    def _facing_rows(self, pose: np.ndarray, K: np.ndarray, width: int, height: int,
                     margin_deg: float = 0.0) -> tuple[torch.Tensor, torch.Tensor]:
        """The Gaussians of this view's frustum (:meth:`_view_rows`) and which of them are flat ones it
        sees from behind (:func:`back_facing`, camera ``margin_deg`` behind their plane)."""
        rows = self._view_rows(pose, K, width, height)
        p = self.gaussians.params
        behind = back_facing(p["quats"].index_select(0, rows), p["log_scales"].index_select(0, rows),
                             p["means"].index_select(0, rows), pose[:3, 3], margin_deg=margin_deg)
        return rows, behind

    def _retire_coarse(self, pose: np.ndarray, obs_depth: torch.Tensor) -> torch.Tensor:
        """The coarse refresh (MapperConfig): the Gaussians in this view that it sees whole and much finer
        (:func:`coarse_mask`) are made fully transparent, so that eq. 8 covers their footprint anew from
        this frame; the pruning at the end of the frame removes them. Returns their rows."""
        if self.config.refresh_coarse_factor is None or len(self.gaussians) == 0:
            return torch.zeros(0, dtype=torch.long, device=self.device), None
        p = self.gaussians.params
        rows = self._view_rows(pose, self.K, self.width, self.height, obs_depth)
        hit = coarse_mask(p["means"].index_select(0, rows), p["log_scales"].index_select(0, rows), pose,
                          self.K, obs_depth, self.config)
        coarse = rows[hit]
        footprint = None
        if coarse.numel():
            with torch.no_grad():
                footprint = self._render_or_blank(pose, coarse)["alpha"] > self.config.refresh_footprint_alpha
                p["opacity_logits"][coarse] = -30.0  # sigmoid ~ 1e-13: below prune_opacity, no weight
        return coarse, footprint

    def _merge(self, rows: torch.Tensor) -> torch.Tensor:
        """Merge the alike Gaussians among ``rows`` (:func:`merge_alike`, MapperConfig "Merging"): each
        group's leader takes the merged parameters (its Adam moments stay), and the rows absorbed into it
        are returned for removal. Empty when the rule is off."""
        cfg = self.config
        if cfg.merge_voxel_m is None:
            return rows[:0]
        merge = merge_alike(self.gaussians.rows(rows), cfg.merge_voxel_m, cfg.merge_normal_deg,
                            cfg.merge_colour_tol, cfg.merge_min_opacity, cfg.merge_scale_ratio)
        if merge.absorbed.numel():
            leaders = rows[merge.leaders]
            with torch.no_grad():
                for name, value in merge.params.items():
                    self.gaussians.params[name][leaders] = value
        return rows[merge.absorbed]

    def _append(self, raw: dict[str, torch.Tensor]) -> int:
        """Add new Gaussians to the map and their (zero) state to the optimiser."""
        if self.config.sparse_adam:
            added = self.gaussians.append(raw)
            self.optimizer.append(added)
            return added
        return self.gaussians.append(raw, self.optimizer)

    def _prune(self, rows: torch.Tensor, pose: np.ndarray, obs_depth: torch.Tensor,
               retired: torch.Tensor | None = None, absorbed: torch.Tensor | None = None) -> int:
        """Pruning, only among ``rows`` (the Gaussians of the current view and of the views trained on
        this frame; nothing else changed): transparent / oversized (:func:`prune_mask`) and floaters in
        the free space the current frame observes (:func:`free_space_mask`), and the ``retired`` rows of
        the coarse refresh; then the optional global cap (:func:`cap_mask`). The ``absorbed`` rows (merged
        into others, :meth:`_merge`) are removed as well but not counted. Returns the number pruned."""
        cfg = self.config
        keep = torch.ones(len(self.gaussians), dtype=torch.bool, device=self.device)
        for gone in (retired, absorbed):
            if gone is not None:
                keep[gone] = False
        if rows.numel():  # the parameters the tests below read, gathered once
            sub = {name: self.gaussians.params[name].detach().index_select(0, rows)
                   for name in ("means", "log_scales", "opacity_logits")}
            ok = prune_mask(sub, cfg)
            if cfg.prune_floater_margin_m is not None:
                ok &= ~free_space_mask(sub["means"], pose, self.K, obs_depth, cfg.prune_floater_margin_m,
                                       cfg.prune_floater_window_px)
            keep[rows] &= ok
        if cfg.max_gaussians is not None:
            keep &= cap_mask(self.gaussians.params["opacity_logits"].detach(), keep, cfg.max_gaussians)
        self.peak_gaussians = max(self.peak_gaussians, len(self.gaussians))
        removed = int((~keep).sum())
        if removed:
            if cfg.sparse_adam:
                self.gaussians.keep(keep)
                self.optimizer.keep(keep)
            else:
                self.gaussians.keep(keep, self.optimizer)
        return removed - (0 if absorbed is None else int(absorbed.numel()))

    def _render_or_blank(self, pose: np.ndarray, rows: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
        """Opacity, depth and median depth of the current view for eqs. 8 and 10, rendered at
        1/``mask_downscale`` resolution and upsampled (nearest) to the sensor size."""
        if len(self.gaussians) == 0:
            return {k: v.to(self.device) for k, v in _blank_render(self.width, self.height).items()}
        d = self.config.mask_downscale
        w, h = -(-self.width // d), -(-self.height // d)
        K = self.K.copy()
        K[:2] /= d
        out = self._render(pose, K, w, h, rows)

        def upsample(t: torch.Tensor) -> torch.Tensor:
            return t.repeat_interleave(d, 0).repeat_interleave(d, 1)[: self.height, : self.width]

        return {name: upsample(getattr(out, name)) for name in ("alpha", "depth", "median_depth")}

    def _pick_view(self, iteration: int, window: list[int], current):
        """Iteration 0 trains the current frame (if so configured); others a random window member."""
        choices = len(window) + 1
        if iteration == 0 and self.config.current_frame_first:
            pick = choices - 1
        else:
            pick = int(self._rng.integers(choices))
        if pick == choices - 1:
            return current
        kf = self.keyframes[window[pick]]
        rgb = torch.from_numpy(kf.rgb).to(self.device, torch.float32) / 255.0
        return rgb, torch.from_numpy(kf.depth).to(self.device), kf.pose

    def _optimize_view(self, view, rows: torch.Tensor | None = None) -> tuple[float, torch.Tensor]:
        """One Adam iteration on one view (at 1/``train_downscale`` resolution), over the Gaussians in its
        frustum only (``rows``, when the caller already has them for this map). Returns the loss and the
        rows that received a gradient (the ones the step moved). A non-finite loss is skipped (the map
        stays as it was)."""
        obs_rgb, obs_depth, pose = view
        d = self.config.train_downscale
        obs_rgb, obs_depth = downsample_observation(obs_rgb, obs_depth, d)
        K = self.K.copy()
        K[:2] /= d
        width, height = obs_depth.shape[1], obs_depth.shape[0]
        if rows is None:
            rows = self._view_rows(pose, K, width, height, obs_depth)
        raw = {name: t.requires_grad_(True) for name, t in self.gaussians.rows(rows).items()}
        out = self._render(pose, K, width, height, rows, raw)
        terms = mapping_loss(out.rgb, out.depth, obs_rgb, obs_depth, self.config)
        if not torch.isfinite(terms.total):
            warnings.warn("mapper: non-finite loss, optimisation step skipped", stacklevel=3)
            return float("nan"), rows[:0]
        terms.total.backward()
        grads = {name: t.grad if t.grad is not None else torch.zeros_like(t) for name, t in raw.items()}
        if self.config.sparse_adam:  # the rows with a non-zero gradient take a step
            touched = self.optimizer.step_nonzero(rows, grads)
        else:  # the release: one torch Adam over the whole map, zero gradient outside the view
            touched = nonzero_rows(grads, len(rows))
            for name, param in self.gaussians.params.items():
                param.grad = torch.zeros_like(param)
                param.grad[rows] = grads[name]
            self.optimizer.step()
            self.optimizer.zero_grad(set_to_none=True)
        return float(terms.total.detach()), rows[touched]

    # ------------------------------------------------------------------ persistence
    def save(self, directory: str | Path) -> Path:
        """Write ``gaussians.ply``, ``keyframes.npz`` and ``mapper.json`` (intrinsics, config) into
        ``directory`` (:mod:`activesplat.splat.persistence`). The Adam state is not saved."""
        return save_mapper(self, directory)

    @classmethod
    def load(cls, directory: str | Path, backend: str | None = None,
             device: str | torch.device | None = None) -> Mapper:
        """Read a folder written by :meth:`save` (fresh Adam state)."""
        return load_mapper(cls, directory, backend, device)
