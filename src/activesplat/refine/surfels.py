"""The ``2dgs`` refinement: the map as 2D Gaussian surfels (2DGS, Huang et al. SIGGRAPH 2024).

**From the 3D map.** Each 3D Gaussian becomes a surfel spanned by its two largest axes: the columns of
its rotation are reordered so that the two largest scales come first and the smallest axis becomes the
third column, the surfel normal (flipped if needed to keep a proper rotation), and the quaternion is
recomputed from that matrix. A near-isotropic Gaussian has no meaningful smallest axis (the online
map's Gaussians start isotropic and stay within a few per cent of it), so there the normal is that of
the plane fitted to its nearest centres (``RefineConfig.surfel_flat_ratio``, ``surfel_normal_neighbours``).
The parameters stay a :class:`~activesplat.splat.gaussians.GaussianMap` with three log-scales, of
which the surfel rasterizer reads the first two; the third is not used (it receives no gradient) and
is written to the PLY as ``surfel_ply_log_thickness``.

**PLY layout.** ``gaussians.ply`` of a 2dgs run is the standard 3DGS layout with ``scale_2`` =
log(1e-6 m): a flat Gaussian, the common way to show 2DGS surfels in 3DGS viewers. Rendered with the 3D
rasterizer it is close to, not identical with, the surfel render (EWA projection of a flat Gaussian vs
ray-splat intersection), so its metrics are computed with the surfel rasterizer.

**Loss.** The 3dgs loss (RGB L1 + D-SSIM + depth L1) plus the 2DGS regularisers:
``lambda_dist`` x mean depth distortion (the rasterizer's sum_{i<j} w_i w_j (z_i - z_j)^2, in m^2), and
``lambda_normal`` x mean (1 - <N, N_d>), N the rendered normal (sum w_i n_i), N_d the unit normal of the
surface given by the rendered expected depth (sum w_i z_i / O, 2DGS's default depth_ratio 0) by finite
differences, times the (detached) opacity, as 2DGS ``depth_to_normal``. Both start at the share of the
run 2DGS uses (3000 and 7000 of 30k iterations).
"""

from __future__ import annotations

import numpy as np
import torch

from activesplat.refine.config import RefineConfig
from activesplat.refine.methods import Splatting3D
from activesplat.splat.gaussians import GaussianMap
from activesplat.splat.kernels import quat_to_rotmat


def rotmat_to_quat(rot: torch.Tensor) -> torch.Tensor:
    """(N,3,3) proper rotations -> (N,4) unit quaternions wxyz (the largest-component branch per row)."""
    m = rot.to(torch.float64)
    m00, m01, m02 = m[:, 0, 0], m[:, 0, 1], m[:, 0, 2]
    m10, m11, m12 = m[:, 1, 0], m[:, 1, 1], m[:, 1, 2]
    m20, m21, m22 = m[:, 2, 0], m[:, 2, 1], m[:, 2, 2]
    diag = torch.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22,
                        1 - m00 - m11 + m22], 1)
    big = 0.5 * torch.sqrt(diag.clamp_min(1e-12))  # |w|, |x|, |y|, |z| candidates
    cands = torch.stack([
        torch.stack([big[:, 0], (m21 - m12), (m02 - m20), (m10 - m01)], 1),
        torch.stack([(m21 - m12), big[:, 1], (m01 + m10), (m02 + m20)], 1),
        torch.stack([(m02 - m20), (m01 + m10), big[:, 2], (m12 + m21)], 1),
        torch.stack([(m10 - m01), (m02 + m20), (m12 + m21), big[:, 3]], 1),
    ], 1)  # (N, 4 branches, 4): off-diagonal entries still to be divided by 4 x the branch's component
    branch = diag.argmax(dim=1)
    rows = torch.arange(len(m))
    q = cands[rows, branch].clone()
    scale = 1.0 / (4.0 * big[rows, branch])
    for k in range(4):
        off = branch != k
        q[off, k] = q[off, k] * scale[off]
    q = q / q.norm(dim=1, keepdim=True)
    return q.to(rot.dtype)


def neighbour_normals(points: np.ndarray, k: int) -> np.ndarray:
    """(N,3) unit normals of the planes fitted (PCA: the eigenvector of the smallest eigenvalue of the
    neighbourhood covariance) to each point's ``k`` nearest points (itself included)."""
    from scipy.spatial import cKDTree

    points = np.asarray(points, dtype=np.float64)
    k = min(k, len(points))
    if k < 3:
        return np.tile([0.0, 0.0, 1.0], (len(points), 1))
    _, idx = cKDTree(points).query(points, k=k)
    nb = points[idx] - points[idx].mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", nb, nb)
    return np.linalg.eigh(cov)[1][:, :, 0]


def frame_from_normal(normal: torch.Tensor) -> torch.Tensor:
    """(N,3,3) rotations whose third column is ``normal`` (N,3, unit): t1 = normalise(n x a) with a the
    coordinate axis least aligned with n, t2 = n x t1, R = [t1 t2 n] (so t1 x t2 = n)."""
    axis = torch.zeros_like(normal)
    axis[torch.arange(len(normal)), normal.abs().argmin(dim=1)] = 1.0
    t1 = torch.nn.functional.normalize(torch.linalg.cross(normal, axis, dim=1), dim=1)
    t2 = torch.linalg.cross(normal, t1, dim=1)
    return torch.stack([t1, t2, normal], dim=2)


def surfel_raw_from_gaussians(raw: dict[str, torch.Tensor], log_thickness: float, flat_ratio: float = 0.8,
                              neighbours: int = 16) -> dict[str, torch.Tensor]:
    """Raw parameters of the surfels made from 3D Gaussians (module docstring): extents = the two largest
    scales; normal = the smallest axis where the Gaussian is flat (smallest / middle scale <
    ``flat_ratio``), else the PCA normal of its ``neighbours`` nearest centres."""
    log_scales = raw["log_scales"]
    order = torch.argsort(log_scales, dim=1, descending=True, stable=True)  # largest first
    rot = quat_to_rotmat(raw["quats"].to(torch.float64))
    rot = torch.gather(rot, 2, order.unsqueeze(1).expand(-1, 3, 3))  # reorder the columns
    flip = torch.linalg.det(rot) < 0
    rot[flip, :, 2] = -rot[flip, :, 2]
    sorted_scales = torch.gather(log_scales, 1, order)
    round_ = torch.exp(sorted_scales[:, 2] - sorted_scales[:, 1]) >= flat_ratio
    if bool(round_.any()):
        normals = neighbour_normals(raw["means"].detach().cpu().numpy(), neighbours)
        normals_t = torch.from_numpy(normals).to(rot)
        rot[round_] = frame_from_normal(normals_t[round_.to(normals_t.device)])
    out = {k: v.clone() for k, v in raw.items()}
    out["quats"] = rotmat_to_quat(rot).to(raw["quats"].dtype)
    out["log_scales"] = sorted_scales.clone()
    out["log_scales"][:, 2] = log_thickness
    return out


def depth_normals(depth: torch.Tensor, K: torch.Tensor) -> torch.Tensor:
    """(H,W,3) camera-space unit normals of the surface z = ``depth`` (H,W), facing the camera, from
    central differences of the back-projected points (zero on the one-pixel border), as 2DGS."""
    h, w = depth.shape
    v, u = torch.meshgrid(torch.arange(h, dtype=depth.dtype) + 0.5, torch.arange(w, dtype=depth.dtype) + 0.5,
                          indexing="ij")
    x = (u - K[0, 2]) / K[0, 0] * depth
    y = (v - K[1, 2]) / K[1, 1] * depth
    points = torch.stack([x, y, depth], dim=-1)
    down = points[2:, 1:-1] - points[:-2, 1:-1]
    right = points[1:-1, 2:] - points[1:-1, :-2]
    normal = torch.nn.functional.normalize(torch.linalg.cross(down, right, dim=-1), dim=-1)
    return torch.nn.functional.pad(normal.permute(2, 0, 1), (1, 1, 1, 1)).permute(1, 2, 0)


class Surfels2D(Splatting3D):
    """2D Gaussian surfel splatting (2DGS) with depth-distortion and normal-consistency regularisers."""

    name = "2dgs"
    ply_layout = ("2dgs: the 3DGS layout, scale_0/1 the surfel extents, scale_2 = log(1e-6 m), "
                  "rot = tangent frame (third column = normal)")

    def __init__(self, cfg: RefineConfig, iters: int, backend: str = "auto"):
        super().__init__(cfg, iters, backend)
        # the surfel rasterizer has numba (CPU) and torch backends; "auto"/"numba"/"gsplat" -> its default
        self.surfel_backend = "torch" if backend == "torch" else "auto"
        self.dist_from, self.normal_from = cfg.regulariser_start(iters)

    def prepare(self, gmap: GaussianMap) -> GaussianMap:
        cfg = self.cfg
        return GaussianMap(surfel_raw_from_gaussians(gmap.raw(), cfg.surfel_ply_log_thickness,
                                                     cfg.surfel_flat_ratio, cfg.surfel_normal_neighbours))

    def render(self, gmap: GaussianMap, viewmat: torch.Tensor, K: torch.Tensor, width: int, height: int,
               track_grad2d: bool = False):
        from activesplat.splat.surfel import rasterize_surfels

        out = rasterize_surfels(gmap.means, gmap.quats, gmap.scales[:, :2], gmap.opacities, gmap.colors,
                                viewmat, K, width, height, backend=self.surfel_backend)
        if track_grad2d and out.means2d.requires_grad:
            out.means2d.retain_grad()
        return out

    def regularisers(self, out, iteration: int, K: torch.Tensor) -> tuple[torch.Tensor | float, dict]:
        """2DGS: lambda_dist x mean distortion (after the distortion start), lambda_normal x mean
        (1 - <N, N_d O>) (after the normal start); both 0 before (no extra render work)."""
        total, terms = 0.0, {}
        if iteration > self.dist_from and self.cfg.lambda_dist > 0:
            dist = out.distortion.mean()
            total = total + self.cfg.lambda_dist * dist
            terms["distortion"] = float(dist.detach())
        if iteration > self.normal_from and self.cfg.lambda_normal > 0:
            err = normal_error(out.depth, out.alpha, out.normal, K)
            total = total + self.cfg.lambda_normal * err
            terms["normal"] = float(err.detach())
        return total, terms

    def export(self, gmap: GaussianMap) -> GaussianMap:
        raw = gmap.raw()
        raw["log_scales"][:, 2] = self.cfg.surfel_ply_log_thickness
        return GaussianMap(raw)

    def eval_kwargs(self) -> dict:
        """Render the evaluation views with the surfel rasterizer (not the 3D one the flat PLY suggests)."""
        return {"renderer": render_surfel_view}

    def eval_renderer(self) -> str:
        return "surfel rasterizer"


def render_surfel_view(gmap: GaussianMap, pose: np.ndarray, K: np.ndarray, width: int, height: int,
                       backend: str = "auto") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Render a surfel map (a 2dgs ``gaussians.ply`` loaded as a GaussianMap; the first two scales are
    the surfel extents) from camera-to-world ``pose``: (rgb clamped to [0,1], depth sum w z, alpha) as
    numpy arrays, the evaluation's renderer interface."""
    from activesplat.splat.surfel import rasterize_surfels

    dev = gmap.means.device
    viewmat = torch.from_numpy(np.linalg.inv(pose).astype(np.float32)).to(dev)
    Kt = torch.from_numpy(np.asarray(K, dtype=np.float32)).to(dev)
    with torch.no_grad():
        out = rasterize_surfels(gmap.means, gmap.quats, gmap.scales[:, :2], gmap.opacities, gmap.colors,
                                viewmat, Kt, width, height, backend="torch" if backend == "torch" else "auto")
    return (out.rgb.clamp(0.0, 1.0).cpu().numpy(), out.depth.cpu().numpy().astype(np.float64),
            out.alpha.cpu().numpy().astype(np.float64))


def normal_error(depth: torch.Tensor, alpha: torch.Tensor, normal: torch.Tensor,
                 K: torch.Tensor) -> torch.Tensor:
    """2DGS normal consistency, mean over pixels of 1 - <N, N_d O>: N the rendered (blended) normal,
    N_d the depth normal of the expected depth sum w z / O, O the detached opacity."""
    expected = depth / alpha.clamp_min(1e-6)
    surface = depth_normals(expected, K.to(depth)) * alpha.detach().unsqueeze(-1)
    return (1.0 - (normal * surface).sum(dim=-1)).mean()
