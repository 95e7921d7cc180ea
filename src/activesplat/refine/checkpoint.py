"""Resuming an offline refinement: its checkpoint file and Ctrl-C.

A checkpoint (``DIR/refined_<method>/checkpoint.pt``: parameters, Adam state, density statistics,
iteration, both random generators, progress history) is written every ``checkpoint_every`` iterations, at
the end, and when Ctrl-C stops the run (at the end of the iteration in progress, `CtrlC`). Running the same
command again continues from it and gives the same map as an uninterrupted run; a checkpoint of other
settings (method, iterations, seed, keyframes, image size, ``--refine.*``) is refused with a line naming
them, and ``restart=True`` (``--restart``) starts over. The training loop itself is
:class:`activesplat.refine.trainer.Refiner`.
"""

from __future__ import annotations

import os
import signal
import threading
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

import numpy as np
import torch

from activesplat.errors import EpisodeError, Interrupted, InvalidInputError, interrupted
from activesplat.refine.adc import DensityControl
from activesplat.splat.gaussians import GaussianMap

if TYPE_CHECKING:
    from activesplat.refine.trainer import Refiner

CHECKPOINT = "checkpoint.pt"
CHECKPOINT_VERSION = 1


def checkpoint_identity(refiner: Refiner) -> dict:
    """What a checkpoint must match to be resumed by this run."""
    return {"method": refiner.method_name, "iters": refiner.iters, "seed": refiner.seed,
            "n_keyframes": refiner.n_keyframes, "image_size": refiner.image_size,
            "config": asdict(refiner.cfg)}


def save_checkpoint(refiner: Refiner) -> Path:
    """Write the refiner's ``checkpoint.pt`` atomically (temporary file, then rename); returns its path."""
    refiner.out_dir.mkdir(parents=True, exist_ok=True)
    state = {
        "version": CHECKPOINT_VERSION, **checkpoint_identity(refiner),
        "iteration": refiner.iteration,
        "params": {name: t.detach().clone() for name, t in refiner.gmap.params.items()},
        "optimizer": refiner.optimizer.state_dict(),
        "adc": refiner.adc.state_dict(),
        "rng": refiner.rng.bit_generator.state,
        "torch_rng": refiner.generator.get_state(),
        "ema": [refiner.ema_loss, refiner.ema_psnr],
        "history": refiner.history, "totals": refiner.totals,
        "train_seconds": refiner.train_seconds, "n_initial": refiner.n_initial,
    }
    path = refiner.out_dir / CHECKPOINT
    tmp = path.with_suffix(".tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)
    refiner.saved_iteration = refiner.iteration
    return path


def load_checkpoint(refiner: Refiner, path: Path) -> None:
    """Set the refiner's training state from the checkpoint at ``path``: EpisodeError when it cannot be
    read (or is of another version), InvalidInputError naming the settings when it is another run's."""
    try:
        state = torch.load(path, weights_only=True, map_location=refiner.device)
    except Exception as err:  # noqa: BLE001 - any unreadable file is bad input here
        raise EpisodeError(f"{path}: unreadable checkpoint ({type(err).__name__}); use --restart") \
            from None
    if state.get("version") != CHECKPOINT_VERSION:
        raise EpisodeError(f"{path}: checkpoint of another version; use --restart")
    mine = checkpoint_identity(refiner)
    differ = [k for k in mine if state.get(k) != mine[k]]
    if differ:
        was = [f"{k}={state.get(k)}" for k in differ if k != "config"]
        saved = state.get("config") if isinstance(state.get("config"), dict) else {}
        was += [f"refine.{k}={saved.get(k, 'absent')}" for k, v in mine["config"].items()
                if "config" in differ and saved.get(k) != v]
        raise InvalidInputError(
            f"{path} belongs to another run ({', '.join(was) or 'other settings'}); pass the same "
            f"arguments to resume it or --restart to start over")
    refiner.gmap = GaussianMap(state["params"])
    refiner.optimizer = refiner.gmap.make_optimizer(refiner.lr, refiner.adam_eps)
    refiner.optimizer.load_state_dict(state["optimizer"])
    refiner.adc = DensityControl(refiner.cfg, 1.0, 0, refiner.device)
    refiner.adc.load_state_dict(state["adc"])
    refiner.iteration = refiner.saved_iteration = int(state["iteration"])
    refiner.rng = np.random.default_rng()
    refiner.rng.bit_generator.state = state["rng"]
    refiner.generator = torch.Generator()
    refiner.generator.set_state(state["torch_rng"].cpu())
    refiner.ema_loss, refiner.ema_psnr = state["ema"]
    refiner.history, refiner.totals = list(state["history"]), dict(state["totals"])
    refiner.train_seconds, refiner.n_initial = float(state["train_seconds"]), int(state["n_initial"])


class CtrlC:
    """Ctrl-C while the refiner trains. The first one becomes a flag (``requested``) checked between
    iterations: the loop saves a checkpoint and calls `stop` (so the checkpoint is consistent). A second one
    interrupts at once; the last checkpoint is kept. Either way one line (`errors.interrupted`) says what is
    kept and that the same command resumes, after the progress ``bar`` is closed. The handler is only
    installed in the main thread."""

    def __init__(self, refiner: Refiner, bar=None):
        self.refiner, self.bar = refiner, bar
        self.requested = False
        self._previous = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def _close_bar(self) -> None:
        if self.bar is not None:  # before the line, which it would otherwise follow
            self.bar.close()

    def stop(self) -> NoReturn:
        """After the checkpoint of a requested stop: the line saying where it is."""
        self._close_bar()
        r = self.refiner
        raise interrupted(f"refine: stopped at iteration {r.iteration} of {r.iters}, saved in "
                          f"{r.out_dir / CHECKPOINT}; the same command resumes (--restart starts over)")

    def __exit__(self, exc_type, exc, tb):
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
        if exc_type is None or not issubclass(exc_type, KeyboardInterrupt):
            return False
        if issubclass(exc_type, Interrupted):  # the line of a requested stop is said
            return False
        # a second Ctrl-C: the iteration in progress is lost, the last checkpoint is not
        self._close_bar()
        r = self.refiner
        if r.saved_iteration is None:
            kept = "nothing saved yet; the same command starts over"
        else:
            kept = (f"the checkpoint of iteration {r.saved_iteration} in {r.out_dir / CHECKPOINT} is kept; "
                    f"the same command resumes from it")
        raise interrupted(f"refine: stopped at once in iteration {r.iteration + 1} of {r.iters}: "
                          f"{kept}") from None


__all__ = ["CHECKPOINT", "CtrlC", "checkpoint_identity", "load_checkpoint", "save_checkpoint"]
