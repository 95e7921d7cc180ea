"""A coarser copy of the map for the replan's scoring panoramas (ours; ``PanoramaConfig.score_lod_voxel_m``).

A replan scores every candidate node by a panorama of 3 x 120 x 150 pixels, about 1 degree each, rendered
from the whole map: on a medium house at the end of an episode 0.9 M Gaussians, of which a panorama
camera draws ~300k for its 18,000 pixels. The rasterizer's cost is per drawn Gaussian (projection, depth
sort, tile binning), so the panoramas took as long as the mapper.

:func:`voxel_lod` merges the Gaussians whose centres share a voxel (5 cm by default, a pixel of the
panorama 3 m away) into one that matches the group's first two moments: weights w = opacity x area
(the square root of the sum of the products of squared scales), the weighted mean of the centres, the
weighted mean of (covariance + outer product of the centre) minus the outer product of the mean, the
weighted mean colour, and the opacity 1 - prod(1 - o) of the group (a surface covered by layers stays as
opaque). A voxel with one Gaussian keeps it as it is. The moments of a patch of surface are those of a
uniform square, whose Gaussian fit leaves gaps between neighbouring voxels: the merged covariance is
scaled by ``inflate`` squared (1.3 by default) so that a covered surface still reads as covered. The
panoramas' visible share and hull volume then follow the full map's (docs/exploration.md, "Coarser
panoramas").
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit, prange

from activesplat.geometry import voxel_groups, voxel_keys
from activesplat.splat.gaussians import activate, rgb_to_f_dc
from activesplat.splat.kernels import quat_to_rotmat, rotmat_to_quat

LOD_INFLATE = 1.3
"""The default scale of a merged Gaussian's standard deviations (``PanoramaConfig.score_lod_inflate``)."""


@njit(cache=True, parallel=True)
def _group_moments(order, first, means, rot, scales, opac, colours):
    """Per voxel group (``order`` sorted by voxel, ``first`` marking each group's start): member count,
    weighted mean, weighted second moment about the origin (covariance + outer product), log(1 - o) sum
    and weighted mean colour. Groups in parallel, each summed over its members in order (the same sums
    as one pass over all of them)."""
    starts = np.flatnonzero(first)
    g_count = starts.shape[0]
    ends = np.empty(g_count, np.int64)
    ends[:-1] = starts[1:]
    if g_count:
        ends[-1] = order.shape[0]
    count = ends - starts
    mean = np.zeros((g_count, 3))
    second = np.zeros((g_count, 3, 3))
    log_t = np.zeros(g_count)
    colour = np.zeros((g_count, 3))
    for g in prange(g_count):
        weight = 0.0
        for i in range(starts[g], ends[g]):
            n = order[i]
            # float64 from here on, whatever the inputs' precision (the same values as float64 inputs)
            x = (np.float64(means[n, 0]), np.float64(means[n, 1]), np.float64(means[n, 2]))
            o = np.float64(opac[n])
            s0, s1, s2 = np.float64(scales[n, 0]) ** 2, np.float64(scales[n, 1]) ** 2, \
                np.float64(scales[n, 2]) ** 2
            w = o * np.sqrt(s0 * s1 + s1 * s2 + s0 * s2)
            weight += w
            log_t[g] += np.log1p(-min(o, 0.999999))
            for a in range(3):
                mean[g, a] += w * x[a]
                colour[g, a] += w * np.float64(colours[n, a])
                ra = (np.float64(rot[n, a, 0]), np.float64(rot[n, a, 1]), np.float64(rot[n, a, 2]))
                for b in range(3):
                    cov = (ra[0] * s0 * np.float64(rot[n, b, 0]) + ra[1] * s1 * np.float64(rot[n, b, 1])
                           + ra[2] * s2 * np.float64(rot[n, b, 2]))
                    second[g, a, b] += w * (cov + x[a] * x[b])
        w = max(weight, 1e-30)
        for a in range(3):
            mean[g, a] /= w
            colour[g, a] /= w
            for b in range(3):
                second[g, a, b] /= w
        for a in range(3):
            for b in range(3):
                second[g, a, b] -= mean[g, a] * mean[g, b]
    return count, mean, second, log_t, colour


def voxel_lod(raw: dict[str, torch.Tensor], voxel_m: float,
              inflate: float = LOD_INFLATE) -> dict[str, torch.Tensor]:
    """Raw parameters of the map ``raw`` with the Gaussians of each ``voxel_m`` voxel merged into one
    (module docstring); rows in voxel order, on the device of ``raw``."""
    with torch.no_grad():
        means, quats, scales, opac, rgb = (t.detach().cpu() for t in activate(raw))
        x = means.numpy()  # float32: voxel_keys and the moments work in float64 (no float64 copies)
        order, first = voxel_groups(voxel_keys(x, voxel_m))
        rot = quat_to_rotmat(quats).numpy()
        count, mean, cov, log_t, colour = _group_moments(order, first, x, rot, scales.numpy(), opac.numpy(),
                                                         rgb.numpy())
        multi = count > 1
        cov[multi] *= inflate * inflate
        ev, vec = np.linalg.eigh(cov[multi])
        vec[np.linalg.det(vec) < 0, :, 0] *= -1.0  # a rotation, not a reflection
        leaders = order[first]
        out = {name: t.detach().cpu()[torch.from_numpy(leaders)].clone() for name, t in raw.items()}
        rows = torch.from_numpy(np.flatnonzero(multi))
        opacity = np.clip(-np.expm1(log_t[multi]), 1e-4, 0.999)
        out["means"][rows] = torch.from_numpy(mean[multi]).float()
        out["quats"][rows] = rotmat_to_quat(torch.from_numpy(vec).float())
        out["log_scales"][rows] = torch.from_numpy(0.5 * np.log(np.maximum(ev, 1e-12))).float()
        out["opacity_logits"][rows] = torch.from_numpy(np.log(opacity / (1.0 - opacity))).float()
        out["f_dc"][rows] = rgb_to_f_dc(torch.from_numpy(np.clip(colour[multi], 0.0, 1.0)).float())
    device = raw["means"].device  # the merge runs on the CPU; the copy lives where the map does
    return {name: t.to(device) for name, t in out.items()}
