"""The exploration policies of `activesplat explore --policy` (paper Tab. I and the ablations of Tab.
III / IV): each a small configuration of one explorer class, or its own class (FBE)."""

from __future__ import annotations

import dataclasses
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


def describe_policies() -> str:
    return "\n".join(f"{name:16s} {desc}" for name, (desc, _) in _VARIANTS.items())


def make_policy(name: str, world: WorldModel, floor_height: float, cfg: ExplorerConfig | None = None,
                timers: Timers | None = None, frontier: FrontierConfig | None = None) -> Explorer:
    """Build the named policy for one episode (`frontier`: the settings of the `fbe` baseline)."""
    if name not in _VARIANTS:
        raise InvalidInputError(f"unknown policy {name!r}; choose one of: {', '.join(POLICY_NAMES)}")
    cfg = _VARIANTS[name][1](cfg or ExplorerConfig())
    if name == "fbe":
        explorer = FrontierExplorer(world, floor_height, cfg, timers, frontier=frontier)
    else:
        explorer = ActiveSplatExplorer(world, floor_height, cfg, timers)
    explorer.name = name
    return explorer
