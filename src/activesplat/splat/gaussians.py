"""The Gaussian map: raw parameters, the activations the renderer needs, and Adam bookkeeping.

Raw (optimised) parameters, as in SplaTAM / 3DGS:
``means`` (N,3) world metres, ``quats`` (N,4) wxyz unnormalised, ``log_scales`` (N,3),
``opacity_logits`` (N,), ``f_dc`` (N,3) the degree-0 SH coefficient, rgb = 0.5 + C0 * f_dc.
The colour is stored as f_dc (not plain RGB) so that the standard 3DGS PLY layout round-trips
bit-exactly; :class:`~activesplat.splat.config.LearningRates` explains why the dynamics are unchanged.

Adam state follows every change of the Gaussian count: :meth:`GaussianMap.append` extends the
moments with zeros, :meth:`GaussianMap.keep` drops the pruned rows (the 3DGS recipe).
"""

from __future__ import annotations

import numpy as np
import torch

from activesplat.errors import InvalidInputError
from activesplat.splat.config import LearningRates
from activesplat.splat.kernels import quat_normal, rotmat_to_quat

SH_C0 = 0.28209479177387814  # degree-0 real spherical harmonic, 1 / (2 sqrt(pi))
PARAM_NAMES = ("means", "quats", "log_scales", "opacity_logits", "f_dc")
PARAM_WIDTHS = {"means": 3, "quats": 4, "log_scales": 3, "opacity_logits": 0, "f_dc": 3}


# ATen splits an elementwise op over more than 32768 elements (its grain size) among its threads, and
# torch.sigmoid computes the last few elements of each thread's share with a scalar formula that can
# differ from its SIMD one by an ulp: the opacities, and so the whole run, changed with the thread count.
# Blocks of this size run on one thread each and end on a whole SIMD step (a multiple of 32 floats).
SIGMOID_BLOCK = 16384


def _sigmoid_blocks(x: torch.Tensor) -> torch.Tensor:
    out = torch.empty_like(x)
    flat_x, flat_out = x.view(-1), out.view(-1)
    for start in range(0, flat_x.numel(), SIGMOID_BLOCK):
        torch.sigmoid(flat_x[start:start + SIGMOID_BLOCK], out=flat_out[start:start + SIGMOID_BLOCK])
    return out


class _BlockedSigmoid(torch.autograd.Function):
    @staticmethod
    def forward(ctx, x: torch.Tensor) -> torch.Tensor:
        y = _sigmoid_blocks(x)
        ctx.save_for_backward(y)
        return y

    @staticmethod
    def backward(ctx, grad: torch.Tensor) -> torch.Tensor:
        (y,) = ctx.saved_tensors
        return torch.ops.aten.sigmoid_backward(grad, y)  # what torch.sigmoid's own backward computes


def sigmoid(x: torch.Tensor) -> torch.Tensor:
    """``torch.sigmoid`` with the same bits whatever the number of CPU threads: the bits of one thread.
    Differentiable. Large contiguous CPU tensors are done in blocks of ``SIGMOID_BLOCK`` elements (see
    the comment above it); anything else is torch.sigmoid itself."""
    if (x.device.type != "cpu" or x.numel() < 2 * SIGMOID_BLOCK or not x.is_contiguous()
            or torch.get_num_threads() == 1):
        return torch.sigmoid(x)
    return _BlockedSigmoid.apply(x) if x.requires_grad and torch.is_grad_enabled() else _sigmoid_blocks(x)


def rgb_to_f_dc(rgb: torch.Tensor) -> torch.Tensor:
    """3DGS convention: f_dc = (rgb - 0.5) / C0."""
    return (rgb - 0.5) / SH_C0


def f_dc_to_rgb(f_dc: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`rgb_to_f_dc`."""
    return 0.5 + SH_C0 * f_dc


def _check_raw(raw: dict[str, torch.Tensor]) -> int:
    """Validate a dict of raw parameters; return the Gaussian count."""
    if set(raw) != set(PARAM_NAMES):
        raise InvalidInputError(f"Gaussian parameters must be exactly {PARAM_NAMES}, got {sorted(raw)}")
    n = raw["means"].shape[0]
    for name in PARAM_NAMES:
        t = raw[name]
        want = (n,) if PARAM_WIDTHS[name] == 0 else (n, PARAM_WIDTHS[name])
        if tuple(t.shape) != want:
            raise InvalidInputError(
                f"Gaussian parameter {name!r} must have shape {want}, got {tuple(t.shape)}")
        if not torch.isfinite(t).all():
            raise InvalidInputError(f"Gaussian parameter {name!r} contains NaN or inf")
    return n


class GaussianMap:
    """A set of 3D Gaussians (paper eq. 1) held as leaf tensors that Adam optimises."""

    GROWTH = 1.25
    """Capacity factor when :meth:`append` outgrows the storage (the spare rows cost at most a quarter)."""

    def __init__(self, raw: dict[str, torch.Tensor]):
        _check_raw(raw)
        # each parameter is a leaf view of the first rows of a larger buffer, so that appending m rows
        # writes m rows instead of copying the whole map (torch.cat at every mapped frame)
        self._buffers = {name: raw[name].detach().to(torch.float32).clone() for name in PARAM_NAMES}
        self.params: dict[str, torch.Tensor] = {name: self._leaf(name, len(buf))
                                                for name, buf in self._buffers.items()}

    def _leaf(self, name: str, n: int) -> torch.Tensor:
        """A leaf tensor (requires grad) on the first ``n`` rows of buffer ``name``, sharing its storage."""
        return self._buffers[name][:n].detach().requires_grad_(True)

    # ------------------------------------------------------------------ construction
    @classmethod
    def empty(cls, device: str | torch.device = "cpu") -> GaussianMap:
        raw = {
            name: torch.zeros((0,) if w == 0 else (0, w), device=device) for name, w in PARAM_WIDTHS.items()
        }
        return cls(raw)

    @staticmethod
    def raw_from_points(points: torch.Tensor, rgb: torch.Tensor, radii: torch.Tensor, opacity: float,
                        oriented: tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None = None
                        ) -> dict[str, torch.Tensor]:
        """Gaussians at ``points`` (M,3) with colour ``rgb`` (M,3) in [0,1] and radius ``radii`` (M,),
        opacity ``opacity`` (docs/protocol.md §2, initialisation). Isotropic with identity rotation,
        except the rows that ``oriented`` = (rows (M,) bool, frames (R,3,3), factors (R,3)) names: their
        rotation is the right-handed frame whose columns are the Gaussian's axes, and their scales are
        ``radii`` times the factors."""
        m = points.shape[0]
        quats = torch.zeros((m, 4), dtype=torch.float32, device=points.device)
        quats[:, 0] = 1.0
        log_scales = torch.log(radii.to(torch.float32)).unsqueeze(1).expand(m, 3).clone()
        if oriented is not None:
            rows, frames, factors = oriented
            quats[rows] = rotmat_to_quat(frames.to(torch.float32))
            log_scales[rows] += torch.log(factors.to(torch.float32))
        logit = float(np.log(opacity / (1.0 - opacity)))
        return {
            "means": points.to(torch.float32),
            "quats": quats,
            "log_scales": log_scales,
            "opacity_logits": torch.full((m,), logit, dtype=torch.float32, device=points.device),
            "f_dc": rgb_to_f_dc(rgb.to(torch.float32)),
        }

    @classmethod
    def from_points(cls, points: torch.Tensor, rgb: torch.Tensor, radii: torch.Tensor,
                    opacity: float = 0.5) -> GaussianMap:
        return cls(cls.raw_from_points(points, rgb, radii, opacity))

    # ------------------------------------------------------------------ activations (what the renderer takes)
    def __len__(self) -> int:
        return int(self.params["means"].shape[0])

    @property
    def device(self) -> torch.device:
        return self.params["means"].device

    @property
    def means(self) -> torch.Tensor:
        return self.params["means"]

    @property
    def quats(self) -> torch.Tensor:
        """Unit quaternions wxyz."""
        return unit_quats(self.params["quats"])

    @property
    def scales(self) -> torch.Tensor:
        """Linear scales (metres), exp of the log-scales."""
        return torch.exp(self.params["log_scales"])

    @property
    def opacities(self) -> torch.Tensor:
        """Opacities in [0,1], sigmoid of the logits."""
        return sigmoid(self.params["opacity_logits"])

    @property
    def colors(self) -> torch.Tensor:
        """Plain RGB (no clamping, as SplaTAM)."""
        return f_dc_to_rgb(self.params["f_dc"])

    def rows(self, index: torch.Tensor) -> dict[str, torch.Tensor]:
        """Detached copies of the raw parameters of the Gaussians ``index`` (1-D long indices); index_select,
        a few times faster than advanced indexing on the CPU for the same copies."""
        return {name: t.detach().index_select(0, index) for name, t in self.params.items()}

    def raw(self) -> dict[str, torch.Tensor]:
        """Detached copies of the raw parameters."""
        return {name: t.detach().clone() for name, t in self.params.items()}

    # ------------------------------------------------------------------ optimiser
    def make_optimizer(self, lr: LearningRates, eps: float) -> torch.optim.Adam:
        """Adam with one parameter group per raw tensor, the release's rates."""
        rates = {"means": lr.means, "quats": lr.quats, "log_scales": lr.scales,
                 "opacity_logits": lr.opacities, "f_dc": lr.colors / SH_C0}
        groups = [{"params": [self.params[n]], "lr": rates[n], "name": n} for n in PARAM_NAMES]
        return torch.optim.Adam(groups, lr=0.0, eps=eps)

    def _replace(self, name: str, new: torch.Tensor, optimizer: torch.optim.Adam | None,
                 edit_state) -> None:
        """Swap parameter ``name`` for ``new`` (a leaf), editing its Adam moments with ``edit_state``."""
        old = self.params[name]
        new = new.detach().requires_grad_(True)
        self.params[name] = new
        if optimizer is None:
            return
        for group in optimizer.param_groups:
            if group["params"][0] is old:
                group["params"][0] = new
                state = optimizer.state.pop(old, None)
                if state:
                    for key in ("exp_avg", "exp_avg_sq"):
                        state[key] = edit_state(state[key])
                    optimizer.state[new] = state
                return
        raise RuntimeError(f"optimizer does not hold parameter {name!r}")

    # ------------------------------------------------------------------ densify / prune
    def append(self, raw: dict[str, torch.Tensor], optimizer: torch.optim.Adam | None = None) -> int:
        """Add Gaussians (densification); their Adam moments start at zero. Returns the number added."""
        m = _check_raw(raw)
        if m == 0:
            return 0
        n = len(self)
        for name in PARAM_NAMES:
            buf = self._buffers[name]
            if n + m > buf.shape[0]:  # grown geometrically: O(m) amortised per append
                grown = buf.new_empty((max(n + m, int(self.GROWTH * buf.shape[0])), *buf.shape[1:]))
                grown[:n] = buf[:n]
                buf = self._buffers[name] = grown
            buf[n:n + m] = raw[name].detach().to(self.device, torch.float32)
            self._replace(name, self._leaf(name, n + m), optimizer,
                          lambda s, m=m: torch.cat([s, s.new_zeros((m, *s.shape[1:]))]))
        return m

    def keep(self, mask: torch.Tensor, optimizer: torch.optim.Adam | None = None) -> int:
        """Keep the Gaussians where ``mask`` (N,) is True (pruning). Returns the number removed."""
        if mask.dtype != torch.bool or tuple(mask.shape) != (len(self),):
            raise InvalidInputError(f"keep mask must be bool of shape ({len(self)},), got {mask.dtype} "
                                    f"{tuple(mask.shape)}")
        removed = int((~mask).sum())
        if removed == 0:
            return 0
        index = torch.nonzero(mask, as_tuple=True)[0]  # index_select: several times faster than a bool mask
        for name in PARAM_NAMES:  # into new storage: views of the map as it was (a snapshot) stay valid
            self._buffers[name] = self.params[name].detach().index_select(0, index)
            self._replace(name, self._leaf(name, len(index)), optimizer, lambda s: s.index_select(0, index))
        return removed


def activate(raw: dict[str, torch.Tensor]) -> tuple[torch.Tensor, ...]:
    """The renderer's inputs from raw parameters (any subset of rows, differentiable): means, unit
    quaternions, linear scales, opacities in [0,1], RGB; the same maps as the properties of
    :class:`GaussianMap`."""
    return (raw["means"], unit_quats(raw["quats"]), torch.exp(raw["log_scales"]),
            sigmoid(raw["opacity_logits"]), f_dc_to_rgb(raw["f_dc"]))


def unit_quats(q: torch.Tensor) -> torch.Tensor:
    """(N, 4) quaternions scaled to unit length (a zero row stays zero)."""
    return q / q.norm(dim=1, keepdim=True).clamp_min(1e-12)


def frustum_rows(means: torch.Tensor, log_scales: torch.Tensor, pose, K, width: int, height: int,
                 depth: torch.Tensor | None = None, occlusion_margin_m: float = 0.1,
                 occlusion_window_px: int = 8, candidates: torch.Tensor | None = None) -> torch.Tensor:
    """Indices (long) of the Gaussians the rasterizer can draw into the (width x height) image of the
    camera-to-world ``pose``: in front of its near plane, with a conservative screen radius (largest
    scale, the projection Jacobian at the rasterizer's clamped image coordinates, the low-pass) that
    reaches the image. A superset of what the rasterizer draws, so a render of these rows is the render
    of the whole map, at a cost proportional to the view instead of the map.

    With the observed ``depth`` of that camera ((height, width), 0 = invalid), Gaussians hidden behind the
    observed surface are dropped too: those whose whole footprint (radius <= ``occlusion_window_px``) lies
    where every observed depth within the window around the centre is nearer than the centre's depth
    by more than ``occlusion_margin_m`` (invalid depth never hides anything). Where the map reproduces
    the observed surface, they are composited behind it with no visible weight; this is what keeps a
    view of a corridor from paying for every room behind its walls.

    ``candidates`` (ascending long indices): test only these rows, e.g. those an earlier call for the same
    camera kept, plus rows added since; the result is the same as a call over the whole map whenever every
    row left out would fail the test."""
    from activesplat.splat.raster.constants import RASTER

    if candidates is not None and means.device.type != "cpu":
        index = candidates.to(means.device)
        kept = _frustum_rows_torch(means.index_select(0, index), log_scales.index_select(0, index), pose, K,
                                   width, height, depth, occlusion_margin_m, occlusion_window_px)
        return index[kept]
    if means.device.type == "cpu":
        from activesplat.splat._mapper_numba import cull_rows, cull_some_rows, far_depth

        pose = np.asarray(pose, dtype=np.float64)
        far = np.zeros((1, 1), np.float32)
        if depth is not None:  # the numba twin of _far_depth (same values, tested)
            observed = np.ascontiguousarray(depth.detach().numpy(), dtype=np.float32)
            far = far_depth(observed, occlusion_window_px)
        fx, fy, cx, cy = float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
        args = (means.detach().numpy(), log_scales.detach().numpy(), pose[:3, :3].copy(), pose[:3, 3].copy(),
                fx, fy, cx, cy, width, height, RASTER.near, *_jacobian_limits(K, width, height),
                RASTER.extent_sigmas, RASTER.low_pass, far, occlusion_window_px, occlusion_margin_m,
                depth is not None)
        if candidates is not None:
            index = np.ascontiguousarray(candidates.numpy(), dtype=np.int64)
            return torch.from_numpy(index[cull_some_rows(index, *args)])
        return torch.from_numpy(np.flatnonzero(cull_rows(*args)))
    return _frustum_rows_torch(means, log_scales, pose, K, width, height, depth, occlusion_margin_m,
                               occlusion_window_px)


def is_flat(log_scales: torch.Tensor, flatness: float = 0.5) -> torch.Tensor:
    """(N,) bool: the third scale is below ``flatness`` times the smaller of the other two (a flat
    Gaussian, whose third rotation axis is the normal of its surface)."""
    return log_scales[:, 2] < torch.minimum(log_scales[:, 0], log_scales[:, 1]) + float(np.log(flatness))


def back_facing(quats: torch.Tensor, log_scales: torch.Tensor, means: torch.Tensor, camera_center,
                flatness: float = 0.5, margin_deg: float = 0.0) -> torch.Tensor:
    """(N,) bool: flat Gaussians seen from behind. A Gaussian is flat when its third scale is below
    ``flatness`` times the smaller of the other two; its third rotation axis is then the normal of the
    surface it was made from, pointing to the side that observed it (``densify.gaussians_from_pixels``
    turns it so). Seen from behind = the camera centre lies on the other side of that plane: the
    Gaussian belongs to the far face of a wall or an object, not to a surface this camera can see. With
    ``margin_deg`` > 0 the camera must lie that many degrees behind the plane (seen from the Gaussian),
    so that a plane seen edge-on, whose normal is a few degrees off, does not flip from side to side."""
    with torch.no_grad():
        if quats.shape[0] == 0:
            return torch.zeros(0, dtype=torch.bool, device=quats.device)
        return seen_from_behind(is_flat(log_scales, flatness), quat_normal(quats), means, camera_center,
                                margin_deg)


def seen_from_behind(flat: torch.Tensor, normal: torch.Tensor, means: torch.Tensor, camera_center,
                     margin_deg: float = 0.0) -> torch.Tensor:
    """:func:`back_facing` from the Gaussians' flatness (:func:`is_flat`) and normals (``quat_normal``),
    for callers that test many cameras against the same Gaussians (``splat.snapshot.MapSnapshot``)."""
    with torch.no_grad():
        c = torch.as_tensor(np.asarray(camera_center, dtype=np.float32), device=means.device)
        to_camera = c - means
        limit = -float(np.sin(np.radians(margin_deg))) * to_camera.norm(dim=1) if margin_deg > 0 else 0.0
        return flat & ((to_camera * normal).sum(dim=1) < limit)


def camera_points(means: torch.Tensor, pose) -> torch.Tensor:
    """(N, 3) the centres ``means`` in the camera frame of the camera-to-world ``pose``: R^T (p - t)."""
    pose = np.asarray(pose, dtype=np.float64)
    rot = torch.from_numpy(pose[:3, :3].astype(np.float32)).to(means.device)
    t = torch.from_numpy(pose[:3, 3].astype(np.float32)).to(means.device)
    return (means.detach() - t) @ rot


def _frustum_rows_torch(means, log_scales, pose, K, width, height, depth, occlusion_margin_m,
                        occlusion_window_px) -> torch.Tensor:
    """:func:`frustum_rows` in torch (any device; the CPU uses the numba kernel)."""
    from activesplat.splat.raster.constants import RASTER

    with torch.no_grad():
        cam = camera_points(means, pose)
        z = cam[:, 2]
        front = z > RASTER.near
        safe_z = torch.where(front, z, torch.ones_like(z))
        fx, fy, cx, cy = float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
        x, y = cam[:, 0] / safe_z, cam[:, 1] / safe_z  # normalised image coordinates
        lim_x, lim_y = _jacobian_limits(K, width, height)
        stretch = 1.0 + x.clamp(-lim_x, lim_x).square() + y.clamp(-lim_y, lim_y).square()
        s = torch.exp(log_scales.detach().max(dim=1).values) * max(fx, fy) / safe_z
        radius = RASTER.extent_sigmas * torch.sqrt(s.square() * stretch + RASTER.low_pass) + 1.0  # pixels
        u, v = fx * x + cx, fy * y + cy
        inside = front & (u + radius >= 0) & (u - radius <= width)
        inside &= (v + radius >= 0) & (v - radius <= height)
        if depth is not None:
            far = _far_depth(depth, occlusion_window_px)
            ui, vi = u.clamp(-1, width).floor().long(), v.clamp(-1, height).floor().long()
            test = inside & (radius <= occlusion_window_px) & (ui >= 0) & (ui < width) & (vi >= 0)
            test &= vi < height
            idx = torch.nonzero(test, as_tuple=True)[0]
            hidden = z[idx] > far[vi[idx], ui[idx]] + occlusion_margin_m
            inside[idx[hidden]] = False
        return torch.nonzero(inside, as_tuple=True)[0]


def _jacobian_limits(K, width: int, height: int) -> tuple[float, float]:
    """The normalised image coordinates at which the rasterizer clamps its projection Jacobian."""
    from activesplat.splat.raster.constants import RASTER

    fx, fy, cx, cy = float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
    return ((1.0 + RASTER.fov_clamp) * max(cx, width - cx) / fx,
            (1.0 + RASTER.fov_clamp) * max(cy, height - cy) / fy)


def _far_depth(depth: torch.Tensor, r: int) -> torch.Tensor:
    """The farthest observed depth within the (2r+1)^2 window around each pixel; inf where any pixel of
    the window is invalid (unknown space hides nothing)."""
    x = torch.where(depth > 0, depth, torch.full_like(depth, float("inf")))[None, None]
    x = torch.nn.functional.max_pool2d(x, (1, 2 * r + 1), stride=1, padding=(0, r))
    x = torch.nn.functional.max_pool2d(x, (2 * r + 1, 1), stride=1, padding=(r, 0))
    return x[0, 0]
