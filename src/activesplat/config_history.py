"""How a recorded configuration of an older version reads today (`activesplat.config.RunConfig`).

An episode.json records every field of the run's configuration. Fields come and go between versions:
`REMOVED` lists the fields taken out (with the value that behaves as today's code), `ADDED` the fields
added with a default that changes what runs do (with the value that does what the code did before). An old
file then reads as the run it recorded, or is refused with one line saying why.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from activesplat.errors import InvalidInputError

CONFIG_VERSION = 1
"""Version of the configuration recorded in episode.json. Every release so far writes 1: a field removed
since goes in `REMOVED`, a field added with a default that changes what a run does goes in `ADDED`, so that
an old episode.json reads as the run it recorded or is refused with a line saying why
(tests/test_config_fields.py fails until a removed or added field is described). Bump it only for a change
these two tables cannot describe (a field whose meaning changed)."""

_ANY = object()  # a removed field that only tuned another removed one: any value reads
_MEASURED_OFF = "2026-12-05, measured off and removed; last in commit 9d426c9"

REMOVED: dict[str, tuple[Any, str]] = {
    "mapper.area_budget_slack": (None, "2026-12-02, measured and reverted"),
    "mapper.area_budget_cell_m": (_ANY, "2026-12-02, with area_budget_slack"),
    "explorer.planning.score.w_entry": (0.0, "2026-11-27, measured and reverted"),
    "explorer.planning.score.entry_radius_m": (_ANY, "2026-11-27, with w_entry"),
    "explorer.multi_stop_new_m": (None, "2026-11-29, measured and reverted"),
    "explorer.multi_stop_frontier_m": (None, "2026-11-29, measured and reverted"),
    "explorer.multi_stop_frontier_cells": (_ANY, "2026-11-29, with multi_stop_frontier_m"),
    "explorer.front_faces_scores_after": (None, "2026-12-02, measured and removed"),
    "explorer.tilt_within_deg": (None, _MEASURED_OFF),
    "explorer.unsampled_views": (0, _MEASURED_OFF),
    "explorer.unsampled_radius_m": (_ANY, _MEASURED_OFF),
    "explorer.unsampled_voxel_m": (_ANY, _MEASURED_OFF),
    "explorer.unsampled_min_weight": (_ANY, _MEASURED_OFF),
    "explorer.global_halving_m": (None, _MEASURED_OFF),
    "explorer.bridge_gain_m": (None, _MEASURED_OFF),
    "explorer.neck_travel": (False, _MEASURED_OFF),
    "explorer.cut_off_look_m": (None, _MEASURED_OFF),
    "explorer.global_tour": (False, _MEASURED_OFF),
    "explorer.route_memory_m": (None, _MEASURED_OFF),
    "explorer.route_min_info": (_ANY, _MEASURED_OFF),
    "explorer.route_in_place": (False, _MEASURED_OFF),
    "explorer.last_call_steps": (None, _MEASURED_OFF),
    "explorer.last_call_min_info": (_ANY, _MEASURED_OFF),
    "explorer.last_call_steps_per_m": (_ANY, _MEASURED_OFF),
    "explorer.out_of_reach_last": (False, _MEASURED_OFF),
    "explorer.keep_promise_m": (None, _MEASURED_OFF),
    "explorer.commit_global_m": (None, _MEASURED_OFF),
    "explorer.postpone_once_m": (None, _MEASURED_OFF),
    "explorer.collision_obstacle_m": (None, _MEASURED_OFF),
    "explorer.collision_arrive_m": (None, _MEASURED_OFF),
    "explorer.collision_fail_after": (_ANY, _MEASURED_OFF),
    "explorer.flat_until_step": (None, _MEASURED_OFF),
    "explorer.planning.panorama.front_faces_scores": (False, _MEASURED_OFF),
    "explorer.planning.panorama.scores_back_face_seen": (0.0, _MEASURED_OFF),
    "explorer.planning.panorama.back_faces_in_window": (False, _MEASURED_OFF),
    "explorer.planning.rotation.max_cluster_yaw_deg": (None, _MEASURED_OFF),
    "explorer.planning.high_loss.forget_resolved": (False, _MEASURED_OFF),
    "explorer.planning.high_loss.resolved_tolerance_m": (_ANY, _MEASURED_OFF),
    "explorer.planning.score.w_q": (0.0, _MEASURED_OFF),
    "explorer.planning.score.quality_in_local": (_ANY, _MEASURED_OFF),
    "explorer.planning.score.quality_radius_m": (_ANY, _MEASURED_OFF),
    "explorer.planning.score.quality_voxel_m": (_ANY, _MEASURED_OFF),
    "explorer.planning.score.quality_reference": (_ANY, _MEASURED_OFF),
    "explorer.planning.score.quality_below_invisible": (_ANY, _MEASURED_OFF),
    "explorer.planning.score.inv_reference": (None, _MEASURED_OFF),
    "explorer.planning.score.vol_reference_m3": (None, _MEASURED_OFF),
    "mapper.densify_median_depth": (False, _MEASURED_OFF),
    "mapper.densify_represented_tol": (None, _MEASURED_OFF),
    "mapper.densify_represented_px": (
        _ANY, "2026-12-05, with densify_represented_tol; last in commit 9d426c9"),
    "mapper.densify_represented_age": (
        _ANY, "2026-12-05, with densify_represented_tol; last in commit 9d426c9"),
    "mapper.init_max_elongation": (1.0, _MEASURED_OFF),
    "mapper.init_slant_fill": (1, _MEASURED_OFF),
    "mapper.cull_occluded_masks": (False, _MEASURED_OFF),
}
"""Fields removed from RunConfig: dotted path -> (the value that behaves as today's code, when and why). An
old file holding that value (or any value, for a field that only tuned a removed one) reads without it; any
other value is refused, since this version cannot run it."""

ADDED: dict[str, Any] = {
    "sim.texture_filter": "nearest",
    "mapper.init_normal_scale": 1.0,
    "mapper.densify_front_faces_only": False,
    "mapper.edge_band_px": 0,
    "mapper.detail_colour_range": None,
    "mapper.cull_occluded_margin_m": None,
    "mapper.planar_depth": False,
    "explorer.fewest_action_tour": False,
    "explorer.global_in_horizon": True,
    "explorer.global_information_first": False,
    "explorer.panorama_every_subregion": False,
    "explorer.multi_stop_spacing_m": 0.0,
    "explorer.detour_m": None,
    "explorer.local_near_m": None,
    "explorer.retry_unreachable": False,
    "explorer.neck_margin_m": None,
    "explorer.way_back_m": None,
    "explorer.start_blocks": None,
    "explorer.leave_when_cut_off": False,
    "explorer.planning.high_loss.max_targets": 0,
    "explorer.planning.panorama.front_faces_targets": False,
    "explorer.planning.panorama.score_lod_voxel_m": None,
    "refine.planar_depth": False,
}
"""Fields added to RunConfig with a default that is not what runs did before them (a rule added on, or added
off and turned on later): dotted path -> the value that does what the code did before the field existed. A
field whose default keeps the old behaviour (an option added off and still off, or one that only tunes an
option whose entry here turns it off) needs none. An episode.json that lacks one (written before it) reads
as that value, with a warning naming it; a hand-written partial config file takes today's defaults. The
``mapper`` entries are also `activesplat.splat.config.ADDED_FIELDS`, for an older mapper.json; the ``refine``
entries also fill the recorded settings ``activesplat refine`` starts from (`recorded_refine_config`)."""

_ABSENT = object()


def pop_path(data: dict, path: list[str]):
    for name in path[:-1]:
        data = data.get(name) if isinstance(data, dict) else None
    return data.pop(path[-1], _ABSENT) if isinstance(data, dict) else _ABSENT


def drop_removed(data: dict, source: str) -> None:
    """Take the `REMOVED` fields out of a config dictionary (in place): those at the value that behaves as
    today's code go silently, any other value is an InvalidInputError naming the field."""
    for dotted, (same, when) in REMOVED.items():
        value = pop_path(data, dotted.split("."))
        if value is _ABSENT or same is _ANY or value == same:
            continue
        raise InvalidInputError(f"{source}: {dotted} was removed ({when}); this activesplat cannot run "
                                f"{dotted} = {value!r}. Use the activesplat version that wrote the file, or "
                                f"remove the key from a copy of the file to run without it")


def fill_added(config: dict, path: Path, only: str = "") -> dict:
    """An episode.json's recorded config with each `ADDED` field it lacks set to the value its version ran
    with, and a warning naming them (episode.json records every field, so a missing one is younger than
    the file). ``only``: just the fields whose dotted path starts with it (``"refine."``)."""
    import copy

    config = copy.deepcopy(config)
    filled = []
    for dotted, old in ADDED.items():
        if not dotted.startswith(only):
            continue
        *groups, name = dotted.split(".")
        inner = config
        for g in groups:
            inner = inner.get(g) if isinstance(inner, dict) else None
        if isinstance(inner, dict) and name not in inner:
            inner[name] = old
            filled.append(f"{dotted}={json.dumps(old)}")
    if filled:
        import warnings

        warnings.warn(f"{path} was written before {len(filled)} field(s) whose default has changed; it runs "
                      f"with the values of its version: {', '.join(filled)} (options override them)",
                      stacklevel=3)
    return config
