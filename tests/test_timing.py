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
