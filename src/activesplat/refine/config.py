"""Configuration of the offline refinement (paper sec. III-D4, docs/protocol.md §7).

The defaults are the 3DGS recipe (Kerbl et al. 2023, ``arguments/__init__.py``: 30k iterations, densify
every 100 iterations from 500 until 15k, gradient threshold 2e-4, opacity reset every 3000, prune below
opacity 0.005, percent-dense 0.01, position learning rate decayed 100x) and the 2DGS regularisers
(Huang et al. 2024: depth distortion and normal consistency, from iterations 3000 / 7000 of 30k). What
the project changes is written next to the field, with the reason.

**Schedules are given for the 30k-iteration reference run and scaled to shorter runs.** A refinement of
N < 30k iterations (2k on a CPU) keeps the 3DGS densification *interval* (100 iterations: the gradient
statistics need that many views to average over) and start (500), but stops densifying at
``densify_until_frac`` x N (3DGS: 15k of 30k, i.e. half the run, so the map re-converges after the last
split) and starts the 2DGS regularisers at the same share of the run as 2DGS (3000/30000, 7000/30000).
Opacity resets happen only inside the densification window (as 3DGS), so a 2k run has none.

**Gradient threshold.** The accumulated quantity is the norm of the view-space gradient of each
Gaussian's projected centre, averaged over the iterations in which it was in view. The rasterizer gives
that gradient in pixels; 3DGS's threshold 2e-4 is in normalised device coordinates (its CUDA backward
multiplies the pixel gradient by W/2, H/2; gsplat does the same before comparing with 2e-4), so the pixel
gradient is scaled by (W/2, H/2) of the keyframes (128 for our 256x256 images) before the comparison. In
NDC the statistic is roughly independent of the image resolution (the loss is a per-pixel mean), so the
3DGS threshold carries over to our 256x256 keyframes unchanged.

**Scene extent** (3DGS ``cameras_extent``): 1.1 x the largest distance of a keyframe camera centre from
their mean. ``percent_dense`` x extent separates clone (small) from split (large); Gaussians larger than
``prune_max_extent`` x extent are pruned after the first opacity reset (3DGS ``big_points_ws``).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from activesplat.errors import InvalidInputError

METHODS = ("3dgs", "2dgs")
REFERENCE_ITERATIONS = 30_000  # 3DGS / 2DGS default training length (paper: 30,000 iterations)


@dataclass(frozen=True)
class RefineConfig:
    """Every constant of ``activesplat refine`` (see the module docstring for the schedule scaling)."""

    # --- loss: (1 - lambda) L1 + lambda (1 - SSIM) on RGB + w_d L1 on depth, over valid-depth pixels
    lambda_dssim: float = 0.2  # 3DGS lambda_dssim (= the mapper's eq. 5 weights 0.8 / 0.2)
    weight_color: float = 1.0  # 3DGS: the photometric term unscaled (the online mapper's eq. 7 uses 0.5)
    weight_depth: float = 1.0  # paper "with depth loss"; the mapper's eq. 7 w_d (depth in metres)

    # --- depth (3DGS): None = as the online map was trained (MapperConfig.planar_depth in its mapper.json);
    # True / False forces planar / centre depth. On the small-0 episode (1000 steps, 2000 iterations at 256)
    # planar gave test depth L1 1.98 cm against 2.14 (train 0.78 against 0.91) for test PSNR 33.17 against
    # 33.32 dB and LPIPS 0.173 against 0.168 (README, "Offline refinement")
    planar_depth: bool | None = None

    # --- optimiser: the episode's mapper learning rates (mapper.json), plus the 3DGS position decay
    means_lr_final_ratio: float = 0.01  # 3DGS position_lr_final / position_lr_init = 1.6e-6 / 1.6e-4
    # the positions' learning rate decays log-linearly from the mapper's rate to ratio x that rate over
    # the whole run (3DGS get_expon_lr_func with lr_delay_steps = 0)

    # --- adaptive density control (3DGS; iteration numbers of the 30k reference run)
    densify_interval: int = 100  # 3DGS densification_interval
    densify_from_iter: int = 500  # 3DGS densify_from_iter
    densify_until_iter: int = 15_000  # 3DGS densify_until_iter (cap; see densify_until_frac)
    densify_until_frac: float = 0.5  # project: stop at min(15k, frac x N); 3DGS 15k / 30k = 0.5
    grad_threshold: float = 2e-4  # 3DGS densify_grad_threshold, NDC units (pixel gradient x W/2, H/2)
    percent_dense: float = 0.01  # 3DGS: clone if max scale <= 0.01 x extent, else split
    split_samples: int = 2  # N new Gaussians per split (3DGS N = 2)
    split_scale_divisor: float = 1.6  # split children scale / (0.8 N) (3DGS)
    opacity_reset_interval: int = 3000  # 3DGS opacity_reset_interval
    opacity_reset_value: float = 0.01  # 3DGS: opacity = min(opacity, 0.01)
    prune_opacity: float = 0.005  # 3DGS min_opacity
    prune_max_extent: float = 0.1  # 3DGS big_points_ws: max scale > 0.1 x extent (after the 1st reset)
    extent_margin: float = 1.1  # 3DGS getNerfppNorm: radius = 1.1 x max camera distance from the centre
    max_gaussians: int = 1_000_000  # project: CPU memory / time cap; clones and splits stop beyond it

    # --- 2DGS regularisers (Huang et al. 2024, train.py defaults)
    # depth distortion weight. 2DGS uses 100 (TnT) / 1000 (DTU) on NDC depth m = f/(f-n) (1 - n/z),
    # n = 0.2, f = 100; our rasterizer's distortion is in plain metres^2. (dm/dz)^2 = (n/z^2)^2 at a typical
    # indoor depth z = 2.5 m is 1.0e-3, so 2DGS's 100 becomes 100 x 1.0e-3 = 0.1 (project conversion)
    lambda_dist: float = 0.1
    lambda_normal: float = 0.05  # 2DGS normal consistency weight
    dist_from_frac: float = 0.1  # 2DGS: distortion from iteration 3000 of 30k
    normal_from_frac: float = 7000 / 30000  # 2DGS: normal consistency from iteration 7000 of 30k
    surfel_ply_log_thickness: float = -13.815510557964274  # ours: log(1e-6 m), scale_2 of a surfel in the PLY
    # project: surfel orientation at initialisation. A Gaussian clearly flatter along one axis (smallest /
    # middle scale < surfel_flat_ratio) keeps that axis as the normal; a near-isotropic one (the online
    # map's Gaussians start isotropic and stay within a few % of it) takes the normal of the plane fitted
    # (PCA) to its surfel_normal_neighbours nearest centres. 2DGS starts from random rotations and has
    # 30k GPU iterations to turn them; a CPU run of a few thousand iterations does not.
    surfel_flat_ratio: float = 0.8
    surfel_normal_neighbours: int = 16

    # --- bookkeeping
    checkpoint_every: int = 500  # ours: iterations between checkpoints (also at the end and on Ctrl-C)
    psnr_ema: float = 0.98  # ours: smoothing of the progress bar's running loss / PSNR

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "surfel_ply_log_thickness":
                continue
            if isinstance(value, (int, float)) and not isinstance(value, bool) and value < 0:
                raise InvalidInputError(f"RefineConfig.{f.name} must be >= 0, got {value}")
        for name in ("densify_interval", "checkpoint_every", "split_samples", "opacity_reset_interval",
                     "surfel_normal_neighbours"):
            if getattr(self, name) < 1:
                raise InvalidInputError(f"RefineConfig.{name} must be >= 1, got {getattr(self, name)}")
        if not 0.0 <= self.lambda_dssim <= 1.0:
            raise InvalidInputError(f"RefineConfig.lambda_dssim must be in [0, 1], got {self.lambda_dssim}")

    # ------------------------------------------------------------------ schedule of an N-iteration run
    def densify_until(self, iters: int) -> int:
        """Last iteration (exclusive) at which density control runs in an ``iters``-iteration run."""
        return min(self.densify_until_iter, int(round(self.densify_until_frac * iters)))

    def regulariser_start(self, iters: int) -> tuple[int, int]:
        """(distortion start, normal-consistency start) of an ``iters``-iteration 2DGS run."""
        return int(round(self.dist_from_frac * iters)), int(round(self.normal_from_frac * iters))
