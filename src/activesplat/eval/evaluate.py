"""`activesplat evaluate DIR`: recompute an episode's completion metrics from its action log alone."""

from __future__ import annotations

import json
from pathlib import Path

from activesplat.episode import Episode, has_no_ground_truth, read_episode, write_json_atomic
from activesplat.errors import EpisodeError, check_output_file
from activesplat.eval.coverage import CoverageConfig
from activesplat.eval.replay import replay_coverage

COMPLETION_KEYS = ("completion_ratio_pct", "completion_cm", "completion_cm_uncapped", "within_cap_pct",
                   "n_gt_points", "path_length_m", "steps")


def parse_sim_overrides(items: list[str]) -> dict:
    """``["texture_filter=nearest", "width=128"]`` -> SimConfig overrides: values that read as Python
    literals (numbers, tuples) become them, anything else stays a string."""
    import ast

    out = {}
    for item in items:
        key, _, value = item.partition("=")
        try:
            out[key] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            out[key] = value
    return out


def recorded_sim_config(meta: dict, overrides: dict | None = None, source: str | Path = "episode.json"):
    """The SimConfig an episode was recorded with (episode.json's config.sim), with ``overrides`` on top.
    A field younger than the file takes the value its version ran with (`activesplat.config.ADDED`, e.g.
    texture_filter "nearest" for an episode recorded before the area filter), with a warning naming
    ``source``: the map was trained on that camera's images, so its renders are compared with them."""
    from activesplat.config_history import fill_added
    from activesplat.sim import SimConfig

    saved = meta.get("config", {}).get("sim")
    if isinstance(saved, dict):
        saved = fill_added({"sim": saved}, Path(source), only="sim.")["sim"]
    fields = SimConfig.__dataclass_fields__
    kwargs = {k: tuple(v) if isinstance(v, list) else v for k, v in (saved or {}).items() if k in fields}
    return SimConfig(**{**kwargs, **(overrides or {})})


def simulated_scene(meta: dict, folder):
    """The scene of a simulated episode's episode.json; EpisodeError for one explored in an environment
    without ground truth (a robot, a user's own ``Environment``) or naming no scene."""
    from activesplat.sim import load_scene

    if has_no_ground_truth(meta):
        raise EpisodeError(f"{folder} was explored in an environment without ground truth "
                           f"({meta.get('scene')}: a robot or a user's own Environment): this needs a "
                           f"simulated episode")
    if "scene" not in meta:
        raise EpisodeError(f"{folder}/episode.json names no scene (not a simulated episode)")
    return load_scene(meta["scene"], z_up=bool(meta.get("z_up", False)), floor=meta.get("floor"))


def replay_episode(episode: Episode, **options) -> dict:
    """`replay_coverage` of an episode (`read_episode`) with the scene, coverage and simulator settings it
    was recorded with; `options` are replay_coverage's (``with_completed``, ``with_gain``)."""

    meta = episode.meta
    scene = simulated_scene(meta, episode.dir)
    cov = meta.get("config", {}).get("coverage", {})
    cfg = CoverageConfig(**{k: v for k, v in cov.items() if k in CoverageConfig.__dataclass_fields__})
    sim_config = recorded_sim_config(meta, source=episode.dir / "episode.json")
    return replay_coverage(scene, episode.start_pose, episode.actions, cfg, expected_poses=episode.poses,
                           sim_config=sim_config, **options)


def evaluate_episode(path: str | Path, write: bool = True) -> dict:
    """Replay DIR/actions.txt from the recorded start pose, measure completion (docs/protocol.md §6) and
    update DIR/metrics.json (a partial episode gets one marked `"complete": false`)."""
    episode = read_episode(path)
    metrics_path = episode.dir / "metrics.json"
    if write:  # before the replay (a read-only folder failed after it)
        check_output_file(metrics_path)
    result = replay_episode(episode)
    metrics = {"complete": False}
    if metrics_path.exists():
        try:
            metrics = json.loads(metrics_path.read_text())
        except ValueError as exc:
            raise EpisodeError(f"{metrics_path} is unreadable ({exc}); move it away to evaluate the episode "
                               f"anew") from None
        if not isinstance(metrics, dict):
            raise EpisodeError(f"{metrics_path} does not hold a JSON object; move it away to evaluate the "
                               f"episode anew")
    metrics.update({k: result[k] for k in COMPLETION_KEYS})
    if write:
        write_json_atomic(metrics_path, metrics)
    return metrics
