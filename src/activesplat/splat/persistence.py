"""A mapper on disk: the Gaussian map (``gaussians.ply``, the standard 3DGS layout), the keyframe buffer
(``keyframes.npz``) and what is needed to go on mapping (``mapper.json``: intrinsics, image size, the
:class:`MapperConfig` and the frame count). The Adam state is not written: a loaded mapper starts with
fresh moments."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch

from activesplat.episode import write_npz
from activesplat.errors import InvalidInputError
from activesplat.splat.config import MapperConfig
from activesplat.splat.keyframes import Keyframe
from activesplat.splat.ply import load_ply, save_ply

if TYPE_CHECKING:
    from activesplat.splat.mapper import Mapper


def save_mapper(mapper: Mapper, directory: str | Path) -> Path:
    """Write ``gaussians.ply``, ``keyframes.npz`` and ``mapper.json`` into ``directory`` (created)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    save_ply(mapper.gaussians, directory / "gaussians.ply")
    kfs = mapper.keyframes
    h, w = mapper.height, mapper.width
    write_npz(
        directory / "keyframes.npz",
        rgb=np.stack([k.rgb for k in kfs]) if kfs else np.zeros((0, h, w, 3), np.uint8),
        depth=np.stack([k.depth for k in kfs]) if kfs else np.zeros((0, h, w), np.float32),
        pose=np.stack([k.pose for k in kfs]) if kfs else np.zeros((0, 4, 4)),
        step=np.array([k.step for k in kfs], dtype=np.int64),
    )
    meta = {"K": mapper.K.tolist(), "width": w, "height": h, "frames": mapper.frames,
            "backend": mapper.backend, "config": asdict(mapper.config)}
    (directory / "mapper.json").write_text(json.dumps(meta, indent=1))
    return directory


def load_mapper(cls: type[Mapper], directory: str | Path, backend: str | None = None,
                device: str | torch.device | None = None) -> Mapper:
    """A ``cls`` mapper read from a folder written by :func:`save_mapper` (fresh Adam state)."""
    directory = Path(directory)
    meta_path = directory / "mapper.json"
    if not meta_path.is_file():
        raise InvalidInputError(f"{directory}: not a mapper folder (no mapper.json)")
    meta = json.loads(meta_path.read_text())
    mapper = cls(meta["K"], meta["width"], meta["height"], MapperConfig.from_dict(meta["config"]),
                 backend or meta["backend"], device)
    mapper.gaussians = load_ply(directory / "gaussians.ply", mapper.device)
    mapper.optimizer = mapper._make_optimizer()
    mapper.peak_gaussians = len(mapper.gaussians)
    with np.load(directory / "keyframes.npz") as data:  # each data[key] decompresses: read once
        rgb, depth, pose, step = data["rgb"], data["depth"], data["pose"], data["step"]
    mapper.keyframes = [Keyframe(rgb[i], depth[i], pose[i], int(step[i])) for i in range(len(step))]
    mapper.frames = int(meta["frames"])
    return mapper


__all__ = ["load_mapper", "save_mapper"]
