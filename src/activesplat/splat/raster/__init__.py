"""The 3D Gaussian rasterizer: ``rasterize(...)`` (paper eqs. 2-4, 3DGS semantics).

Every consumer (mapping, top-down workspace, panoramas, evaluation) calls :func:`rasterize`; the
backend is swappable:

- ``"numba"``: tile-based CPU rasterizer with an analytic backward pass (default without CUDA;
  ``numba_backend`` with the kernels ``numba_project`` and ``numba_tiles``).
- ``"gsplat"``: adapter to ``gsplat.rasterization`` (CUDA, ``gsplat_backend``).
- ``"torch"``: slow, obviously correct reference in plain torch autograd (``torch_ref``, used by tests).
- ``"auto"``: gsplat when CUDA is available and gsplat imports, else numba.

Semantics (all backends): EWA projection with a 0.3 px low-pass on the 2D covariance,
alpha_i = min(0.99, o_i exp(-power)), contributions below 1/255 skipped, front-to-back by view
depth, a pixel stops before the Gaussian that would bring T below 1e-4;
rgb = sum w_i c_i + background T, depth = sum w_i z_i (not normalised), alpha = 1 - T,
median_depth = z of the Gaussian at which T first drops below 0.5 (0 if never). z_i is the view depth
of the centre, or with ``planar_depth`` its linear extension over the footprint (:mod:`.planar`).
Pixel (row i, column j) has its centre at (j + 0.5, i + 0.5) in the image plane of K.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal

import torch
from torch import Tensor

from activesplat.errors import InvalidInputError
from activesplat.splat.kernels import check_ranges, check_size, check_tensors

Backend = Literal["auto", "numba", "torch", "gsplat"]
BACKENDS = ("auto", "numba", "torch", "gsplat")


@dataclass
class RenderOutput:
    """Images rendered from one camera plus per-Gaussian metadata.

    ``means2d`` is an intermediate of the autograd graph: call ``out.means2d.retain_grad()`` before
    ``backward()`` to read the view-space 2D mean gradient that 3DGS densification uses.
    """

    rgb: Tensor
    """(H, W, 3) colour, background blended in."""
    depth: Tensor
    """(H, W) alpha-blended view depth sum w_i z_i (not divided by alpha)."""
    alpha: Tensor
    """(H, W) accumulated opacity 1 - T."""
    median_depth: Tensor
    """(H, W) depth where T first drops below 0.5, 0 where it never does (no gradient)."""
    radii: Tensor
    """(N,) int32 screen radius in pixels; 0 = not rendered (culled, masked out or off-screen)."""
    means2d: Tensor
    """(N, 2) projected centres in pixels (differentiable)."""
    depths: Tensor
    """(N,) view-space z of the centres."""

    def __getitem__(self, name: str) -> Tensor:
        """Dict-style access, ``out["alpha"]`` == ``out.alpha``."""
        if name not in self.__dataclass_fields__:
            raise KeyError(name)
        return getattr(self, name)


@dataclass
class Projection:
    """Per-Gaussian screen-space quantities shared by the backends."""

    means2d: Tensor  # (N, 2) pixels
    conics: Tensor  # (N, 3) inverse 2D covariance (a, b, c): power = 0.5 (a dx^2 + c dy^2) + b dx dy
    depths: Tensor  # (N,) view z
    radii: Tensor  # (N,) int32, 0 = culled


def rasterize(
    means: Tensor,
    quats: Tensor,
    scales: Tensor,
    opacities: Tensor,
    colors: Tensor,
    viewmat: Tensor,
    K: Tensor,
    width: int,
    height: int,
    backend: Backend = "auto",
    background: Tensor | None = None,
    mask: Tensor | None = None,
    planar_depth: bool = False,
) -> RenderOutput:
    """Render N Gaussians into a (height, width) pinhole camera (3DGS, paper eqs. 2-4).

    means (N,3) world; quats (N,4) wxyz (normalised here); scales (N,3) linear; opacities (N,)
    in [0,1]; colors (N,3); viewmat (4,4) world-to-camera, OpenCV axes; K (3,3); background (3,)
    colour (default black); mask (N,) bool renders only that subset. ``planar_depth``: each Gaussian's
    depth varies linearly over its footprint, the slope of its densest point along the pixel rays
    (:mod:`activesplat.splat.raster.planar`; a project option, 3DGS renders the centre's depth).
    Raises InvalidInputError on wrong shapes, NaN/inf values or an unknown backend.
    """
    check_size("rasterize", width, height)
    tensors = _check_tensors(means, quats, scales, opacities, colors, viewmat, K, background, mask)
    means, quats, scales, opacities, colors, viewmat, K, background, mask = tensors
    name = resolve_backend(backend)
    if name == "torch":
        from activesplat.splat.raster.torch_ref import rasterize_torch as render
    elif name == "numba":
        from activesplat.splat.raster.numba_backend import rasterize_numba as render
    else:
        from activesplat.splat.raster.gsplat_backend import rasterize_gsplat as render
    return render(means, quats, scales, opacities, colors, viewmat, K, width, height, background, mask,
                  planar_depth=planar_depth)


def resolve_backend(backend: str) -> str:
    """The backend ``backend`` names ("auto": gsplat when CUDA and gsplat are there, else numba)."""
    if backend not in BACKENDS:
        raise InvalidInputError(f"unknown rasterizer backend {backend!r}; expected one of {BACKENDS}")
    if backend == "auto":
        return "gsplat" if gsplat_available() else "numba"
    if backend == "gsplat" and not gsplat_available():
        why = ("the gsplat package is not installed (pip install activesplat[cuda])"
               if torch.cuda.is_available() else "this torch has no CUDA device")
        raise InvalidInputError(f"the rasterizer backend 'gsplat' needs an NVIDIA GPU and gsplat: {why}; "
                                f"use --backend numba (or auto, which picks gsplat where it can)")
    return backend


def backend_device(backend: str) -> torch.device:
    """Where a map rendered with ``backend`` should live: the GPU for gsplat, else the CPU."""
    return torch.device("cuda" if resolve_backend(backend) == "gsplat" else "cpu")


def prepare_backend(backend: Backend = "auto", planar_depth: bool = False) -> float:
    """Render and back-propagate a tiny image with ``backend`` so that its compiled code is loaded
    before an episode's clock starts; returns the seconds it took.

    The first call of a process pays one-time costs that are not per-step work: gsplat loads its CUDA
    extension (and its JIT builder recompiles the extension whenever its sources carry new file times,
    e.g. after a reinstall: 80-90 s on 16 cores), Triton compiles the median-depth kernel, numba loads
    (or compiles) its kernels. ``activesplat explore`` calls this first and reports the time as
    ``backend_setup_s`` instead of folding it into the first step (docs/gpu.md)."""
    import time

    name = resolve_backend(backend)
    device = torch.device("cuda" if name == "gsplat" else "cpu")
    t0 = time.perf_counter()
    if name == "gsplat":
        from gsplat.cuda._backend import _C

        if _C is None:
            raise InvalidInputError("gsplat's CUDA extension could not be built or loaded (is the CUDA "
                                    "toolkit installed? see docs/gpu.md); use --backend numba")
    from activesplat.splat.raster.numba_backend import warm_up_scene

    params, K = warm_up_scene(3)
    params = [p.detach().to(device).requires_grad_(True) for p in params]
    out = rasterize(*params, torch.eye(4, device=device), K.to(device), 32, 32, backend=name,
                    planar_depth=planar_depth)
    (out.rgb.sum() + out.depth.sum() + out.alpha.sum()).backward()
    if device.type == "cuda":
        torch.cuda.synchronize()
    return time.perf_counter() - t0


@functools.cache
def gsplat_available() -> bool:
    """True when CUDA is available and ``gsplat`` imports."""
    if not torch.cuda.is_available():
        return False
    try:
        import gsplat  # noqa: F401
    except ImportError:
        return False
    return True


_SHAPES = {
    "means": (None, 3),
    "quats": (None, 4),
    "scales": (None, 3),
    "opacities": (None,),
    "colors": (None, 3),
    "viewmat": (4, 4),
    "K": (3, 3),
    "background": (3,),
}


def _check_tensors(means, quats, scales, opacities, colors, viewmat, K, background, mask):
    """Validate shapes and finiteness; return the tensors with a float dtype and defaults filled."""
    values = {"means": means, "quats": quats, "scales": scales, "opacities": opacities, "colors": colors,
              "viewmat": viewmat, "K": K, "background": background}
    out = check_tensors("rasterize", _SHAPES, values)
    check_ranges("rasterize", out[1], out[2], out[3], out[6])
    if mask is not None:
        mask = _check_mask(mask, out[0].shape[0], out[0].device)
    return (*out, mask)


def _check_mask(mask, n: int, device) -> Tensor:
    mask = torch.as_tensor(mask)
    if tuple(mask.shape) != (n,):
        raise InvalidInputError(f"rasterize: mask must have shape (N,) = ({n},), got {tuple(mask.shape)}")
    if mask.dtype != torch.bool:
        raise InvalidInputError(f"rasterize: mask must be a bool tensor, got {mask.dtype}")
    return mask.to(device)
