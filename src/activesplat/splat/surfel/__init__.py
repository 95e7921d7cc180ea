"""2D Gaussian surfels (2DGS, Huang et al. SIGGRAPH 2024): ``rasterize_surfels(...)``.

A surfel is a flat elliptic Gaussian disc: centre ``means[i]``, tangent axes the first two columns
t_u, t_v of R(q), extents (s_u, s_v) = ``scales[i]``, normal the third column of R(q). Backends:

- ``"numba"``: tile-based CPU rasterizer with an analytic backward pass (the default, ``"auto"``;
  ``numba_backend`` with the kernels ``numba_project`` and ``numba_tiles``).
- ``"torch"``: slow, literal reference in plain torch autograd (``torch_ref``, used by tests).

Forward model (2DGS eqs. 8-11). In camera space a point of the surfel is P(u, v) = p_c + u s_u t_u +
v s_v t_v = H (u, v, 1)^T; its homogeneous pixel is T (u, v, 1)^T with T = K H (the "KWH" transform).
The ray through pixel centre x = (j + 0.5, i + 0.5) is the intersection of the planes h_x = (-1, 0, x)
and h_y = (0, -1, y); in (u, v, 1) coordinates they are h_u = T^T h_x, h_v = T^T h_y and the ray-splat
intersection is (u, v) = (c_0 / c_2, c_1 / c_2) with c = h_u x h_v. A pixel sees
G = max(exp(-(u^2 + v^2) / 2), exp(-|x - c_2d|^2)) (the 2DGS low-pass, sigma = sqrt(2)/2 px around the
projected centre c_2d); its depth is the view z of the intersection point where the ray-splat term wins
and the centre's z where the low-pass wins (2DGS ``diff-surfel-rasterization``).

Compositing has the 3D rasterizer's semantics (docs/protocol.md §8): alpha_i = min(0.99, o_i G), skipped below
1/255, front to back by centre view depth (stable), a pixel stops before the surfel that would bring T
below 1e-4; rgb = sum w_i c_i + background T, depth = sum w_i z_i (not normalised), alpha = 1 - T,
median_depth = z where T first drops below 0.5 (0 if never), with w_i = alpha_i T_i.
normal = sum w_i n_i with n_i the camera-space surfel normal flipped to face the camera (not normalised).
distortion = sum_{i<j} w_i w_j (z_i - z_j)^2 over the blended surfels of a pixel (half the symmetric
double sum of 2DGS eq. 13), with z the **plain view depth in metres** of each ray-splat intersection
(2DGS maps depth to NDC first; plain z keeps the term in m^2 whatever the near/far planes), evaluated
in one front-to-back pass as sum_i w_i (z_i^2 A_i - 2 z_i D1_i + D2_i), A_i = 1 - T_i, D1_i, D2_i the
running sums of w z, w z^2 (the 2DGS CUDA form).

Culling: a surfel renders only where its opacity exceeds 1/255 and its whole alpha >= 1/255 disc
(radius sqrt(2 ln(255 o)) in (u, v)) lies beyond the near plane (0.01 m): every ray-splat intersection
that can contribute is then in front of the camera. Surfels crossing the near plane are dropped for that
view (as 3DGS drops Gaussians whose centre is behind it). Each surfel touches exactly the tiles of the
screen box of that footprint (ellipse box of the disc, union the low-pass disc), so tiling never
changes the image. Pixel (row i, column j) has its centre at (j + 0.5, i + 0.5) in the image plane of K.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from torch import Tensor

from activesplat.errors import InvalidInputError
from activesplat.splat.kernels import check_ranges, check_size, check_tensors
from activesplat.splat.raster import RenderOutput

SurfelBackend = Literal["auto", "numba", "torch"]
SURFEL_BACKENDS = ("auto", "numba", "torch")


@dataclass
class SurfelRenderOutput(RenderOutput):
    """Images rendered from one camera plus per-surfel metadata: the fields of :class:`RenderOutput`
    (rgb, depth = sum w_i z_i with z_i the view depth of the ray-splat intersection, alpha,
    median_depth, radii, means2d, depths) plus ``normal`` and ``distortion``. Images are float32 from
    numba and in the input dtype from the torch reference.

    ``radii`` is the farthest screen-box edge from the projected centre (0 = culled: through the near
    plane, too transparent or off-screen). ``means2d`` is a node of the autograd graph: call
    ``out.means2d.retain_grad()`` before ``backward()`` to read the gradient of the loss w.r.t. a
    screen-space shift of each surfel's footprint (pixels; the statistic densification accumulates).
    """

    normal: Tensor
    """(H, W, 3) sum w_i n_i, camera-space (OpenCV axes) normals flipped to face the camera (not
    normalised: divide by alpha for unit-ish normals)."""
    distortion: Tensor
    """(H, W) depth distortion sum_{i<j} w_i w_j (z_i - z_j)^2 in m^2 (plain view depth, see module doc)."""


def rasterize_surfels(
    means: Tensor,
    quats: Tensor,
    scales: Tensor,
    opacities: Tensor,
    colors: Tensor,
    viewmat: Tensor,
    K: Tensor,
    width: int,
    height: int,
    background: Tensor | None = None,
    backend: SurfelBackend = "auto",
) -> SurfelRenderOutput:
    """Render N 2D Gaussian surfels into a (height, width) pinhole camera (2DGS; see the module doc).

    means (N,3) world; quats (N,4) wxyz (normalised here); scales (N,2) linear extents along the first
    two columns of R(q) (the third column is the normal); opacities (N,) in [0,1]; colors (N,3);
    viewmat (4,4) world-to-camera, OpenCV axes; K (3,3); background (3,) colour (default black).
    Differentiable in means, quats, scales, opacities, colors through rgb, depth, alpha, normal and
    distortion. Raises InvalidInputError on wrong shapes, NaN/inf values or an unknown backend.
    """
    check_size("rasterize", width, height)
    tensors = _check_tensors(means, quats, scales, opacities, colors, viewmat, K, background)
    if backend not in SURFEL_BACKENDS:
        raise InvalidInputError(
            f"unknown surfel rasterizer backend {backend!r}; expected one of {SURFEL_BACKENDS}")
    if backend == "torch":
        from activesplat.splat.surfel.torch_ref import rasterize_surfels_torch as render
    else:
        from activesplat.splat.surfel.numba_backend import rasterize_surfels_numba as render
    return render(*tensors, width, height)


_SHAPES = {
    "means": (None, 3), "quats": (None, 4), "scales": (None, 2), "opacities": (None,), "colors": (None, 3),
    "viewmat": (4, 4), "K": (3, 3), "background": (3,),
}


def _check_tensors(means, quats, scales, opacities, colors, viewmat, K, background) -> list[Tensor]:
    """Validate shapes and finiteness; return the tensors in one float dtype, background filled in."""
    values = {"means": means, "quats": quats, "scales": scales, "opacities": opacities, "colors": colors,
              "viewmat": viewmat, "K": K, "background": background}
    out = check_tensors("rasterize_surfels", _SHAPES, values)
    check_ranges("rasterize_surfels", out[1], out[2], out[3], out[6])
    return out
