"""Per-module timing of the closed loop (the paper's Tab. VI): mean milliseconds per step; the process's
peak memory."""

from __future__ import annotations

import sys
import time
from collections import defaultdict
from collections.abc import Callable


def progress_bar(total: int, desc: str, unit: str, enabled: bool = True, **kwargs):
    """The progress bar every long command shows on stderr (tqdm, at most two updates a second, as wide as
    the terminal); None when `enabled` is off (``--no-progress``)."""
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, dynamic_ncols=True, file=sys.stderr, mininterval=0.5,
                **kwargs)


class Timers:
    """Mean milliseconds per step of each module (Tab. VI): totals divided by the step count."""

    def __init__(self) -> None:
        self.total_ms: dict[str, float] = defaultdict(float)

    def time(self, name: str, fn: Callable, *args, **kwargs):
        """Call ``fn(*args, **kwargs)`` and add its wall time to module ``name``."""
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            self.total_ms[name] += 1000.0 * (time.perf_counter() - t0)

    def per_step(self, steps: int) -> dict[str, float]:
        return {k: v / max(steps, 1) for k, v in self.total_ms.items()}


class LapClock:
    """Phases of one pass, timed in a row: each :meth:`lap` adds the wall time since the previous lap (ms)
    to ``timings[name]``. ``sync`` (e.g. ``torch.cuda.synchronize``) is called first at every lap, so that
    a phase's GPU kernels count for that phase and not for the next one that waits on them."""

    def __init__(self, timings: dict[str, float], sync: Callable[[], None] | None = None):
        self.timings, self.sync, self.t = timings, sync, time.perf_counter()

    def lap(self, name: str) -> None:
        if self.sync is not None:
            self.sync()
        now = time.perf_counter()
        self.timings[name] = self.timings.get(name, 0.0) + 1000.0 * (now - self.t)
        self.t = now


def peak_rss_mb() -> float | None:
    """Peak resident memory of this process so far, in MB (None where the OS does not report it)."""
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux, bytes on macOS
    return peak / 1024.0 ** (2 if sys.platform == "darwin" else 1)


__all__ = ["LapClock", "Timers", "peak_rss_mb"]
