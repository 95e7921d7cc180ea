"""The episode folder's writer and reader: what an exploration leaves, partial episodes, corrupt files."""

import json

import numpy as np
import pytest

from activesplat.episode import EpisodeWriter, is_complete, read_episode, read_poses
from activesplat.errors import EpisodeError


def _write(folder, n_actions: int, complete: bool = True):
    writer = EpisodeWriter(folder, overwrite=True)
    writer.start({"scene": "small-0", "start_pose": np.eye(4).tolist()}, np.eye(4))
    for step in range(1, n_actions + 1):
        writer.record(step, "turn_left", np.eye(4))
    if complete:
        writer.finish({"steps": n_actions})
    else:
        writer.close()
    return folder


def test_replacing_an_episode_removes_what_was_made_from_the_old_one(tmp_path):
    ep = _write(tmp_path / "ep", 3)
    for name in ("render_metrics.json", "render_grid.png", "render_budget.json", "trajectory.png",
                 "coverage.npz"):
        (ep / name).write_text("old")
    (ep / "refined_3dgs").mkdir()
    (ep / "refined_3dgs" / "checkpoint.pt").write_text("old")
    (ep / "notes.txt").write_text("the user's own file")
    with pytest.raises(EpisodeError, match="complete episode.*--overwrite"):
        EpisodeWriter(ep)
    EpisodeWriter(ep, overwrite=True)
    assert sorted(p.name for p in ep.iterdir()) == ["notes.txt"]


def test_a_partial_episode_is_not_replaced_without_overwrite(tmp_path):
    ep = _write(tmp_path / "ep", 4, complete=False)
    with pytest.raises(EpisodeError, match=r"partial episode \(4 actions\).*--overwrite"):
        EpisodeWriter(ep)
    # `evaluate` marks a partial episode's metrics.json "complete": false: still partial
    (ep / "metrics.json").write_text(json.dumps({"complete": False, "steps": 4}))
    with pytest.raises(EpisodeError, match="partial episode"):
        EpisodeWriter(ep)
    assert not read_episode(ep).complete
    EpisodeWriter(ep, overwrite=True)
    assert not (ep / "actions.txt").exists()


def test_poses_missing_or_corrupt_are_named(tmp_path):
    ep = _write(tmp_path / "ep", 5)
    lines = (ep / "poses.txt").read_text().splitlines(keepends=True)
    (ep / "poses.txt").write_text("".join(lines[:3] + ["3 garbage\n"] + lines[4:]))
    with pytest.raises(EpisodeError, match="poses.txt, line 4"):
        read_episode(ep)
    (ep / "poses.txt").write_text("".join(lines[:4]))  # a complete episode with poses missing
    with pytest.raises(EpisodeError, match="4 readable poses for 5 actions"):
        read_episode(ep)
    (ep / "poses.txt").unlink()
    with pytest.raises(EpisodeError, match="no poses.txt"):
        read_episode(ep)


def test_a_crash_may_cut_only_the_last_line(tmp_path):
    ep = _write(tmp_path / "ep", 5, complete=False)
    text = (ep / "poses.txt").read_text()
    (ep / "poses.txt").write_text(text[:-10])  # the last pose line cut half-way
    got = read_episode(ep)
    assert not got.complete and len(got.actions) == 4 and len(got.poses) == 5


def test_completeness_and_poses_of_a_folder_without_actions(tmp_path):
    """`is_complete` and `read_poses` read any folder with a metrics.json / poses.txt, such as a map of a
    recording (no actions.txt, which `read_episode` needs): the viewer's timeline of a recording uses them."""
    ep = _write(tmp_path / "ep", 3, complete=False)
    (ep / "actions.txt").unlink()
    assert not is_complete(ep) and not is_complete(str(tmp_path / "nowhere"))
    (ep / "metrics.json").write_text("{not json")
    assert not is_complete(ep)
    (ep / "metrics.json").write_text(json.dumps({"steps": 3}))
    assert is_complete(str(ep))
    text = (ep / "poses.txt").read_text()
    (ep / "poses.txt").write_text(text[:-10])  # the last line cut by a crash
    poses = read_poses(str(ep / "poses.txt"))
    assert len(poses) == 3 and all(np.array_equal(p, np.eye(4)) for p in poses)
    with pytest.raises(EpisodeError, match="no poses.txt"):
        read_poses(tmp_path / "poses.txt")


def test_a_recorded_map_is_told_apart_by_its_json_not_its_spacing(tmp_path):
    """episode.json is read as JSON: a compact or reformatted file of a recording's map is still a
    recording, and a file that is not a JSON object is named."""
    from activesplat.cli import recorded_map

    (tmp_path / "episode.json").write_text(json.dumps({"source": "recording"}, separators=(",", ":")))
    assert recorded_map(tmp_path) and recorded_map(tmp_path / "refined_3dgs")
    with pytest.raises(EpisodeError, match="map of a recording"):
        read_episode(tmp_path)
    (tmp_path / "episode.json").write_text("[1, 2]")
    assert not recorded_map(tmp_path)
    with pytest.raises(EpisodeError, match="not an episode"):
        read_episode(tmp_path)


def test_an_episode_records_the_code_that_wrote_it():
    """episode.json's `software`: the package version, and the git commit when run from a checkout."""
    import re

    import activesplat
    from activesplat.episode import software

    info = software()
    assert info["activesplat"] == activesplat.__version__
    assert info["commit"] is None or re.fullmatch(r"[0-9a-f]{40}", info["commit"])
    assert info["modified"] in (None, True, False)
