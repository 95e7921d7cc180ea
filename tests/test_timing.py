"""The timing helpers: per-module means (Tab. VI) and phase laps."""

import time

from activesplat.timing import LapClock, Timers


def test_lap_clock_adds_each_phase_and_calls_sync_first():
    timings, calls = {"a": 5.0}, []
    clock = LapClock(timings, sync=lambda: calls.append(len(timings)))
    time.sleep(0.01)
    clock.lap("a")
    clock.lap("b")
    clock.lap("b")
    assert timings["a"] >= 5.0 + 9.0  # added to what was there
    assert 0.0 <= timings["b"] < timings["a"] - 5.0
    assert len(calls) == 3  # once per lap, before the time is read


def test_timers_divide_totals_by_steps():
    timers = Timers()
    assert timers.time("m", lambda x: x + 1, 1) == 2
    per = timers.per_step(4)
    assert set(per) == {"m"} and per["m"] == timers.total_ms["m"] / 4
    assert timers.per_step(0)["m"] == timers.total_ms["m"]


def _fresh_kernels():
    """Two new numba kernels (one calling the other), not yet compiled and not cached on disk."""
    from numba import njit

    @njit(cache=False)
    def inner(x):
        return x * 2.0

    @njit(cache=False)
    def outer(x):
        return inner(x) + 1.0

    return inner, outer


def test_jit_compile_clock_charges_compiling_to_the_running_module():
    import threading

    from activesplat.timing import OTHER_THREAD, UNTIMED, JitCompileClock

    timers = Timers()
    inner, outer = _fresh_kernels()
    with JitCompileClock(timers) as clock:
        t0 = time.perf_counter()
        assert timers.time("mapper", outer, 1.0) == 3.0  # compiles outer and, inside it, inner: counted once
        wall = time.perf_counter() - t0
        first = clock.total_s
        assert 0 < first <= wall and dict(clock.by_module) == {"mapper": first}
        timers.time("mapper", outer, 2.0)  # compiled already: nothing more
        assert clock.total_s == first
        inner(1)  # a new signature (int64) compiles, outside every timed module
        worker = threading.Thread(target=inner, args=(1j,))  # and one on another thread
        worker.start()
        worker.join()
        assert set(clock.by_module) == {"mapper", UNTIMED, OTHER_THREAD}
        assert clock.total_s == sum(clock.by_module.values())
    done = clock.total_s
    inner(True)  # after the clock is closed: not counted
    assert clock.total_s == done and timers.running == []


def test_the_progress_bar_goes_to_stderr_and_starts_where_a_resumed_run_is(capsys):
    from activesplat.timing import progress_bar

    assert progress_bar(10, "job", "it", enabled=False) is None  # --no-progress
    bar = progress_bar(10, "job", "it", initial=3)
    assert bar.n == 3
    bar.update(7)
    bar.close()
    captured = capsys.readouterr()
    assert captured.out == "" and "job: " in captured.err and "3/10" in captured.err
    assert "10/10" in captured.err


def test_the_progress_bar_redraws_seldom_where_stderr_is_a_log(capsys, monkeypatch):
    """On a terminal it redraws twice a second; into a log file or a pipe each redraw is a line of the log,
    so it redraws every 30 s, and a postfix set without a refresh waits for the next redraw."""
    import sys

    from activesplat.timing import PROGRESS_INTERVAL_LOG_S, PROGRESS_INTERVAL_S, progress_bar

    bar = progress_bar(1000, "run", "step")  # capsys: stderr is not a terminal
    assert bar.mininterval == PROGRESS_INTERVAL_LOG_S == 30.0
    for i in range(1000):
        bar.set_postfix_str(f"completion {i / 10:.1f}%", refresh=False)
        bar.update(1)
    bar.close()
    err = capsys.readouterr().err
    assert err.count("run: ") <= 3  # the first draw, the close, at most one on the way
    assert "1000/1000" in err and "completion 99.9%" in err
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert progress_bar(10, "job", "it").mininterval == PROGRESS_INTERVAL_S == 0.5
