"""One typed configuration of an exploration run: `RunConfig`.

It nests the settings of every part of the loop, each kept in its own module as a frozen, validated
dataclass whose fields say where their values come from (paper / release / ours):

- ``sim``       `activesplat.sim.SimConfig`: sensor, agent body and action sizes
- ``mapper``    `activesplat.splat.config.MapperConfig`: the online Gaussian mapper
- ``explorer``  `activesplat.planning.explorer_config.ExplorerConfig` with its ``planning``, ``workspace`` and
                ``controller`` groups: viewpoint selection, workspace graph, path following
- ``frontier``  `activesplat.planning.frontier.FrontierConfig`: the `fbe` baseline
- ``coverage``  `activesplat.eval.coverage.CoverageConfig`: the completion metrics measured during the run
- ``refine``    `activesplat.refine.config.RefineConfig`: offline refinement of the episode's map

The geometry the robot defines is set once, in ``sim``: the planner's agent radius and height, its action
sizes and its panorama height are derived from it (`DERIVED`) and cannot be set elsewhere.

On the command line every field is an option ``--GROUP.FIELD VALUE`` (``activesplat explore --help``).
An episode folder's ``episode.json`` records the run's configuration under ``"config"`` with its
``"version"``; `load_run_config` reads it back, so ``activesplat explore --config EPISODE/episode.json``
reruns an episode exactly.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import numbers
import re
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import tyro

from activesplat.config_history import _ABSENT, CONFIG_VERSION, drop_removed, fill_added, pop_path
from activesplat.config_history import ADDED as ADDED  # re-exported: activesplat.config.ADDED / REMOVED
from activesplat.config_history import REMOVED as REMOVED
from activesplat.errors import InvalidInputError
from activesplat.eval.coverage import CoverageConfig
from activesplat.planning.explorer_config import ExplorerConfig
from activesplat.planning.frontier import FrontierConfig
from activesplat.planning.policies import POLICY_NAMES, check_policy
from activesplat.refine.config import METHODS, RefineConfig
from activesplat.sim.config import SimConfig
from activesplat.splat.config import MapperConfig
from activesplat.splat.rasterize import BACKENDS

DERIVED: dict[str, str] = {
    "explorer.workspace.agent_radius": "agent_radius",
    "explorer.workspace.agent_height": "agent_height",
    "explorer.controller.turn_deg": "turn_deg",
    "explorer.controller.look_deg": "look_deg",
    "explorer.controller.forward_m": "forward_step",
    "explorer.panorama_height_m": "sensor_height",
}
"""Fields derived from the robot's own settings: dotted path in RunConfig -> field of ``sim``."""

PolicyName = Literal[POLICY_NAMES]  # type: ignore[valid-type]
BackendName = Literal[BACKENDS]  # type: ignore[valid-type]
RefineMethod = Literal[METHODS]  # type: ignore[valid-type]


# nested settings groups, each with a short description for --help (the classes' docstrings are long)
SimGroup = Annotated[SimConfig, tyro.conf.arg(help=(
    "Simulated robot: sensor, agent body and action sizes (Habitat protocol). The explorer's agent "
    "radius and height, action sizes and panorama height are derived from these."))]
MapperGroup = Annotated[MapperConfig, tyro.conf.arg(help=(
    "Online Gaussian mapper (paper sec. III-A): losses, densification, pruning, schedule. "
    "splat/config.py explains each project default."))]
ExplorerGroup = Annotated[ExplorerConfig, tyro.conf.arg(help=(
    "Explorer (paper sec. III-B, III-C): bootstrap, viewpoint scores, hierarchical planning, paths."))]
FrontierGroup = Annotated[FrontierConfig, tyro.conf.arg(help=(
    "The fbe baseline: classic frontier-based exploration (Yamauchi 1997)."))]
CoverageGroup = Annotated[CoverageConfig, tyro.conf.arg(help=(
    "Completion metrics measured during the run (paper sec. IV-B)."))]
RefineGroup = Annotated[RefineConfig, tyro.conf.arg(help=(
    "Offline refinement of the episode's map (paper sec. III-D4), used by `activesplat refine`."))]

GROUPS = {"sim": SimConfig, "mapper": MapperConfig, "explorer": ExplorerConfig, "frontier": FrontierConfig,
          "coverage": CoverageConfig, "refine": RefineConfig}
"""RunConfig's settings groups and their classes."""


@dataclass(frozen=True)
class RunConfig:
    """Everything that decides what an exploration episode does: scene, policy, seed, budget and the
    settings of every part. Two runs with equal RunConfigs (and the same number of CPU threads) take the
    same actions."""

    scene: str = "small-0"
    """Built-in scene (small-<seed>: 2-4 rooms, medium-<seed>: 5-10 rooms) or a mesh file
    (.glb/.gltf/.ply/.obj)."""
    policy: PolicyName = "activesplat"
    """Exploration policy: the paper's method (activesplat), its ablations and the baselines, or one a package
    adds (docs/extending.md)."""
    seed: int = 0
    """Seed of the random start pose."""
    steps: int | None = None
    """Step budget in actions; None: 1000 for small scenes and mesh files, 2000 for medium ones."""
    z_up: bool = False
    """The scene mesh file is z-up (built-in scenes and glTF files are y-up)."""
    backend: BackendName = "auto"
    """Rasterizer backend (auto: gsplat with CUDA, else numba)."""
    floor: int | float | str | None = None
    """Storey of a multi-storey mesh: an index from the bottom (0, 1, ...) or a floor height in metres
    (3.0); None: the mesh's only storey (an error lists the storeys when there are several)."""

    sim: SimGroup = field(default_factory=SimConfig)
    mapper: MapperGroup = field(default_factory=MapperConfig)
    explorer: ExplorerGroup = field(default_factory=ExplorerConfig)
    frontier: FrontierGroup = field(default_factory=FrontierConfig)
    coverage: CoverageGroup = field(default_factory=CoverageConfig)
    refine: RefineGroup = field(default_factory=RefineConfig)

    def __post_init__(self) -> None:
        if self.policy not in POLICY_NAMES:  # a registered or installed one (docs/extending.md)
            check_policy(self.policy)
        if self.backend not in BACKENDS:
            raise InvalidInputError(f"RunConfig.backend must be one of {', '.join(BACKENDS)}, "
                                    f"got {self.backend!r}")
        if isinstance(self.floor, str):  # from a file or an untyped caller: "1" is an index, "3.0" a height
            text = self.floor.strip().removesuffix("m")
            try:
                floor = float(text) if "." in text or "e" in text.lower() else int(text)
            except ValueError:
                raise InvalidInputError(f"RunConfig.floor must be a storey index (1) or a floor height in "
                                        f"metres (3.0), got {self.floor!r}") from None
            object.__setattr__(self, "floor", floor)
        if isinstance(self.seed, bool) or not isinstance(self.seed, numbers.Integral) or self.seed < 0:
            raise InvalidInputError(f"RunConfig.seed must be an integer >= 0, got {self.seed!r}")
        object.__setattr__(self, "seed", int(self.seed))  # a numpy integer too, as an int (episode.json)
        if self.steps is not None:
            steps = self.steps
            if isinstance(steps, bool) or not isinstance(steps, numbers.Integral) or steps <= 0:
                raise InvalidInputError(f"RunConfig.steps must be a positive number of actions (an integer, "
                                        f"or None for the scene's default), got {self.steps!r}")
            object.__setattr__(self, "steps", int(self.steps))
        for name, group in GROUPS.items():
            value = getattr(self, name)
            if not isinstance(value, group):
                hint = f" (use {group.__name__}(**that_dict))" if isinstance(value, dict) else ""
                raise InvalidInputError(f"RunConfig.{name} must be a {group.__name__}, got "
                                        f"{type(value).__name__}{hint}")
        derived = self
        for path, sim_field in DERIVED.items():
            derived = _replace_path(derived, path.split("."), getattr(self.sim, sim_field))
        object.__setattr__(self, "explorer", derived.explorer)  # frozen: the derived group replaces the given

    def replace(self, **changes) -> RunConfig:
        """A copy with some fields changed (`dataclasses.replace`; derived fields follow ``sim``)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """JSON-ready: ``{"version": CONFIG_VERSION, field: value, group: {...}, ...}`` (derived fields
        included, as a record; `from_dict` checks them)."""
        return {"version": CONFIG_VERSION, **dataclasses.asdict(self)}

    @classmethod
    def from_dict(cls, data: dict, source: str = "config") -> RunConfig:
        """The configuration of a `to_dict` dictionary. Missing fields take their defaults; an unknown key,
        a value of the wrong type, a derived field that disagrees with ``sim`` or another version raises an
        InvalidInputError naming it (``source`` names the file in the message)."""
        if not isinstance(data, dict):
            raise InvalidInputError(f"{source}: expected a JSON object, got {type(data).__name__}")
        data = dict(data)
        version = data.pop("version", None)
        if version != CONFIG_VERSION:
            raise InvalidInputError(f"{source}: config version {version} (this activesplat reads version "
                                    f"{CONFIG_VERSION}); rerun with options instead")
        derived = {path: pop_path(data, path.split(".")) for path in DERIVED}
        drop_removed(data, source)
        config = _build(cls, data, "", source)
        for path, value in derived.items():
            want = _get_path(config, path.split("."))
            if value is not _ABSENT and value != want:
                raise InvalidInputError(f"{source}: {path} is derived from sim.{DERIVED[path]} ({want}); "
                                        f"the file says {value!r}")
        return config


@dataclass(frozen=True)
class ExploreCommand:
    """`activesplat explore`: explore a scene and write an episode folder."""

    config: Path | None = None
    """Rerun the configuration recorded in this episode.json (or episode folder): scene, policy, seed, steps
    and every field; the other options given override it."""
    out: Path | None = None
    """Episode folder (default: runs/SCENE-POLICY-sSEED)."""
    overwrite: bool = False
    """Replace an episode (complete or partial) in --out, with everything made from it (render-eval and
    refine results)."""
    progress: bool = True
    """Show a progress bar."""
    viewer: bool = False
    """Serve a live viser web viewer of the run on localhost."""
    viewer_port: int = 8080
    """Port of --viewer."""
    max_splats: int = 400_000
    """With --viewer, the most Gaussians sent to the browser: a larger map is cut to its most opaque ones,
    and the page and the terminal say so (as `activesplat view --max-splats`). The run itself is the same."""
    run: Annotated[RunConfig, tyro.conf.arg(name="")] = field(default_factory=RunConfig)
    """The run's configuration: its fields are options of their own."""

    def __post_init__(self) -> None:
        if isinstance(self.max_splats, bool) or not isinstance(self.max_splats, int) or self.max_splats < 1:
            raise InvalidInputError(f"--max-splats must be a positive number of Gaussians, got "
                                    f"{self.max_splats!r}")


@dataclass(frozen=True)
class BenchmarkCommand:
    """`activesplat benchmark`: scenes x policies x trials -> CSV and paper-style tables. The --GROUP.FIELD
    options apply to every run."""

    scenes: tuple[str, ...] = ("small-0", "small-1", "small-2", "small-3")
    """Scene names or mesh files."""
    policies: tuple[str, ...] = ("activesplat", "fbe", "random")
    """Policies."""
    trials: int = 1
    """Trials (seeds 0..trials-1) per scene."""
    steps: int | None = None
    """Step budget (default: per scene size)."""
    root: Path = Path("runs/benchmark")
    """Folder of the episodes and tables."""
    workers: int = 1
    """Parallel processes (local executor)."""
    executor: Literal["local", "ray"] = "local"
    """Local process pool or a Ray cluster (pip install activesplat[ray])."""
    ray_address: str | None = None
    """Ray cluster address (default: auto / local)."""
    ceiling: bool = True
    """Measure each scene's exhaustive-sweep ceiling (cached in ROOT/<scene>/sweep.json; minutes per house)
    for the multi-room table: share of the ceiling, worst room, steps to 90 / 95 % of it."""
    run: Annotated[RunConfig, tyro.conf.arg(name="")] = field(default_factory=RunConfig)
    """Settings of every run (scene, policy, seed and steps come from the options above)."""


BENCHMARK_OWN = ("scene", "policy", "seed", "steps")
"""RunConfig fields a benchmark sets per run, not from --GROUP.FIELD options."""


@dataclass(frozen=True)
class RefineCommand:
    """`activesplat refine`: offline refinement of an episode's map from its keyframes. The settings are the
    episode's recorded ``refine`` group (defaults for an episode that records none), then the options."""

    dir: Annotated[tyro.conf.Positional[Path], tyro.conf.arg(metavar="DIR")]
    """Episode folder."""
    method: RefineMethod = "3dgs"
    """3dgs: 3D Gaussians with 3DGS adaptive density control; 2dgs: 2D Gaussian surfels with the 2DGS
    regularisers."""
    iters: int = 2000
    """Optimisation iterations (ours: a CPU budget; 3DGS and 2DGS train 30,000)."""
    seed: int = 0
    """Seed of the view sampling."""
    restart: bool = False
    """Ignore a checkpoint in DIR/refined_METHOD and start again."""
    backend: BackendName = "auto"
    """Rasterizer backend (auto: gsplat with CUDA, else numba)."""
    image_size: int | None = None
    """Refine and evaluate at this square size in pixels, the keyframes rendered again by the simulator
    from their poses (simulated episodes; the paper refines at 512). None: the keyframes as recorded."""
    progress: bool = True
    """Show a progress bar."""
    lpips: bool = True
    """Measure LPIPS in the evaluation after training (--no-lpips: leave it out, for a machine without its
    AlexNet weights; checked before training starts)."""
    refine: RefineGroup = field(default_factory=RefineConfig)


def recorded_refine_config(episode_dir: str | Path) -> RefineConfig | None:
    """The ``refine`` settings an episode's episode.json records, None when it records none (an episode of
    a version before RunConfig, or no episode.json). Only the ``refine`` group is read, so a field of
    another group that this version removed does not keep the recorded settings from counting; a
    ``refine`` field added since the episode was recorded reads as its version ran (`ADDED`, with a
    warning naming it); a ``refine`` group this version cannot read is an InvalidInputError naming the
    field."""
    from activesplat.episode import read_meta
    from activesplat.errors import EpisodeError

    try:
        config = read_meta(episode_dir).get("config")
    except EpisodeError:
        return None  # the refine command names a missing or unreadable episode itself
    if not isinstance(config, dict) or "refine" not in config:
        return None
    path = Path(episode_dir) / "episode.json"
    refine = config["refine"]
    if isinstance(refine, dict):  # fields added since read as its version ran, as in load_run_config
        refine = fill_added({"refine": refine}, path, only="refine.")["refine"]
    return _build(RefineConfig, refine, "refine.", str(path))


def load_run_config(path: str | Path) -> RunConfig:
    """The RunConfig recorded in an episode folder, its episode.json, or a JSON file of
    `RunConfig.to_dict`."""
    p = Path(path)
    if p.is_dir():
        p = p / "episode.json"
    if not p.is_file():
        raise InvalidInputError(f"--config: no such file: {p}")
    try:
        data = json.loads(p.read_text())
    except (OSError, ValueError) as exc:
        raise InvalidInputError(f"--config: {p} is not readable JSON: {exc}") from None
    if isinstance(data, dict) and "start_pose" in data:  # an episode.json: the config is one of its keys
        if not isinstance(data.get("config"), dict):
            raise InvalidInputError(f"--config: {p} records no configuration (an episode of a version "
                                    f"before RunConfig); rerun it with options instead")
        data = fill_added(data["config"], p)
    return RunConfig.from_dict(data, source=str(p))


def option_paths(cls=RunConfig, prefix: str = "") -> dict[str, type]:
    """Every settable field as a dotted path (``mapper.lr.means``) -> the dataclass that holds it; derived
    fields are left out."""
    out: dict[str, type] = {}
    for f in dataclasses.fields(cls):
        path = prefix + f.name
        tp = strip_annotated(typing.get_type_hints(cls)[f.name])
        if dataclasses.is_dataclass(tp):
            out.update(option_paths(tp, path + "."))
        elif path not in DERIVED:
            out[path] = cls
    return out


def name_fields(message: str, flags: bool = False) -> str:
    """A validation message with each ``ClassName.field`` written as its place in RunConfig
    (``mapper.pixel_stride``, or the option ``--mapper.pixel-stride`` with ``flags``)."""
    def place(match: re.Match) -> str:
        prefix = _class_prefixes().get(match.group(1))
        if prefix is None:
            return match.group(0)
        path = prefix + match.group(2)
        return "--" + path.replace("_", "-") if flags else path

    return re.sub(r"\b([A-Z][A-Za-z]*Config)\.([a-z_][a-z0-9_]*)", place, message)


@functools.cache
def _class_prefixes() -> dict[str, str]:
    """Class name -> its dotted prefix in RunConfig, for the classes that occur once."""
    seen: dict[str, list[str]] = {}
    for path, cls in option_paths().items():
        prefix = path.rsplit(".", 1)[0] + "." if "." in path else ""
        seen.setdefault(cls.__name__, [])
        if prefix not in seen[cls.__name__]:
            seen[cls.__name__].append(prefix)
    return {name: prefixes[0] for name, prefixes in seen.items() if len(prefixes) == 1}


# --------------------------------------------------------------------------- helpers


def _replace_path(obj, path: list[str], value):
    if len(path) == 1:
        if getattr(obj, path[0]) == value:
            return obj
        return dataclasses.replace(obj, **{path[0]: value})
    inner = getattr(obj, path[0])
    new = _replace_path(inner, path[1:], value)
    return obj if new is inner else dataclasses.replace(obj, **{path[0]: new})


def _get_path(obj, path: list[str]):
    for name in path:
        obj = getattr(obj, name)
    return obj


def strip_annotated(tp):
    while typing.get_origin(tp) is Annotated:
        tp = typing.get_args(tp)[0]
    return tp


def _build(cls, data: dict, prefix: str, source: str):
    """cls(**data) checked field by field, recursing into nested dataclasses."""
    if not isinstance(data, dict):
        raise InvalidInputError(f"{source}: {prefix.rstrip('.') or 'config'} must be an object, got {data!r}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls) if f.init}
    unknown = [k for k in data if k not in names]
    if unknown:
        raise InvalidInputError(f"{source}: unknown key {prefix + unknown[0]}")
    kwargs = {}
    for name, value in data.items():
        tp = strip_annotated(hints[name])
        if dataclasses.is_dataclass(tp):
            kwargs[name] = _build(tp, value, prefix + name + ".", source)
        else:
            kwargs[name] = _value(value, tp, prefix + name, source)
    try:
        return cls(**kwargs)
    except InvalidInputError as exc:
        raise InvalidInputError(f"{source}: {name_fields(str(exc))}") from None


def _value(value: Any, tp, path: str, source: str):
    """A JSON value as the field's type (lists back to tuples), or an error naming the field."""
    ok, out = _convert(value, tp)
    if not ok:
        raise InvalidInputError(f"{source}: {path} must be {_type_name(tp)}, got {value!r}")
    return out


def _convert(value: Any, tp) -> tuple[bool, Any]:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is Any:
        return True, value
    if tp is type(None):
        return value is None, None
    if origin in (typing.Union, types.UnionType):
        for arg in args:
            ok, out = _convert(value, arg)
            if ok:
                return True, out
        return False, None
    if origin is Literal:
        return value in args, value
    if tp is bool:
        return isinstance(value, bool), value
    if tp is int:
        return isinstance(value, int) and not isinstance(value, bool), value
    if tp is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool), float(value) if isinstance(
            value, (int, float)) else None
    if tp is str:
        return isinstance(value, str), value
    if origin is tuple and isinstance(value, (list, tuple)):
        if len(args) == 2 and args[1] is Ellipsis:
            items = [_convert(v, args[0]) for v in value]
        elif len(args) == len(value):
            items = [_convert(v, a) for v, a in zip(value, args, strict=True)]
        else:
            return False, None
        return all(ok for ok, _ in items), tuple(v for _, v in items)
    return False, None


def _type_name(tp) -> str:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_name(a) for a in args)
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in args)
    if origin is tuple:
        return "a list"
    return {bool: "true or false", int: "an integer", float: "a number", str: "a string",
            type(None): "null"}.get(tp, getattr(tp, "__name__", str(tp)))
