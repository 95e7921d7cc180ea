"""Row-sparse Adam for the online map: only the Gaussians a view trains are touched.

torch's Adam updates every row of a parameter tensor at every step. With a zero gradient (a Gaussian
that the current view does not see) the stale first moment still moves the row, by up to ~10 learning
rates after it left the view, and the step costs O(map size). In an online map that means rooms mapped
earlier keep drifting while the robot is elsewhere, and every iteration gets slower as the house grows.

:class:`RowAdam` keeps the first and second moments and a step count *per row* and updates only the rows
it is given (the Gaussians rendered in the trained view whose gradient is non-zero), with the bias
correction of each row's own step count. For a row that is trained at every step this is exactly
Adam (Kingma & Ba, 2015); a row that is not trained is left bit-for-bit as it was. A departure from
the release, which keeps one torch Adam over the whole map (see ``MapperConfig.sparse_adam``).
"""

from __future__ import annotations

import numpy as np
import torch

from activesplat.splat.config import LearningRates
from activesplat.splat.gaussians import PARAM_NAMES, SH_C0, GaussianMap


def learning_rates(lr: LearningRates) -> dict[str, float]:
    """Per-parameter rates of the raw tensors (colour rate converted to f_dc units, see LearningRates)."""
    return {"means": lr.means, "quats": lr.quats, "log_scales": lr.scales,
            "opacity_logits": lr.opacities, "f_dc": lr.colors / SH_C0}


def nonzero_rows(grads: dict[str, torch.Tensor], n: int) -> torch.Tensor:
    """(n,) bool: the rows whose gradient is non-zero in some parameter (``grads[name]``: (n, ...))."""
    touched = torch.zeros(n, dtype=torch.bool, device=next(iter(grads.values())).device)
    for g in grads.values():
        touched |= (g != 0).reshape(n, -1).any(dim=1)
    return touched


class RowAdam:
    """Adam with per-row state over the raw tensors of a :class:`GaussianMap`.

    The map's row count changes through :meth:`append` and :meth:`keep`, which must follow every
    ``GaussianMap.append`` / ``GaussianMap.keep`` (the mapper does both together).
    """

    def __init__(self, gmap: GaussianMap, lr: LearningRates, eps: float, betas=(0.9, 0.999)):
        self.gmap, self.rates, self.eps = gmap, learning_rates(lr), float(eps)
        self.beta1, self.beta2 = betas
        n, device = len(gmap), gmap.device
        # the state lives in buffers of ``_capacity`` rows, grown geometrically so that appending m rows
        # costs O(m) amortised instead of copying the whole state; the tensors below are views of their
        # first rows (contiguous, so the numba step updates them in place)
        self._capacity = n
        self._buffers = {key: torch.zeros((n, *gmap.params[name].shape[1:]), device=device)
                         for key, name in self._keys()}
        self._buffers["steps"] = torch.zeros(n, dtype=torch.int32, device=device)
        self._views(n)
        self._calls = 0  # step calls so far: a bound on every row's step count
        self._bias1_of = self._bias2_sqrt_of = np.zeros(0)  # bias corrections by step count (step_nonzero)

    GROWTH = 1.25  # capacity factor on reallocation (the spare rows cost at most 25 % of the state)

    @staticmethod
    def _keys():
        return [((kind, name), name) for kind in ("exp_avg", "exp_avg_sq") for name in PARAM_NAMES]

    def _views(self, n: int) -> None:
        """Point exp_avg, exp_avg_sq and steps at the first ``n`` rows of the buffers."""
        self.exp_avg = {name: self._buffers[("exp_avg", name)][:n] for name in PARAM_NAMES}
        self.exp_avg_sq = {name: self._buffers[("exp_avg_sq", name)][:n] for name in PARAM_NAMES}
        self.steps = self._buffers["steps"][:n]

    def __len__(self) -> int:
        return int(self.steps.shape[0])

    def append(self, m: int) -> None:
        """State for ``m`` new rows (zero moments, step 0)."""
        if m <= 0:
            return
        n = len(self)
        if n + m > self._capacity:
            self._capacity = max(n + m, int(self.GROWTH * self._capacity))
            for key, buf in self._buffers.items():
                grown = buf.new_empty((self._capacity, *buf.shape[1:]))
                grown[:n] = buf[:n]
                self._buffers[key] = grown
        for buf in self._buffers.values():
            buf[n:n + m] = 0
        self._views(n + m)

    def keep(self, mask: torch.Tensor) -> None:
        """Drop the state of the rows where ``mask`` is False (compacted within the buffers)."""
        n = len(self)
        index = torch.nonzero(mask, as_tuple=True)[0]  # index_select: several times faster than a bool mask
        k = len(index)
        for buf in self._buffers.values():
            buf[:k] = buf[:n].index_select(0, index)
        self._views(k)

    @torch.no_grad()
    def step(self, rows: torch.Tensor, grads: dict[str, torch.Tensor]) -> None:
        """One Adam step on ``rows`` (long indices, unique) with ``grads[name]`` of shape (len(rows), ...)."""
        if rows.numel() == 0:
            return
        self._calls += 1
        steps = self.steps[rows] + 1
        self.steps[rows] = steps
        if rows.device.type == "cpu":
            self._step_numba(rows, grads, steps)
            return
        t = steps.to(torch.float32)
        bias1 = 1.0 - torch.pow(torch.tensor(self.beta1, device=t.device), t)
        bias2_sqrt = torch.sqrt(1.0 - torch.pow(torch.tensor(self.beta2, device=t.device), t))
        for name in PARAM_NAMES:
            g = grads[name]
            m = self.exp_avg[name][rows].mul_(self.beta1).add_(g, alpha=1.0 - self.beta1)
            v = self.exp_avg_sq[name][rows].mul_(self.beta2).addcmul_(g, g, value=1.0 - self.beta2)
            self.exp_avg[name][rows] = m
            self.exp_avg_sq[name][rows] = v
            shape = (-1,) + (1,) * (g.dim() - 1)
            denom = (v.sqrt() / bias2_sqrt.view(shape)).add_(self.eps)
            update = (m / bias1.view(shape)).div_(denom).mul_(self.rates[name])
            param = self.gmap.params[name]
            param.data[rows] = param.data[rows] - update

    @torch.no_grad()
    def step_nonzero(self, rows: torch.Tensor, grads: dict[str, torch.Tensor]) -> torch.Tensor:
        """:meth:`step` on the rows among ``rows`` (unique) whose gradient ``grads[name]`` (shape
        (len(rows), ...)) is non-zero in some parameter; returns that mask over ``rows``. On the CPU in one
        parallel pass (no gathers of the rows and gradients)."""
        if rows.device.type != "cpu" or rows.numel() == 0:
            touched = nonzero_rows(grads, len(rows))
            self.step(rows[touched], {name: g[touched] for name, g in grads.items()})
            return touched
        from activesplat.splat._mapper_numba import adam_nonzero_rows

        idx = rows.numpy().astype(np.int64, copy=False)
        grad = tuple(np.ascontiguousarray(grads[n].detach().numpy(), dtype=np.float32).reshape(len(idx), -1)
                     for n in PARAM_NAMES)
        self._calls += 1  # no row has been stepped more often than this
        if len(self._bias1_of) <= self._calls:
            t = np.arange(2 * self._calls + 64, dtype=np.float64)
            self._bias1_of = 1.0 - np.power(self.beta1, t)  # as _step_numba computes them
            self._bias2_sqrt_of = np.sqrt(1.0 - np.power(self.beta2, t))
        touched = adam_nonzero_rows(
            tuple(_flat(self.gmap.params[name]) for name in PARAM_NAMES),
            tuple(_flat(self.exp_avg[name]) for name in PARAM_NAMES),
            tuple(_flat(self.exp_avg_sq[name]) for name in PARAM_NAMES), grad, idx, self.steps.numpy(),
            np.array([self.rates[name] for name in PARAM_NAMES]), self._bias1_of, self._bias2_sqrt_of,
            self.beta1, self.beta2, self.eps)
        return torch.from_numpy(touched)

    def _step_numba(self, rows: torch.Tensor, grads: dict[str, torch.Tensor], steps: torch.Tensor) -> None:
        """The same update in one parallel pass per parameter, in place (CPU)."""
        from activesplat.splat._mapper_numba import adam_rows

        t = steps.numpy().astype(np.float64)
        bias1 = 1.0 - np.power(self.beta1, t)
        bias2_sqrt = np.sqrt(1.0 - np.power(self.beta2, t))
        idx = rows.numpy().astype(np.int64)
        for name in PARAM_NAMES:
            param = self.gmap.params[name]
            grad = np.ascontiguousarray(grads[name].detach().numpy().reshape(len(idx), -1), dtype=np.float32)
            adam_rows(_flat(param), _flat(self.exp_avg[name]), _flat(self.exp_avg_sq[name]), grad, idx,
                      self.rates[name] / bias1, bias2_sqrt, self.beta1, self.beta2, self.eps)


def _flat(x: torch.Tensor) -> np.ndarray:
    """(N, D) numpy view of a CPU tensor's memory (an in-place update through it reaches the tensor)."""
    a = x.detach().numpy()
    if not a.flags.c_contiguous:  # a reshape would copy, and the in-place update would be lost
        raise RuntimeError("RowAdam: a parameter or its Adam state is not contiguous")
    return a.reshape(a.shape[0], -1)
