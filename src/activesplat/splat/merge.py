"""Merging Gaussians that render alike (a project rule, off by default; MapperConfig "Merging").

Two flat Gaussians (surfels) whose centres fall in the same small voxel, that face the same way, have
the same colour, comparable radii and are both opaque draw the same thing twice: a revisit seen from
closer puts a second Gaussian on a surface the map already holds. :func:`merge_alike` finds them among
a set of rows and replaces each such group by one Gaussian that matches the group's first two moments
in the leader's plane (the weighted mean of the centres, and of the in-plane covariances plus the spread
of the centres), with the weighted mean colour and the largest opacity. The mapper applies it to the
Gaussians of the current view after the frame's Adam iterations, so that only what the data left alike
is merged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from activesplat.geometry import voxel_groups, voxel_keys
from activesplat.splat.gaussians import f_dc_to_rgb, is_flat, sigmoid
from activesplat.splat.kernels import quat_normal, quat_to_rotmat, rotmat_to_quat


@dataclass
class Merge:
    """What :func:`merge_alike` decided, in indices into the rows it was given: ``leaders`` take the
    parameters ``params`` (raw, one row per leader), ``absorbed`` are to be removed."""

    leaders: torch.Tensor
    params: dict[str, torch.Tensor]
    absorbed: torch.Tensor


def _leaders(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each row's group leader (the lowest row with the same voxel key) and whether it is a leader."""
    order, first = voxel_groups(keys)  # by voxel, then by row: each group's first is its lowest row
    leader = np.empty(len(keys), np.int64)
    leader[order] = order[first][np.cumsum(first) - 1]
    return leader, leader == np.arange(len(keys))


@torch.no_grad()
def merge_alike(raw: dict[str, torch.Tensor], voxel_m: float, normal_deg: float, colour_tol: float,
                min_opacity: float, scale_ratio: float) -> Merge:
    """Groups of alike Gaussians among ``raw`` (rows of raw parameters) and their merged parameters.

    A row is merged into its voxel's leader (the first row whose centre lies in the same ``voxel_m``
    voxel) when both are flat (:func:`is_flat`), their normals (third rotation axes) are within
    ``normal_deg`` of each other and point the same way, no colour channel differs by more than
    ``colour_tol``, both opacities are above ``min_opacity``, and their in-plane radii differ by at
    most ``scale_ratio``. Weights are opacity times in-plane area. The merged Gaussian keeps the
    leader's plane: its normal (third axis) is the leader's, its in-plane axes and radii match the
    group's covariances and centres projected into that plane, its thickness is the weighted mean."""
    dev = raw["means"].device
    empty = torch.zeros(0, dtype=torch.long, device=dev)
    if raw["means"].shape[0] < 2:
        return Merge(empty, {}, empty)
    leader_np, is_leader = _leaders(voxel_keys(raw["means"].detach().cpu().numpy(), voxel_m))
    cand = torch.from_numpy(np.flatnonzero(~is_leader)).to(dev)  # rows sharing a voxel with a lower row
    if cand.numel() == 0:
        return Merge(empty, {}, empty)
    lead = torch.from_numpy(leader_np[~is_leader]).to(dev)
    pair = torch.cat([cand, lead])  # the tests below on the candidates (first half) and their leaders
    log_s = raw["log_scales"].detach()[pair]
    opac = sigmoid(raw["opacity_logits"].detach()[pair])
    normal = quat_normal(raw["quats"].detach()[pair])
    rgb = f_dc_to_rgb(raw["f_dc"].detach()[pair])
    radius = torch.maximum(log_s[:, 0], log_s[:, 1])
    k = len(cand)
    a, b = slice(0, k), slice(k, 2 * k)
    flat = is_flat(log_s)
    alike = (flat[a] & flat[b] & (opac[a] > min_opacity) & (opac[b] > min_opacity)
             & ((normal[a] * normal[b]).sum(dim=1) > float(np.cos(np.radians(normal_deg))))
             & ((rgb[a] - rgb[b]).abs().amax(dim=1) <= colour_tol)
             & ((radius[a] - radius[b]).abs() <= float(np.log(scale_ratio))))
    absorbed = cand[alike]
    if absorbed.numel() == 0:
        return Merge(empty, {}, empty)
    leaders, slot_of_absorbed = torch.unique(lead[alike], return_inverse=True)
    rows = torch.cat([leaders, absorbed])  # every member of every merged group, leaders first
    slot = torch.cat([torch.arange(len(leaders), device=dev), slot_of_absorbed])

    m = len(leaders)
    s = torch.exp(raw["log_scales"].detach()[rows]).to(torch.float64)
    w = sigmoid(raw["opacity_logits"].detach()[rows]).to(torch.float64) * s[:, 0] * s[:, 1]
    total = torch.zeros(m, dtype=torch.float64, device=dev).index_add_(0, slot, w)

    def group_mean(x: torch.Tensor) -> torch.Tensor:
        """Per group, the mean of the members' ``x`` (leading dimension: ``rows``), weighted by ``w``."""
        shape = (-1,) + (1,) * (x.dim() - 1)
        sums = torch.zeros((m, *x.shape[1:]), dtype=torch.float64, device=dev)
        return sums.index_add_(0, slot, w.view(shape) * x) / total.view(shape)

    mu_k = raw["means"].detach()[rows].to(torch.float64)
    mu = group_mean(mu_k)
    rot = quat_to_rotmat(raw["quats"].detach()[rows]).to(torch.float64)
    # in the leader's plane: the members' in-plane covariances plus the spread of their centres
    plane = rot[:m]  # the leaders' axes (columns: the two in-plane axes and the normal)
    basis = plane[slot][:, :, :2]  # (k, 3, 2)
    cov_k = rot @ torch.diag_embed(s * s) @ rot.transpose(1, 2)
    d = basis.transpose(1, 2) @ (mu_k - mu[slot])[:, :, None]  # (k, 2, 1)
    spread = basis.transpose(1, 2) @ cov_k @ basis + d @ d.transpose(1, 2)
    cov = group_mean(spread)
    eigval, eigvec = torch.linalg.eigh(cov)  # ascending
    in_plane = plane[:, :, :2] @ eigvec.flip(-1)  # (m, 3, 2): the larger axis first
    normal_m = plane[:, :, 2]
    in_plane[:, :, 1] *= torch.where(torch.linalg.det(torch.cat([in_plane, normal_m[:, :, None]], 2)) < 0,
                                     -1.0, 1.0).to(torch.float64)[:, None]
    axes = torch.cat([in_plane, normal_m[:, :, None]], dim=2)
    thickness = group_mean(s[:, 2])
    scales = torch.cat([eigval.flip(-1).clamp_min(1e-18).sqrt(), thickness[:, None]], dim=1)

    f_dc = group_mean(raw["f_dc"].detach()[rows].to(torch.float64))
    logits = raw["opacity_logits"].detach()
    best = torch.full((m,), -torch.inf, dtype=logits.dtype, device=dev).scatter_reduce(
        0, slot, logits[rows], reduce="amax")
    params = {"means": mu.to(torch.float32), "quats": rotmat_to_quat(axes).to(torch.float32),
              "log_scales": scales.log().to(torch.float32), "opacity_logits": best,
              "f_dc": f_dc.to(torch.float32)}
    return Merge(leaders, params, absorbed)
