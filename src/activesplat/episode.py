"""The episode folder (README, "The episode folder"): what an exploration leaves behind, written so
that a crash or Ctrl-C leaves a consistent, evaluable partial episode.

- ``episode.json``  scene, seed, policy, start pose, configuration (written first, atomically)
- ``actions.txt``   one action name per line, appended and flushed as actions happen
- ``poses.txt``     one line per observation including the reset: step index then the 16 numbers of the
                    4x4 camera-to-world matrix, row-major (OpenCV axes, world frame of the scene)
- ``metrics.json``  written only when the run completes; its presence marks a complete episode
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from activesplat.errors import EpisodeError, check_output_folder

EPISODE_FILES = ("episode.json", "actions.txt", "poses.txt", "metrics.json", "gaussians.ply", "topdown.png",
                 "completion.png", "keyframes.npz", "mapper.json", "stops.json", "trajectory.png",
                 "coverage.npz", "render_metrics.json", "render_grid.png", "render_budget.json",
                 "render_budget.png")
"""What an exploration and the commands run on its folder afterwards (``render-eval``, ``refine``: the
``refined_*`` folders, :data:`DERIVED_DIRS`) write there: replacing an episode removes them all, so that
nothing of the previous run is left beside the new one."""
DERIVED_DIRS = "refined_*"


def software() -> dict:
    """Which code wrote an episode, for episode.json: the package version and, when the package runs from a
    git checkout (an editable install), the commit and whether files differ from it (``None`` otherwise)."""
    import subprocess
    from importlib.resources import files

    from activesplat import __version__

    here = Path(str(files("activesplat")))
    out: dict = {"activesplat": __version__, "commit": None, "modified": None}
    try:
        def git(*args):
            return subprocess.run(["git", "-C", str(here), *args], capture_output=True, text=True, timeout=5)

        head = git("rev-parse", "HEAD")
        if head.returncode == 0:
            status = git("status", "--porcelain", "--untracked-files=no", "--", ".")
            out["commit"] = head.stdout.strip()
            out["modified"] = bool(status.stdout.strip()) if status.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):  # no git, or it hangs: the version alone
        pass
    return out


def write_json_atomic(path: Path, data: dict) -> None:
    """Write JSON through a temporary file and a rename, so readers never see half a file (and an error or a
    Ctrl-C leaves no temporary file)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    try:
        tmp.write_text(json.dumps(data, indent=2))
        os.replace(tmp, path)
    except BaseException:
        remove_quietly(tmp)
        raise


def remove_quietly(path: Path) -> None:
    """Remove the temporary file `path` of a write that failed or was interrupted, if it was made."""
    try:
        path.unlink(missing_ok=True)
    except OSError:  # never made (its folder is missing or not a folder)
        pass


def write_npz(path: Path, compresslevel: int = 1, **arrays: np.ndarray) -> None:
    """``np.savez_compressed`` at deflate level ``compresslevel`` (zlib's default is 6), through a
    temporary file and a rename. Level 1: the 834 keyframes of a 2000-step medium-house run (97 MB) write
    in 6.5 s instead of 18.3 s on 2 cores, for a 14 % larger file; ``np.load`` reads it as before."""
    import zipfile

    path = Path(path)
    tmp = path.with_suffix(path.suffix + ".tmp")
    try:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED,
                             compresslevel=compresslevel) as archive:
            for name, value in arrays.items():
                with archive.open(f"{name}.npy", "w", force_zip64=True) as f:
                    np.lib.format.write_array(f, np.asanyarray(value), allow_pickle=False)
        os.replace(tmp, path)
    except BaseException:
        remove_quietly(tmp)
        raise


def is_complete(folder: str | Path) -> bool:
    """Whether an episode or map folder holds a complete run: its metrics.json, written when the run ends, is
    readable and not marked ``"complete": false`` (what `evaluate` writes for a partial episode). False for
    an interrupted run, and for a folder without metrics.json."""
    metrics = Path(folder) / "metrics.json"
    if not metrics.exists():
        return False
    try:
        return json.loads(metrics.read_text()).get("complete", True) is not False
    except (ValueError, AttributeError):
        return False


def _held_episode(d: Path) -> str:
    """What episode ``d`` holds, in words ("a complete episode", "a partial episode (N actions)"), or ""
    when it holds none."""
    if is_complete(d):
        return "a complete episode"
    actions = d / "actions.txt"
    if actions.exists() or (d / "metrics.json").exists():
        n = sum(1 for line in actions.read_text().splitlines() if line.strip()) if actions.exists() else 0
        return f"a partial episode ({n} actions)"
    return ""


def _pose_line(step: int, pose: np.ndarray) -> str:
    return f"{step} " + " ".join(f"{v:.9g}" for v in np.asarray(pose, dtype=np.float64).reshape(16)) + "\n"


def check_episode_folder(out_dir: str | Path, overwrite: bool = False) -> None:
    """What `EpisodeWriter` checks before it touches `out_dir`, for a command to call before its slow work
    (a scene build, a connection to a robot): `out_dir` can be written into (`check_output_folder`), and holds
    no episode (complete or partial) unless `overwrite`. InvalidInputError / EpisodeError, in one line."""
    d = Path(out_dir)
    check_output_folder(d)
    if not overwrite:
        held = _held_episode(d)
        if held:
            raise EpisodeError(f"{d} already holds {held}; pass --overwrite to replace it")


class EpisodeWriter:
    """Appends actions and poses as they happen; `finish(metrics)` marks the episode complete."""

    def __init__(self, out_dir: str | Path, overwrite: bool = False):
        self.dir = Path(out_dir)
        check_episode_folder(self.dir, overwrite)
        self.dir.mkdir(parents=True, exist_ok=True)
        for name in EPISODE_FILES:
            (self.dir / name).unlink(missing_ok=True)
        for derived in self.dir.glob(DERIVED_DIRS):
            if derived.is_dir():
                shutil.rmtree(derived)
        self._actions = None
        self._poses = None

    def start(self, meta: dict, pose: np.ndarray) -> None:
        """Write episode.json and the reset pose (step 0)."""
        write_json_atomic(self.dir / "episode.json", meta)
        self._actions = open(self.dir / "actions.txt", "w", encoding="utf-8")  # noqa: SIM115
        self._poses = open(self.dir / "poses.txt", "w", encoding="utf-8")  # noqa: SIM115
        self._poses.write(_pose_line(0, pose))
        self._poses.flush()

    def record(self, step: int, action: str, pose: np.ndarray) -> None:
        """One action and the pose it led to (step = number of actions so far)."""
        self._actions.write(action + "\n")
        self._poses.write(_pose_line(step, pose))
        self._actions.flush()
        self._poses.flush()

    def close(self) -> None:
        for f in (self._actions, self._poses):
            if f is not None and not f.closed:
                f.close()

    def finish(self, metrics: dict) -> None:
        self.close()
        write_json_atomic(self.dir / "metrics.json", metrics)


@dataclass
class Episode:
    """An episode folder read back: the consistent prefix of what was recorded."""

    dir: Path
    meta: dict
    actions: list[str]
    poses: np.ndarray
    """(len(actions) + 1, 4, 4) camera-to-world poses, the reset first."""
    complete: bool

    @property
    def start_pose(self) -> np.ndarray:
        return np.asarray(self.meta["start_pose"], dtype=np.float64)


def read_meta(folder: str | Path) -> dict:
    """``folder/episode.json`` as a dict; an EpisodeError naming the file when it is missing, unreadable
    or not a JSON object."""
    path = Path(folder) / "episode.json"
    try:
        meta = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise EpisodeError(f"{path} is unreadable: {exc}") from None
    if not isinstance(meta, dict):
        raise EpisodeError(f"{path} is not an episode description")
    return meta


def is_recorded_map(meta: dict) -> bool:
    """Whether an episode.json describes a map of a recording (``activesplat map``), not an exploration."""
    return meta.get("source") == "recording"


ENVIRONMENT_SOURCE = "environment"
"""episode.json's ``source`` of an exploration in an environment without ground truth (a robot, a user's
own ``Environment``)."""


def has_no_ground_truth(meta: dict) -> bool:
    """Whether an episode.json describes an exploration without ground truth (`ENVIRONMENT_SOURCE`)."""
    return meta.get("source") == ENVIRONMENT_SOURCE


def episode_and_map(path: str | Path) -> tuple[Path, Path | None]:
    """(episode folder, map folder inside it or None) of a command's DIR: an episode folder (a map of a
    recording too), or a map folder inside one (``DIR/refined_<method>/`` with its gaussians.ply).
    EpisodeError otherwise."""
    d = Path(path)
    if not d.is_dir():
        raise EpisodeError(f"{d} is not a folder")
    if (d / "episode.json").is_file():
        return d, None
    if (d / "gaussians.ply").is_file() and (d.parent / "episode.json").is_file():
        return d.parent, d
    raise EpisodeError(f"{d} is not an episode folder (no episode.json), nor a map folder inside one "
                       f"(DIR/refined_<method>/ with its gaussians.ply)")


def read_episode(path: str | Path) -> Episode:
    """Read an episode folder; a partial (interrupted) one is cut to its last complete step."""
    d = Path(path)
    if not d.is_dir():
        raise EpisodeError(f"{d} is not a folder")
    meta_path = d / "episode.json"
    if not meta_path.exists() or not (d / "actions.txt").exists():
        if meta_path.exists() and is_recorded_map(read_meta(d)):
            raise EpisodeError(f"{d} is a map of a recording (activesplat map), not a simulated episode: "
                               f"this needs the simulator's ground truth and actions to replay (`activesplat "
                               f"explore` folder). A recorded map takes render-eval (its held-out views), "
                               f"refine, export and view without the options that need a simulator")
        raise EpisodeError(f"{d} is not an episode folder (no episode.json / actions.txt)")
    meta = read_meta(d)
    try:
        np.asarray(meta["start_pose"], dtype=np.float64).reshape(4, 4)  # a 4x4 pose, or unreadable
    except (ValueError, KeyError, TypeError) as exc:
        raise EpisodeError(f"{meta_path} is unreadable: {exc}") from exc
    text = (d / "actions.txt").read_text()
    lines = text.split("\n")
    actions = [a.strip() for a in (lines if text.endswith("\n") else lines[:-1]) if a.strip()]
    poses = read_poses(d / "poses.txt")
    complete = is_complete(d)
    # poses.txt holds the reset and one pose per action; an interrupted run may lack the last action's pose
    short = len(actions) + 1 - len(poses)
    if short < 0 or short > (0 if complete else 1):
        expected = f"{len(actions) + 1}: the reset and one per action" + ("" if complete else ", or 1 fewer")
        raise EpisodeError(f"{d}: poses.txt has {len(poses)} readable poses for {len(actions)} actions "
                           f"(expected {expected})")
    n = min(len(actions), len(poses) - 1)
    return Episode(d, meta, actions[:n], np.stack(poses[: n + 1]), complete)


def read_poses(path: str | Path) -> list[np.ndarray]:
    """The 4x4 camera-to-world poses of a ``poses.txt`` (an episode's, or a map of a recording's), one per
    line, in order (the step index that starts each line is not checked). A crash can cut only the last
    line, which is dropped; a line that cannot be read anywhere else is corruption, and an EpisodeError
    names it, as it does a missing file or one without a pose."""
    path = Path(path)
    if not path.exists():
        raise EpisodeError(f"{path.parent} has no poses.txt (one line per observation, README \"The episode "
                           f"folder\"): the episode cannot be replayed or checked without it")
    lines = path.read_text().splitlines()
    poses = []
    for i, line in enumerate(lines):
        parts = line.split()
        try:
            if len(parts) != 17:
                raise ValueError(f"{len(parts)} numbers instead of 17")
            poses.append(np.array([float(v) for v in parts[1:]]).reshape(4, 4))
        except ValueError as exc:
            if i == len(lines) - 1 and i > 0:
                break  # the last line, cut by a crash
            raise EpisodeError(f"{path}, line {i + 1}: not a pose line (step index and 16 numbers): "
                               f"{exc}") from None
    if not poses:
        raise EpisodeError(f"{path} holds no pose (the first line is the reset pose)")
    return poses
