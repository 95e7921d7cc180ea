"""Reading an episode folder for offline refinement (paper sec. III-D4): the checks made before anything
slow happens, the online map with the mapper's settings and the keyframe buffer (`load_episode_map`),
and the same keyframes rendered again at another resolution (`rerender_keyframes`)."""

from __future__ import annotations

import json
import zipfile
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch

from activesplat.errors import EpisodeError, InvalidInputError
from activesplat.refine.config import METHODS
from activesplat.splat.config import MapperConfig
from activesplat.splat.gaussians import GaussianMap
from activesplat.splat.ply import load_ply

UNREADABLE = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error)
"""What numpy raises for a keyframes.npz that is not a complete archive of the expected arrays (an array
missing, a truncated file, a member whose data fails its CRC or does not decompress)."""


def check_arguments(episode_dir: str | Path, method: str, iters: int) -> Path:
    """Validate the command's input before anything slow happens; returns the episode folder.

    Raises InvalidInputError (unknown method, iters <= 0) or EpisodeError (no folder, no keyframes.npz,
    zero keyframes, no map)."""
    if method not in METHODS:
        raise InvalidInputError(f"unknown refinement method {method!r}; expected one of {', '.join(METHODS)}")
    if isinstance(iters, bool) or not isinstance(iters, (int, np.integer)) or iters <= 0:
        raise InvalidInputError(f"--iters must be a positive number of iterations, got {iters}")
    path = Path(episode_dir)
    if not path.is_dir():
        raise EpisodeError(f"{path}: no such episode folder")
    keyframes = path / "keyframes.npz"
    if not keyframes.is_file():
        raise EpisodeError(f"{path}: no keyframes.npz, nothing to refine from (not an episode folder?)")
    try:
        with np.load(keyframes) as data:
            count = len(data["step"])
    except UNREADABLE as err:
        raise EpisodeError(f"{keyframes}: unreadable keyframe buffer ({err})") from None
    if count == 0:
        raise EpisodeError(f"{keyframes}: the keyframe buffer is empty, nothing to refine from")
    for name in ("mapper.json", "gaussians.ply"):
        if not (path / name).is_file():
            raise EpisodeError(f"{path}: no {name} (not an episode folder written by `activesplat explore`?)")
    return path


@dataclass
class EpisodeMap:
    """What refinement reads from an episode folder: the online map, the mapper's settings and the
    keyframe buffer as stacked arrays (rgb (N,H,W,3) uint8, depth (N,H,W) float32 m, poses (N,4,4)
    camera-to-world)."""

    K: np.ndarray
    width: int
    height: int
    config: MapperConfig
    gaussians: GaussianMap
    rgb: np.ndarray
    depth: np.ndarray
    poses: np.ndarray


def load_episode_map(episode_dir: str | Path, device: str | torch.device = "cpu") -> EpisodeMap:
    """Read gaussians.ply (onto ``device``), mapper.json and keyframes.npz (each keyframe array read once,
    so the buffer costs its own size in memory; EpisodeError on inconsistent files)."""
    path = Path(episode_dir)
    try:
        meta = json.loads((path / "mapper.json").read_text())
        K, width, height = np.asarray(meta["K"], dtype=np.float64), int(meta["width"]), int(meta["height"])
        config = MapperConfig.from_dict(meta["config"])
    except (ValueError, KeyError, TypeError) as err:
        raise EpisodeError(f"{path / 'mapper.json'}: unreadable mapper settings ({err})") from None
    try:
        with np.load(path / "keyframes.npz") as data:
            rgb, depth, poses = data["rgb"], data["depth"].astype(np.float32), data["pose"].astype(np.float64)
    except UNREADABLE as err:  # check_arguments read only the steps: an array may be missing or damaged
        raise EpisodeError(f"{path / 'keyframes.npz'}: unreadable keyframe buffer ({err})") from None
    n = len(rgb)
    if rgb.shape != (n, height, width, 3) or depth.shape != (n, height, width) or poses.shape != (n, 4, 4):
        raise EpisodeError(f"{path / 'keyframes.npz'}: keyframes of shape {rgb.shape} / {depth.shape} / "
                           f"{poses.shape} do not match the {width}x{height} camera of mapper.json")
    return EpisodeMap(K, width, height, config, load_ply(path / "gaussians.ply", device), rgb, depth, poses)


def rerender_keyframes(episode_dir: Path, mapper: EpisodeMap, size: int) -> EpisodeMap:
    """The keyframe buffer rendered again by the episode's simulator at ``size`` x ``size`` pixels from the
    same poses (the paper refines at 512 x 512 what it explored at 256 x 256). Simulated episodes only."""
    from activesplat.eval.render_eval import episode_simulator
    from activesplat.geometry import intrinsics

    if isinstance(size, bool) or not 16 <= size <= 4096:
        raise InvalidInputError(f"image_size must be between 16 and 4096 pixels, got {size!r}")
    _, sim = episode_simulator(episode_dir, {"width": size, "height": size})
    views = [sim.render(pose, size, size) for pose in mapper.poses]
    rgb = np.stack([v[0] for v in views]) if views else np.zeros((0, size, size, 3), np.uint8)
    depth = (np.stack([v[1] for v in views]).astype(np.float32) if views
             else np.zeros((0, size, size), np.float32))
    return replace(mapper, K=intrinsics(size, size, sim.config.hfov_deg), width=size, height=size, rgb=rgb,
                   depth=depth)


__all__ = ["EpisodeMap", "check_arguments", "load_episode_map", "rerender_keyframes"]
