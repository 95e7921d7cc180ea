"""What the 3D Gaussian (`splat.raster`) and 2D surfel (`splat.surfel`) rasterizers share: input checks,
quaternion rotations (torch for the references, numba for the kernels, with their vector-Jacobian product)
and small 3x3 helpers of the numba kernels.

numba helpers work on row-major 9-tuples in float32; `inlined(fn)` gives a second dispatcher numba inlines
at every call site (the vectorised block loops use it; plain calls stay calls).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from numba import njit
from torch import Tensor

from activesplat.errors import InvalidInputError

F32 = np.float32
ZERO, HALF, ONE, TWO = F32(0.0), F32(0.5), F32(1.0), F32(2.0)


# --------------------------------------------------------------------------- input checks
def _all_finite(value: Tensor) -> bool:
    """True when every element is finite. One pass: the sum of finite float32 values is finite unless it
    overflows, which only the exact element test below then has to look at."""
    if value.numel() == 0:
        return True
    with torch.no_grad():
        if bool(torch.isfinite(value.detach().sum())):
            return True
        return bool(torch.isfinite(value).all())


def check_size(caller: str, width: int, height: int) -> None:
    """Both image sizes are positive ints (InvalidInputError naming `caller` otherwise)."""
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise InvalidInputError(f"{caller}: {name} must be a positive int, got {value!r}")


def check_tensors(caller: str, shapes: dict[str, tuple[int | None, ...]],
                  values: dict[str, Any]) -> list[Tensor]:
    """Validate the shapes (None = the number N of `means`) and finiteness of `values`, in the order of
    `shapes`; return them as tensors of one float dtype (that of `means`, else float32) on the device of
    `means`. A missing `background` becomes black."""
    means = values["means"]
    if not isinstance(means, Tensor):
        raise InvalidInputError(f"{caller}: means must be a torch.Tensor, got {type(means).__name__}")
    dtype = means.dtype if means.dtype in (torch.float32, torch.float64) else torch.float32
    if values.get("background") is None:
        values = {**values, "background": torch.zeros(3, dtype=dtype, device=means.device)}
    n = means.shape[0] if means.ndim == 2 else -1
    out = []
    for name, shape in shapes.items():
        value = values[name]
        value = value if isinstance(value, Tensor) else torch.as_tensor(value)
        expected = tuple(n if d is None else d for d in shape)
        if tuple(value.shape) != expected or n < 0:
            want = "x".join("N" if d is None else str(d) for d in shape)
            rows = f" with N = {n}, the rows of means" if None in shape and name != "means" else ""
            raise InvalidInputError(f"{caller}: {name} must have shape ({want}){rows}, got "
                                    f"{tuple(value.shape)}")
        if not value.is_floating_point():
            value = value.to(dtype)
        if not _all_finite(value):
            raise InvalidInputError(f"{caller}: {name} contains NaN or inf")
        out.append(value.to(device=means.device, dtype=dtype))
    return out


def check_ranges(caller: str, quats: Tensor, scales: Tensor, opacities: Tensor, K: Tensor) -> None:
    """The documented ranges of a render's inputs (3DGS semantics): quaternions of non-zero norm (they are
    normalised, which a zero one cannot be), scales >= 0, opacities in [0, 1], focal lengths > 0. Reductions
    read back in one transfer (one sync on a GPU), no copies of the inputs; InvalidInputError naming the
    argument."""
    with torch.no_grad():
        if opacities.shape[0]:
            values = [opacities.min(), opacities.max(), scales.min(), K[0, 0], K[1, 1]]  # one device, dtype
            on_cpu = quats.device.type == "cpu"
            if not on_cpu:  # the quaternions' reduction joins the one read-back
                values.append((quats * quats).sum(dim=1).min())
            lo_o, hi_o, lo_s, fx, fy, *rest = torch.stack(values).tolist()
            lo_q = _min_quat_norm(quats) if on_cpu else rest[0]
        else:
            lo_o, hi_o, lo_s, lo_q, (fx, fy) = 0.0, 0.0, 0.0, 1.0, K.diagonal()[:2].tolist()
    if lo_o < 0.0 or hi_o > 1.0:
        raise InvalidInputError(f"{caller}: opacities must be in [0, 1] (activated, not logits), got "
                                f"[{lo_o:.4g}, {hi_o:.4g}]")
    if lo_s < 0.0:
        raise InvalidInputError(f"{caller}: scales must be >= 0 (linear, not log), got a minimum of "
                                f"{lo_s:.4g}")
    if lo_q == 0.0:
        raise InvalidInputError(f"{caller}: quats must have a non-zero norm (wxyz, normalised inside); a "
                                f"zero quaternion has no rotation")
    if fx <= 0.0 or fy <= 0.0:
        raise InvalidInputError(f"{caller}: K must have positive focal lengths, got fx {fx}, fy {fy}")


def _min_quat_norm(quats: Tensor) -> float:
    """The smallest squared norm of the (N, 4) CPU quaternions, in one compiled pass (a torch norm allocates
    N values and takes ~1 ms for 300k)."""
    q = quats.detach()
    q = q.numpy() if q.is_contiguous() else np.ascontiguousarray(q.numpy())
    return float(_min_sq_norm_rows(q))


@njit(cache=True)
def _min_sq_norm_rows(q):
    best = np.inf
    for i in range(q.shape[0]):
        v = q[i, 0] * q[i, 0] + q[i, 1] * q[i, 1] + q[i, 2] * q[i, 2] + q[i, 3] * q[i, 3]
        if v < best:
            best = v
    return best


def to_numpy(t: Tensor) -> np.ndarray:
    """A contiguous float32 numpy copy of a tensor for the kernels."""
    return np.ascontiguousarray(t.detach().to("cpu", torch.float32).numpy())


# --------------------------------------------------------------------------- rotations
def quat_to_rotmat(quats: Tensor) -> Tensor:
    """(N,4) wxyz -> (N,3,3) rotation matrices; the quaternions are normalised first."""
    w, x, y, z = (quats / quats.norm(dim=-1, keepdim=True)).unbind(-1)
    rows = [
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ]
    return torch.stack(rows, dim=-1).reshape(-1, 3, 3)


def quat_normal(quats: Tensor) -> Tensor:
    """(N,4) wxyz -> (N,3) third rotation axis, ``quat_to_rotmat(quats)[:, :, 2]`` with the same arithmetic
    (bit-identical) without the other six entries: a flat Gaussian's normal."""
    w, x, y, z = (quats / quats.norm(dim=-1, keepdim=True)).unbind(-1)
    return torch.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], dim=-1)


def rotmat_to_quat(rot: Tensor) -> Tensor:
    """(N,3,3) rotation matrices -> (N,4) unit quaternions wxyz with w >= 0, the inverse of
    :func:`quat_to_rotmat` (Shepperd's method: the largest of the four candidates' diagonals)."""
    r = rot.to(torch.float64)
    tr = r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2]
    diag = torch.stack([r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]], dim=1)
    cand = torch.cat([(1 + tr)[:, None], 1 + 2 * diag - tr[:, None]], dim=1)
    best = cand.argmax(dim=1)
    q = torch.empty((r.shape[0], 4), dtype=torch.float64, device=rot.device)
    for k in range(4):
        rows = best == k
        m = r[rows]
        s = 2.0 * torch.sqrt(cand[rows, k].clamp_min(1e-12))  # 4 x the chosen component
        d21, d02, d10 = m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]
        a01, a02, a12 = m[:, 0, 1] + m[:, 1, 0], m[:, 0, 2] + m[:, 2, 0], m[:, 1, 2] + m[:, 2, 1]
        cols = {0: (s / 4, d21 / s, d02 / s, d10 / s), 1: (d21 / s, s / 4, a01 / s, a02 / s),
                2: (d02 / s, a01 / s, s / 4, a12 / s), 3: (d10 / s, a02 / s, a12 / s, s / 4)}[k]
        q[rows] = torch.stack(cols, dim=1)
    q = torch.where(q[:, :1] < 0, -q, q)
    return (q / q.norm(dim=1, keepdim=True)).to(rot.dtype)


@njit(cache=True, error_model="numpy")
def quat_rotmat(w, x, y, z):
    """Rotation matrix (row-major 9-tuple) of a unit quaternion wxyz (the kernels' `quat_to_rotmat`)."""
    return (
        ONE - TWO * (y * y + z * z), TWO * (x * y - w * z), TWO * (x * z + w * y),
        TWO * (x * y + w * z), ONE - TWO * (x * x + z * z), TWO * (y * z - w * x),
        TWO * (x * z - w * y), TWO * (y * z + w * x), ONE - TWO * (x * x + y * y),
    )


@njit(cache=True, error_model="numpy")
def quat_vjp(q, norm, v_r):
    """Gradient on the raw quaternion from the gradient on R(q / |q|)."""
    w, x, y, z = q
    gw = TWO * (-z * v_r[1] + y * v_r[2] + z * v_r[3] - x * v_r[5] - y * v_r[6] + x * v_r[7])
    gx = TWO * (y * v_r[1] + z * v_r[2] + y * v_r[3] - TWO * x * v_r[4] - w * v_r[5] + z * v_r[6]
                + w * v_r[7] - TWO * x * v_r[8])
    gy = TWO * (-TWO * y * v_r[0] + x * v_r[1] + w * v_r[2] + x * v_r[3] + z * v_r[5] - w * v_r[6]
                + z * v_r[7] - TWO * y * v_r[8])
    gz = TWO * (-TWO * z * v_r[0] - w * v_r[1] + x * v_r[2] + w * v_r[3] - TWO * z * v_r[4] + y * v_r[5]
                + x * v_r[6] + y * v_r[7])
    dot = w * gw + x * gx + y * gy + z * gz
    return (gw - w * dot) / norm, (gx - x * dot) / norm, (gy - y * dot) / norm, (gz - z * dot) / norm


# --------------------------------------------------------------------------- 3x3 helpers of the kernels
@njit(cache=True, error_model="numpy")
def matmul3(a, b):
    """3x3 product of row-major 9-tuples."""
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6], a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@njit(cache=True, error_model="numpy")
def transpose3(a):
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


def inlined(fn):
    """A second dispatcher of the numba function ``fn`` that numba inlines at every call (for the
    vectorised loops; the plain one stays a call)."""
    return njit(cache=True, error_model="numpy", inline="always")(fn.py_func)


__all__ = ["check_size", "check_tensors", "inlined", "matmul3", "quat_rotmat", "quat_to_rotmat", "quat_vjp",
           "rotmat_to_quat", "to_numpy", "transpose3"]
