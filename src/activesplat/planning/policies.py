"""The exploration policies of `activesplat explore --policy` (paper Tab. I and the ablations of Tab.
III / IV): each a small configuration of one explorer class, or its own class (FBE).

Policies from outside the package (docs/extending.md) come in two ways, both by name wherever a policy is
named (`--policy`, `--policies`, `RunConfig.policy`, `run_exploration`, `run_benchmark`):

- `register_policy(name, factory)` in the running process (a script, a notebook);
- an entry point of the group ``activesplat.policies`` in an installed package (``name = "module:factory"``),
  which the command line sees too; it is imported only when a run uses it.

A factory is called as ``factory(world, floor_height, cfg, timers)``, the arguments of `Explorer`'s own
constructor (so an `Explorer` subclass is its own factory), and returns an `Explorer`.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from collections.abc import Callable

from activesplat.errors import InvalidInputError
from activesplat.planning.activesplat import ActiveSplatExplorer
from activesplat.planning.explorer import Explorer, WorldModel
from activesplat.planning.explorer_config import ExplorerConfig
from activesplat.planning.frontier import FrontierConfig, FrontierExplorer
from activesplat.timing import Timers


def _with_scores(cfg: ExplorerConfig, **weights) -> ExplorerConfig:
    score = dataclasses.replace(cfg.planning.score, **weights)
    return dataclasses.replace(cfg, planning=dataclasses.replace(cfg.planning, score=score))


_VARIANTS: dict[str, tuple[str, Callable[[ExplorerConfig], ExplorerConfig]]] = {
    "activesplat": ("full method: viewpoints, rotations, multi-connected stops, hierarchical planning",
                    lambda c: c),
    "no-hp": ("without hierarchical planning (greedy global goals)",
              lambda c: dataclasses.replace(c, hierarchical=False)),
    "viewpoint": ("decoupled positions and rotations, no multi-connected stops, no hierarchy",
                  lambda c: dataclasses.replace(c, hierarchical=False, multi_stops=False)),
    "position": ("node selection only, no target rotations",
                 lambda c: dataclasses.replace(c, hierarchical=False, multi_stops=False, rotations=False)),
    "random": ("random node choice on the Voronoi graph",
               lambda c: dataclasses.replace(c, hierarchical=False, multi_stops=False, rotations=False,
                                             random_goals=True)),
    "visibility-only": ("full method scoring nodes by 2D invisibility only (w_c = 0)",
                        lambda c: _with_scores(c, w_c=0.0)),
    "hull-only": ("full method scoring nodes by 3D hull volume only (w_o = 0)",
                  lambda c: _with_scores(c, w_o=0.0)),
    "fbe": ("classic frontier-based exploration (Yamauchi 1997), nearest frontier first",
            lambda c: dataclasses.replace(c, hierarchical=False, multi_stops=False, rotations=False)),
}

POLICY_NAMES = tuple(_VARIANTS)
"""The built-in policies (`policy_names` adds the registered ones)."""

ENTRY_POINT_GROUP = "activesplat.policies"
"""Entry-point group of the policies that installed packages add."""

PolicyFactory = Callable[[WorldModel, float, ExplorerConfig, Timers], Explorer]
"""``factory(world, floor_height, cfg, timers) -> Explorer``: one new explorer per episode."""

_REGISTERED: dict[str, tuple[str, PolicyFactory]] = {}
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]*")  # a folder name: runs/SCENE-POLICY-sSEED, ROOT/.../POLICY


def register_policy(name: str, factory: PolicyFactory, description: str = "") -> None:
    """Make `factory` the policy `name` in this process (registering a name again replaces its factory).
    `description`: a line for listings (default: the first line of the factory's docstring)."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise InvalidInputError(f"policy name {name!r}: use letters, digits and - _ . + (it names folders)")
    if name in _VARIANTS:
        raise InvalidInputError(f"policy {name!r} is built in; register yours under another name")
    if not callable(factory):
        raise InvalidInputError(f"policy {name!r}: the factory must be callable (an Explorer subclass, or a "
                                f"function of (world, floor_height, cfg, timers)), got {factory!r}")
    doc = (getattr(factory, "__doc__", None) or "").strip().splitlines()
    _REGISTERED[name] = (description or (doc[0] if doc else ""), factory)


@functools.cache
def _entry_points() -> dict:
    """{name: EntryPoint} of the installed packages' policies (read once per process; not imported)."""
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name not in _VARIANTS}


def policy_names() -> tuple[str, ...]:
    """Every policy a run may name: the built-in ones, then the registered and the installed ones."""
    return (*POLICY_NAMES, *_REGISTERED, *(n for n in _entry_points() if n not in _REGISTERED))


def check_policy(name: str) -> None:
    """Raise InvalidInputError when no policy is called `name`."""
    if name not in _VARIANTS and name not in _REGISTERED and name not in _entry_points():
        raise InvalidInputError(f"unknown policy {name!r}; choose one of: {', '.join(policy_names())}")


def describe_policies() -> str:
    lines = [(name, desc) for name, (desc, _) in {**_VARIANTS, **_REGISTERED}.items()]
    lines += [(name, f"from {ep.value}") for name, ep in _entry_points().items() if name not in _REGISTERED]
    return "\n".join(f"{name:16s} {desc}" for name, desc in lines)


def _factory(name: str) -> PolicyFactory:
    if name in _REGISTERED:
        return _REGISTERED[name][1]
    ep = _entry_points()[name]
    try:
        return ep.load()
    except Exception as exc:  # the plugin's own import failed: name it in one line
        raise InvalidInputError(f"policy {name!r} (entry point {ep.value}) cannot be loaded: "
                                f"{type(exc).__name__}: {exc}") from exc


def make_policy(name: str, world: WorldModel, floor_height: float, cfg: ExplorerConfig | None = None,
                timers: Timers | None = None, frontier: FrontierConfig | None = None) -> Explorer:
    """Build the named policy for one episode (`frontier`: the settings of the `fbe` baseline)."""
    check_policy(name)
    if name not in _VARIANTS:
        explorer = _factory(name)(world, floor_height, cfg or ExplorerConfig(), timers or Timers())
        if not isinstance(explorer, Explorer):
            raise InvalidInputError(f"policy {name!r}: its factory returned {type(explorer).__name__}, not "
                                    f"an activesplat.planning.explorer.Explorer")
        explorer.name = name
        return explorer
    cfg = _VARIANTS[name][1](cfg or ExplorerConfig())
    if name == "fbe":
        explorer = FrontierExplorer(world, floor_height, cfg, timers, frontier=frontier)
    else:
        explorer = ActiveSplatExplorer(world, floor_height, cfg, timers)
    explorer.name = name
    return explorer
