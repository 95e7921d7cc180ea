"""3DGS adaptive density control: clone, split, prune and opacity reset (Kerbl et al. 2023, sec. 5.2).

Statistic: for every Gaussian, the norm of the view-space gradient of its projected centre, in NDC
units (pixel gradient x W/2, H/2, as 3DGS's CUDA backward and gsplat), summed over the iterations in
which it was in view and divided by that count. Every ``densify_interval`` iterations:

- **clone** the Gaussians whose mean statistic reaches the threshold and whose largest scale is at most
  ``percent_dense`` x extent (under-reconstruction: a copy with the same parameters; the next gradient
  steps pull the two apart);
- **split** those above the threshold that are larger (over-reconstruction): ``split_samples`` children
  drawn from the parent's own Gaussian, scales divided by 0.8 N, the parent removed;
- **prune** the ones with opacity below ``prune_opacity`` and, after the first opacity reset, those larger
  than ``prune_max_extent`` x extent in the world. 3DGS also names a screen-size test (20 px), but its
  ``densification_postfix`` zeroes the screen radii just before the test, so it never fires there; gsplat
  turns it off by default; so does this project;
- and every ``opacity_reset_interval`` iterations, **reset** opacities to at most 0.01 (with fresh Adam
  moments) so that the following iterations can prune what is not needed.

Both rasterizers (3D Gaussians and 2D surfels) return the projected centres ``means2d`` as a node of the
autograd graph, so the statistic is read from ``out.means2d.grad`` after ``backward()``: the gradient of
the loss w.r.t. a screen-space shift of each footprint, as in 3DGS and 2DGS.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from activesplat.refine.config import RefineConfig
from activesplat.splat.gaussians import PARAM_NAMES, GaussianMap
from activesplat.splat.kernels import quat_to_rotmat


def scene_extent(camera_centres: torch.Tensor, margin: float) -> float:
    """3DGS ``cameras_extent``: ``margin`` x the largest distance of a camera centre from their mean."""
    centres = camera_centres.to(torch.float64)
    radius = float((centres - centres.mean(dim=0)).norm(dim=1).max()) if len(centres) else 0.0
    return margin * max(radius, 1e-6)


def ndc_grad_norm(grad_px: torch.Tensor, width: int, height: int) -> torch.Tensor:
    """(N,) norm of a (N,2) pixel-space gradient converted to NDC units (x W/2, y H/2)."""
    scale = grad_px.new_tensor([0.5 * width, 0.5 * height])
    return (grad_px * scale).norm(dim=1)




@dataclass
class DensifyStats:
    """What one density-control step did."""

    cloned: int = 0
    split: int = 0
    pruned: int = 0


class DensityControl:
    """Accumulated view-space gradient statistics and the clone / split / prune / reset operations."""

    def __init__(self, cfg: RefineConfig, extent: float, n: int, device: torch.device | str = "cpu"):
        self.cfg, self.extent = cfg, float(extent)
        self.grad_accum = torch.zeros(n, device=device)
        self.denom = torch.zeros(n, device=device)

    # ------------------------------------------------------------------ statistics
    def accumulate(self, grad_ndc_norm: torch.Tensor, visible: torch.Tensor) -> None:
        """Add one view: ``grad_ndc_norm`` (N,) from :func:`ndc_grad_norm`, ``visible`` (N,) bool."""
        self.grad_accum += torch.where(visible, grad_ndc_norm.to(self.grad_accum), 0.0)
        self.denom += visible.to(self.denom.dtype)

    def mean_grads(self) -> torch.Tensor:
        return self.grad_accum / self.denom.clamp_min(1)

    def reset_stats(self, n: int) -> None:
        device = self.grad_accum.device
        self.grad_accum, self.denom = torch.zeros(n, device=device), torch.zeros(n, device=device)

    def state_dict(self) -> dict:
        return {"grad_accum": self.grad_accum, "denom": self.denom, "extent": self.extent}

    def load_state_dict(self, state: dict) -> None:
        self.grad_accum, self.denom = state["grad_accum"], state["denom"]
        self.extent = float(state["extent"])

    # ------------------------------------------------------------------ the density-control step
    def densify_and_prune(self, gmap: GaussianMap, optimizer: torch.optim.Optimizer,
                          generator: torch.Generator, prune_big: bool) -> DensifyStats:
        """Clone, split, then prune (3DGS ``densify_and_prune``); statistics start again from zero."""
        cfg = self.cfg
        stats = DensifyStats()
        with torch.no_grad():
            grads = self.mean_grads()
            max_scale = gmap.scales.max(dim=1).values
            large = max_scale > cfg.percent_dense * self.extent
            candidates = grads >= cfg.grad_threshold
            clone_mask, split_mask = self._within_budget(len(gmap), grads, candidates & ~large,
                                                         candidates & large)
            stats.cloned = clone(gmap, optimizer, clone_mask)
            # the clones are appended after the originals: pad the split mask with False for them
            split_mask = torch.cat([split_mask, split_mask.new_zeros(stats.cloned)])
            stats.split = split(gmap, optimizer, split_mask, cfg.split_samples, cfg.split_scale_divisor,
                                generator)
            stats.pruned = prune(gmap, optimizer, self.prune_mask(gmap, prune_big))
        self.reset_stats(len(gmap))
        return stats

    def _within_budget(self, n: int, grads: torch.Tensor, clone_mask: torch.Tensor,
                       split_mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Limit clones + splits to the ``max_gaussians`` cap, highest gradients first."""
        cost = clone_mask.long() + split_mask.long() * (self.cfg.split_samples - 1)
        budget = self.cfg.max_gaussians - n
        if int(cost.sum()) <= budget:
            return clone_mask, split_mask
        picked = torch.nonzero(clone_mask | split_mask, as_tuple=True)[0]
        order = picked[torch.argsort(grads[picked], descending=True, stable=True)]
        allowed = order[torch.cumsum(cost[order], 0) <= max(budget, 0)]
        keep = torch.zeros_like(clone_mask)
        keep[allowed] = True
        return clone_mask & keep, split_mask & keep

    def prune_mask(self, gmap: GaussianMap, prune_big: bool) -> torch.Tensor:
        """(N,) bool, True = remove: transparent, and (after the first opacity reset) too large."""
        remove = gmap.opacities < self.cfg.prune_opacity
        if prune_big:
            remove |= gmap.scales.max(dim=1).values > self.cfg.prune_max_extent * self.extent
        return remove


# ---------------------------------------------------------------------- operations on the map
def clone(gmap: GaussianMap, optimizer: torch.optim.Optimizer | None, mask: torch.Tensor) -> int:
    """Append an exact copy of every masked Gaussian (fresh Adam moments). Returns the number added."""
    raw = {name: gmap.params[name].detach()[mask] for name in PARAM_NAMES}
    return gmap.append(raw, optimizer)


def split(gmap: GaussianMap, optimizer: torch.optim.Optimizer | None, mask: torch.Tensor, samples: int,
          scale_divisor: float, generator: torch.Generator) -> int:
    """Replace every masked Gaussian by ``samples`` children whose centres are drawn from the parent
    (mean + R diag(scales) z, z ~ N(0, I)) and whose scales are the parent's / ``scale_divisor``
    (3DGS ``densify_and_split``). Returns the number of parents split."""
    n_split = int(mask.sum())
    if n_split == 0:
        return 0
    p = {name: gmap.params[name].detach()[mask] for name in PARAM_NAMES}
    stds = torch.exp(p["log_scales"]).repeat(samples, 1)
    z = torch.randn(stds.shape, generator=generator, dtype=stds.dtype).to(stds.device)  # CPU generator
    rot = quat_to_rotmat(p["quats"]).repeat(samples, 1, 1)
    children = {
        "means": (rot @ (z * stds).unsqueeze(2)).squeeze(2) + p["means"].repeat(samples, 1),
        "log_scales": torch.log(stds / scale_divisor),
        "quats": p["quats"].repeat(samples, 1),
        "opacity_logits": p["opacity_logits"].repeat(samples),
        "f_dc": p["f_dc"].repeat(samples, 1),
    }
    n_before = len(gmap)
    gmap.append(children, optimizer)
    keep = torch.ones(len(gmap), dtype=torch.bool, device=mask.device)
    keep[:n_before] = ~mask
    gmap.keep(keep, optimizer)
    return n_split


def prune(gmap: GaussianMap, optimizer: torch.optim.Optimizer | None, remove: torch.Tensor) -> int:
    """Remove the Gaussians where ``remove`` is True. Returns the number removed."""
    return gmap.keep(~remove, optimizer)


def reset_opacity(gmap: GaussianMap, optimizer: torch.optim.Optimizer | None, value: float) -> None:
    """3DGS ``reset_opacity``: opacity = min(opacity, value), in place, with zeroed Adam moments."""
    logits = gmap.params["opacity_logits"]
    cap = float(torch.logit(torch.tensor(value, dtype=torch.float64)))
    with torch.no_grad():
        logits.clamp_(max=cap)
    if optimizer is not None:
        state = optimizer.state.get(logits)
        if state:
            state["exp_avg"].zero_()
            state["exp_avg_sq"].zero_()
