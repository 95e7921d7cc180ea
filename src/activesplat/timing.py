"""Per-module timing of the closed loop (the paper's Tab. VI): mean milliseconds per step; the seconds of
it that numba spent compiling kernels; the process's peak memory."""

from __future__ import annotations

import sys
import threading
import time
from collections import defaultdict
from collections.abc import Callable

PROGRESS_INTERVAL_S = 0.5
"""Seconds between two redraws of a progress bar on a terminal."""
PROGRESS_INTERVAL_LOG_S = 30.0
"""Seconds between two redraws when stderr is not a terminal (a log file, a pipe, a batch job): each redraw
is a line of the log there, so a 2000-step run writes tens of them, not thousands."""


def progress_bar(total: int, desc: str, unit: str, enabled: bool = True, initial: int = 0, **kwargs):
    """The progress bar every long command shows on stderr (tqdm, as wide as the terminal), `total` `unit`s
    long, starting at `initial` (a resumed run); None when `enabled` is off (``--no-progress``). It redraws
    at most every `PROGRESS_INTERVAL_S` on a terminal and every `PROGRESS_INTERVAL_LOG_S` elsewhere; callers
    set the postfix with ``refresh=False`` so that it waits for the next redraw. Other keyword arguments go
    to tqdm."""
    if not enabled:
        return None
    from tqdm import tqdm

    interval = PROGRESS_INTERVAL_S if _is_terminal(sys.stderr) else PROGRESS_INTERVAL_LOG_S
    return tqdm(total=total, desc=desc, unit=unit, initial=initial, dynamic_ncols=True, file=sys.stderr,
                mininterval=interval, **kwargs)


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # a replaced or closed stream
        return False


class Timers:
    """Mean milliseconds per step of each module (Tab. VI): totals divided by the step count."""

    def __init__(self) -> None:
        self.total_ms: dict[str, float] = defaultdict(float)
        self.running: list[str] = []
        """The modules being timed now, innermost last (what a :class:`JitCompileClock` charges)."""

    def time(self, name: str, fn: Callable, *args, **kwargs):
        """Call ``fn(*args, **kwargs)`` and add its wall time to module ``name``."""
        t0 = time.perf_counter()
        self.running.append(name)
        try:
            return fn(*args, **kwargs)
        finally:
            self.running.pop()
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


UNTIMED = "untimed"
"""`JitCompileClock.by_module` key of compiles on the timing thread outside every timed module."""
OTHER_THREAD = "other_thread"
"""`JitCompileClock.by_module` key of compiles on another thread (e.g. the live evaluation's worker)."""


class JitCompileClock:
    """Seconds numba spends compiling kernels while installed (``with clock:``), from its
    ``"numba:compile"`` events: in total and by the module of `timers` that was running on the thread that
    installed it (:data:`UNTIMED`, :data:`OTHER_THREAD` otherwise). A kernel loaded from numba's on-disk
    cache raises no such event, so after the first run following an install or a change of the code this
    stays at 0. A compile that compiles the kernels it calls counts once (the outermost event); compiles
    do not overlap, numba holds one lock over them."""

    def __init__(self, timers: Timers | None = None):
        self.timers = timers
        self.total_s = 0.0
        self.by_module: dict[str, float] = defaultdict(float)
        self._thread = threading.get_ident()
        self._depth, self._t0, self._listener = 0, 0.0, None

    def _start(self) -> None:
        if self._depth == 0:
            self._t0 = time.perf_counter()
        self._depth += 1

    def _end(self) -> None:
        self._depth -= 1
        if self._depth:
            return
        seconds = time.perf_counter() - self._t0
        self.total_s += seconds
        if threading.get_ident() != self._thread:
            module = OTHER_THREAD
        else:
            running = self.timers.running if self.timers is not None else []
            module = running[-1] if running else UNTIMED
        self.by_module[module] += seconds

    def __enter__(self) -> JitCompileClock:
        from numba.core import event

        clock = self

        class _Listener(event.Listener):
            def on_start(self, ev) -> None:
                clock._start()

            def on_end(self, ev) -> None:
                clock._end()

        self._thread = threading.get_ident()
        self._listener = _Listener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Stop listening (again: nothing)."""
        if self._listener is not None:
            from numba.core import event

            event.unregister("numba:compile", self._listener)
            self._listener = None


def peak_rss_mb() -> float | None:
    """Peak resident memory of this process so far, in MB (None where the OS does not report it)."""
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux, bytes on macOS
    return peak / 1024.0 ** (2 if sys.platform == "darwin" else 1)


__all__ = ["OTHER_THREAD", "UNTIMED", "JitCompileClock", "LapClock", "Timers", "peak_rss_mb"]
