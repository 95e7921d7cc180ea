"""How an exploration spent its steps: the multi-room measures of docs/benchmark.md §"Multi-room behaviour".

- action shares: how many actions turned or tilted the camera instead of moving;
- rooms entered: rooms of a built-in house the agent stood inside (``inset_m`` past their walls), corridors
  not counted;
- per-room coverage: the completion ratio (docs/protocol.md §6) of the ground-truth points of each room,
  a point's room being the one whose floor-plan rectangles hold its (x, z);
- relative to the sweep ceiling (eval/sweep.py): the share of the ceiling reached, per house and per room,
  and the steps needed to reach 90 % and 95 % of it;
- the paper's Tab. III: completion at 25 / 50 / 75 / 100 % of the episode's path length.

Everything here works from what an episode folder holds (actions, poses, the completion curve, the
per-point completion mask), so it applies to old episodes too (`activesplat.eval.behaviour.analyse_episode`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

ROTATION_ACTIONS = ("turn_left", "turn_right", "look_up", "look_down")
"""Actions that move the camera without moving the agent."""


@dataclass(frozen=True)
class BehaviourConfig:
    """Definitions of the multi-room measures (ours; the paper defines only Tab. III's path fractions)."""

    entered_inset_m: float = 0.5
    """A room counts as entered when the agent's position is this far inside its floor-plan rectangles
    (past the wall line): looking in from the doorway does not count."""
    min_room_points: int = 200
    """Rooms with fewer ground-truth points seen by the sweep are left out of the worst-room measure (a
    sliver of a room: its share would be noise)."""
    path_fractions: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0)
    """Fractions of the episode's path length of the paper's Tab. III."""
    ceiling_targets_pct: tuple[float, ...] = (90.0, 95.0)
    """Shares of the sweep ceiling whose first step is reported (steps_to_90_pct_ceiling, ...)."""


def action_counts(actions: Iterable[str]) -> dict[str, int]:
    return dict(sorted(Counter(actions).items()))


def rotation_pct(actions: Sequence[str]) -> float:
    """Share (%) of the actions that turned or tilted the camera."""
    actions = list(actions)
    if not actions:
        return 0.0
    return 100.0 * sum(a in ROTATION_ACTIONS for a in actions) / len(actions)


def rotation_causes(actions: Sequence[str], causes: Sequence[str]) -> dict[str, int]:
    """How many turn / tilt actions each cause (the explorer's `last_cause`: bootstrap, arrival, multi_stop,
    path, level, idle, escape, fallback, ...) took, most first."""
    counts = Counter(c for a, c in zip(actions, causes, strict=True) if a in ROTATION_ACTIONS)
    return dict(counts.most_common())


def action_kind(action: str) -> str:
    """"turn", "tilt", or the action's own name (move_forward, ...)."""
    if action in ("turn_left", "turn_right"):
        return "turn"
    if action in ("look_up", "look_down"):
        return "tilt"
    return action


def completion_gain(gain_by_frame: np.ndarray, actions: Sequence[str], causes: Sequence[str],
                    n_gt_points: int) -> dict:
    """Where the completion came from. `gain_by_frame` (frames,): the ground-truth points each frame observed
    first (`CoverageAccumulator.gain_by_frame`); frame 0 is the start's, frame k the one after action k-1.
    Returns ``by_cause`` (the explorer's `last_cause` of each action, plus "start" for frame 0) and
    ``by_action`` (turn / tilt / move_forward), each {name: {"actions": n, "completion_pct": share of the
    ground-truth points first observed after those actions}}, most completion first: a rotation that shows
    nothing new costs a step for nothing, and a cause whose share is small for its actions is where steps
    go to waste."""
    gain = np.asarray(gain_by_frame, np.int64)
    if len(gain) != len(actions) + 1 or len(causes) != len(actions):
        raise ValueError(f"completion_gain needs one frame more than actions and one cause per action, got "
                         f"{len(gain)} frames, {len(actions)} actions, {len(causes)} causes")

    def table(names: Sequence[str]) -> dict:
        out: dict = {}
        for name, g in zip(["start", *names], gain, strict=True):
            entry = out.setdefault(name, {"actions": 0, "points": 0})
            entry["actions"] += name != "start"
            entry["points"] += int(g)
        scale = 100.0 / max(1, n_gt_points)
        return {name: {"actions": e["actions"], "completion_pct": e["points"] * scale}
                for name, e in sorted(out.items(), key=lambda kv: -kv[1]["points"])}

    return {"by_cause": table(list(causes)), "by_action": table([action_kind(a) for a in actions])}


def rooms_entered(house, positions_xz: np.ndarray, inset_m: float) -> list[str]:
    """Names of the (non-corridor) rooms whose floor-plan rectangles, shrunk by `inset_m`, held the agent
    at some step, in the order first entered."""
    labels = house.label_points(np.asarray(positions_xz, np.float64).reshape(-1, 2), inset=inset_m)
    names = house.room_names
    corridors = set(house.corridor_names)
    first = dict.fromkeys(names[i] for i in labels if i >= 0)
    return [n for n in first if n not in corridors]


def room_completion(house, gt_points: np.ndarray, completed: np.ndarray) -> dict[str, dict]:
    """Per room name: its ground-truth point count and the share (%) of them completed. Points outside
    every room (exterior faces of the outer walls, inside walls) belong to no room."""
    labels = house.label_points(np.asarray(gt_points)[:, [0, 2]])
    completed = np.asarray(completed, bool)
    out = {}
    for i, name in enumerate(house.room_names):
        mine = labels == i
        n = int(mine.sum())
        out[name] = {"points": n,
                     "completion_ratio_pct": float(100.0 * completed[mine].mean()) if n else None}
    return out


def at_path_fractions(curve: Sequence[dict], fractions: Sequence[float]) -> list[dict]:
    """Tab. III: for each fraction f of the final path length L, the completion reached with a path of at
    most f·L (the last curve point whose path length is within it; curves are taken every 50 steps, so
    this is a lower bound by at most 50 steps of progress)."""
    if not curve:
        return []
    total = float(curve[-1]["path_length_m"])
    rows = []
    for f in fractions:
        allowed = f * total + 1e-9
        within = [p for p in curve if p["path_length_m"] <= allowed]
        point = within[-1] if within else None
        rows.append({"fraction": float(f), "path_length_m": f * total,
                     "completion_ratio_pct": point["completion_ratio_pct"] if point else 0.0,
                     "completion_cm": point["completion_cm"] if point else None,
                     "step": point["step"] if point else 0})
    return rows


def steps_to_reach(curve: Sequence[dict], target_pct: float) -> int | None:
    """The first curve step whose completion ratio is at least `target_pct`; None if never reached."""
    for p in curve:
        if p["completion_ratio_pct"] >= target_pct:
            return int(p["step"])
    return None


def relative_to_ceiling(metrics: dict, ceiling: dict, cfg: BehaviourConfig | None = None) -> dict:
    """Measures of an episode's `metrics` against the sweep `ceiling` of its scene (``completion_ratio_pct``
    and, for built-in houses, ``rooms`` as room_completion gives): the share of the ceiling reached, the
    steps to reach `cfg.ceiling_targets_pct` of it, and per room its share of the room's own ceiling."""
    cfg = cfg or BehaviourConfig()
    if "completion_ratio_pct" not in metrics:  # a run without ground truth
        return {}
    top = float(ceiling["completion_ratio_pct"])
    out: dict = {"ceiling_pct": top,
                 "of_ceiling_pct": 100.0 * metrics["completion_ratio_pct"] / top if top > 0 else None}
    curve = metrics.get("curve") or []
    for target in cfg.ceiling_targets_pct:
        out[f"steps_to_{target:g}_pct_ceiling"] = steps_to_reach(curve, target / 100.0 * top)
    rooms, room_ceiling = (metrics.get("rooms") or {}).get("completion"), ceiling.get("rooms")
    if rooms and room_ceiling:
        shares = {}
        for name, room in rooms.items():
            top_room = room_ceiling.get(name)
            if (top_room and room["completion_ratio_pct"] is not None and top_room["completion_ratio_pct"]
                    and top_room["points"] * top_room["completion_ratio_pct"] / 100.0 >= cfg.min_room_points):
                shares[name] = 100.0 * room["completion_ratio_pct"] / top_room["completion_ratio_pct"]
        out["room_of_ceiling_pct"] = shares
        if shares:
            worst = min(shares, key=shares.get)
            out["worst_room"] = worst
            out["worst_room_of_ceiling_pct"] = shares[worst]
    return out


def room_behaviour(house, positions_xz: np.ndarray, gt_points=None, completed=None,
                   cfg: BehaviourConfig | None = None) -> dict:
    """The metrics.json entries of an episode in a built-in house: ``rooms_total``, ``rooms_entered`` and
    ``rooms`` (names entered, and with the ground-truth points and their completed mask the per-room
    completion)."""
    cfg = cfg or BehaviourConfig()
    entered = rooms_entered(house, positions_xz, cfg.entered_inset_m)
    out: dict = {"rooms_total": int(house.n_rooms), "rooms_entered": len(entered),
                 "rooms": {"entered": entered}}
    if gt_points is not None and completed is not None:
        out["rooms"]["completion"] = room_completion(house, gt_points, completed)
    return out


def episode_behaviour(actions: Sequence[str], positions_xz: np.ndarray, house=None, gt_points=None,
                      completed=None, cfg: BehaviourConfig | None = None) -> dict:
    """``action_counts``, ``rotation_pct``, and for a built-in house room_behaviour's entries."""
    out: dict = {"action_counts": action_counts(actions), "rotation_pct": rotation_pct(actions)}
    if house is not None:
        out.update(room_behaviour(house, positions_xz, gt_points, completed, cfg))
    return out


__all__ = ["ROTATION_ACTIONS", "BehaviourConfig", "action_counts", "action_kind", "at_path_fractions",
           "completion_gain", "episode_behaviour",
           "relative_to_ceiling", "room_behaviour", "room_completion", "rooms_entered", "rotation_causes",
           "rotation_pct", "steps_to_reach"]
