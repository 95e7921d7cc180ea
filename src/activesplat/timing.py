"""Per-module timing of the closed loop (the paper's Tab. VI): mean milliseconds per step; the process's
peak memory."""

from __future__ import annotations

import sys
import time
from collections import defaultdict
from collections.abc import Callable


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


def peak_rss_mb() -> float | None:
    """Peak resident memory of this process so far, in MB (None where the OS does not report it)."""
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux, bytes on macOS
    return peak / 1024.0 ** (2 if sys.platform == "darwin" else 1)


__all__ = ["Timers", "peak_rss_mb"]
