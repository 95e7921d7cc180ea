"""What each rotation stop of an exploration saw, against what its actions would have been worth at the end
of the run. Are there stops, or turns after a replan, that the step budget would have been better without?

    python benchmarks/stop_yield.py runs/bench/medium-10*/activesplat/s0

Each episode is replayed in the simulator with its own settings (`eval.evaluate.replay_episode`) to get
the ground-truth points each frame observed first (completion points per frame). With the explorer's
stops.json:
- a rotation stop's actions run from its step to the next replan (arrival: the turns and tilts toward its
  targets and the levelling tilts) or to the next forward move (a stop at a multi-connected node on the
  way);
- the alignment after a replan runs from the replan to the first forward move (the turns toward the path);
- the end-of-run rate is the completion gained over the last `--tail` steps per action: what an action
  saved anywhere in the run would buy at the end, where saved steps go.
A stop whose points per action fall below its run's end-of-run rate cost more than it gave, if one could
have told in advance. Per run: completion, end-of-run rate, share of the sweep ceiling (with
``<scene>/sweep.json`` two folders up, as `activesplat benchmark` writes it), stops and their yield.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from activesplat.episode import read_episode
from activesplat.eval.evaluate import replay_episode


def next_forward(actions: list[str], step: int) -> int:
    """Index of the first forward move at or after `step` (len(actions) if none)."""
    return next((i for i in range(step, len(actions)) if actions[i] == "move_forward"), len(actions))


def stop_spans(actions: list[str], stops: list[dict], replans: list[int]) -> list[tuple[str, int, int]]:
    """(cause, first action, end) of every rotation stop: actions [first, end) belong to it."""
    spans = []
    for stop in stops:
        s = int(stop["step"])
        if stop["cause"] == "arrival":
            end = next((r for r in replans if r >= s), len(actions))
        else:
            end = next_forward(actions, s)
        spans.append((stop["cause"], s, end))
    return spans


def alignment_spans(actions: list[str], replans: list[int]) -> list[tuple[int, int]]:
    """(replan step, first forward move after it) for every replan."""
    return [(r, next_forward(actions, r)) for r in replans]


def analyse(episode_dir: Path, tail: int) -> dict:
    episode = read_episode(episode_dir)
    replay = replay_episode(episode, with_gain=True)
    n_points = replay["n_gt_points"]
    gain = np.asarray(replay["gain_by_frame"], np.float64) * 100.0 / n_points  # completion points per frame
    actions = list(episode.actions)
    record = json.loads((episode_dir / "stops.json").read_text())
    replans = sorted(int(r["step"]) for r in record["replans"])
    end_rate = float(gain[-tail:].sum()) / tail

    def points(first: int, end: int) -> float:  # frame k follows action k-1
        return float(gain[first + 1:end + 1].sum())

    spans = stop_spans(actions, record["stops"], replans)
    stops = [(cause, end - s, points(s, end)) for cause, s, end in spans]
    low = [(n, p) for _, n, p in stops if n and p / n < end_rate]
    align = [(end - r, points(r, end)) for r, end in alignment_spans(actions, replans)]
    sweep = episode_dir.parent.parent / "sweep.json"
    ceiling = json.loads(sweep.read_text())["completion_ratio_pct"] if sweep.exists() else None
    return {
        "run": "/".join(episode_dir.parts[-3:]), "completion": replay["completion_ratio_pct"],
        "of_ceiling": None if ceiling is None else 100.0 * replay["completion_ratio_pct"] / ceiling,
        "end_rate": 100.0 * end_rate, "stops": len(stops), "stop_actions": sum(n for _, n, _ in stops),
        "stop_points": sum(p for _, _, p in stops), "low_stops": len(low),
        "low_actions": sum(n for n, _ in low),
        "low_points": sum(p for _, p in low), "low_at_end": end_rate * sum(n for n, _ in low),
        "align_actions": sum(n for n, _ in align), "align_points": sum(p for _, p in align),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("episodes", nargs="+", type=Path, help="episode folders with stops.json")
    parser.add_argument("--tail", type=int, default=250, help="steps at the end that set the end-of-run rate")
    args = parser.parse_args()
    rows = [analyse(e, args.tail) for e in args.episodes]
    print("| run | completion % | of ceiling % | last steps, points per 100 | stops | actions per stop | "
          "points per 100 stop actions | stops below the end rate: stops / actions / points / those actions "
          "at the end rate | alignment actions / points |")
    print("|---|---|---|---|---|---|---|---|---|")

    def row(name: str, r: dict, n: int = 1) -> str:
        ceil = "–" if r["of_ceiling"] is None else f"{r['of_ceiling']:.1f}"
        return (f"| {name} | {r['completion']:.2f} | {ceil} | {r['end_rate']:.2f} | {r['stops'] / n:.1f} | "
                f"{r['stop_actions'] / max(1, r['stops']):.1f} | "
                f"{100 * r['stop_points'] / max(1, r['stop_actions']):.2f} | {r['low_stops'] / n:.1f} / "
                f"{r['low_actions'] / n:.0f} / {r['low_points'] / n:.2f} / {r['low_at_end'] / n:.2f} | "
                f"{r['align_actions'] / n:.0f} / {r['align_points'] / n:.2f} |")

    for r in rows:
        print(row(r["run"], r))
    if len(rows) > 1:
        total = {k: sum(r[k] for r in rows) for k in rows[0] if k not in ("run", "of_ceiling")}
        mean = {**total, "completion": total["completion"] / len(rows),
                "end_rate": total["end_rate"] / len(rows)}
        ceilings = [r["of_ceiling"] for r in rows if r["of_ceiling"] is not None]
        mean["of_ceiling"] = float(np.mean(ceilings)) if ceilings else None
        print(row(f"mean of {len(rows)} (per run)", mean, len(rows)))


if __name__ == "__main__":
    main()
