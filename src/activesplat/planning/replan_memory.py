"""What the goal selection remembers from one replan to the next (ours; both off by default): the
promises of nodes outside the agent's subregion (`Promises`, `ExplorerConfig.keep_promise_m`) and the
goal of the last global choice (`Commitment`, `ExplorerConfig.commit_global_m`) and the order of the last
global route (`RouteMemory`, `ExplorerConfig.route_memory_m`). The paper's planner
ranks every replan from its own panoramas alone; `planning.goals.rank_goals` applies these on top."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Promises:
    """What the nodes outside the agent's subregion once promised to show (ours,
    `ExplorerConfig.keep_promise_m`):
    the information part of every node scored by panorama, kept across replans by floor position. A room
    looked into from its door, or passed along a corridor, looks half seen from there: its nodes' promise
    drops although most of the room was never seen from close by, and the agent walked past such rooms and
    never came back. With this memory a node promises at least what it promised before, until the agent
    has replanned inside the node's subregion or visited it (then the memory of it is dropped and the
    panoramas rule again)."""

    radius: float
    """A remembered promise belongs to the current nodes within this of its position (the Voronoi graph
    moves a little between replans)."""
    pos: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    value: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def keep(self, pos: np.ndarray, info: np.ndarray, scored: np.ndarray, release: np.ndarray) -> np.ndarray:
        """The nodes' information parts with the memory applied: max(info, the promise remembered within
        `radius`) for the nodes not `release`d (those in the agent's subregion or visited: their memory is
        dropped). The memory then holds every scored node's (not released) value."""
        pos, info = np.asarray(pos, float).reshape(-1, 2), np.asarray(info, float)
        scored, release = np.asarray(scored, bool), np.asarray(release, bool)
        near = np.hypot(*(pos[:, None, :] - self.pos[None, :, :]).transpose(2, 0, 1)) <= self.radius
        kept = np.where(near, self.value[None, :], 0.0).max(axis=1, initial=0.0)
        out = np.where(release, info, np.maximum(info, kept))
        stale = (near & (release | scored)[:, None]).any(axis=0)  # dropped or replaced by a fresh value
        new = scored & ~release
        self.pos = np.concatenate([self.pos[~stale], pos[new]])
        self.value = np.concatenate([self.value[~stale], out[new]])
        return out


@dataclass
class Commitment:
    """The global goal the agent set out for, kept until it is reached or no longer worth a visit (ours,
    `ExplorerConfig.commit_global_m`). Every global-stage replan ranks the nodes anew on a map that grew
    since the last one; a long trip has stops on the way (`closer_on_the_way`, the detour rule), and at
    each the best node could change sides of the house, so the agent crossed it again and again. With a
    commitment a global replan goes on toward the subregion it chose before while a node of it still
    promises something to see."""

    radius: float
    """The committed subregion is that of the candidate nearest the remembered goal, if one lies within
    this (the Voronoi graph and its subregions are rebuilt at every replan)."""
    pos: np.ndarray | None = None
    """The goal of the last global choice (floor x, z); None: no commitment."""

    def first(self, order: list[int], worth: np.ndarray, nodes: Sequence[int], pos: np.ndarray,
              subregions: dict[int, int]) -> tuple[list[int], bool]:
        """`order` (indices into `nodes`) with the committed subregion's best node worth a visit moved to
        the front, and whether the commitment held; when it did not (no candidate near the remembered goal,
        or none of its subregion worth a visit) the order is unchanged and the commitment dropped."""
        if self.pos is None or len(nodes) == 0:
            return order, False
        d = np.hypot(*(np.asarray(pos, float).reshape(-1, 2) - self.pos).T)
        nearest = int(np.argmin(d))
        region = subregions.get(nodes[nearest])
        if d[nearest] <= self.radius:
            keep = [i for i in order if worth[i] and (subregions.get(nodes[i]) == region if region is not None
                                                       else i == nearest)]
            if keep:
                return [keep[0]] + [i for i in order if i != keep[0]], True
        self.pos = None
        return order, False


@dataclass
class RouteMemory:
    """The order of the last global route through the subregions, kept across replans (ours,
    `ExplorerConfig.route_memory_m`). `hierarchical.tour_first` re-plans the shortest route at every global
    replan; the map grows in between, and the route's first stop could jump to the other side of the house
    and back (fresh medium-103: six crossings of 8-13 m). With this memory the stops of the last route that
    are still there (a subregion's representative within `radius` of a remembered stop) keep their order,
    new ones are inserted where they lengthen the route least, and finished ones drop out."""

    radius: float
    """A remembered stop stands for the current representative within this (metres)."""
    min_info: float = 0.0
    """Only subregions whose best node promises more than this (information part of eq. 12) are stops of
    the route; the others follow in the global stage's own order (0: every subregion worth a visit)."""
    stops: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """Floor (x, z) of the last route's stops, in route order."""

    def follow(self, pos: np.ndarray, start: np.ndarray, pairwise: np.ndarray) -> list[int] | None:
        """The order of the current stops (`pos` (K, 2), `start[i]`: travel from the agent, `pairwise`:
        between stops) that keeps the remembered order of those matched to it, with the others inserted by
        cheapest insertion; None when no remembered stop matches (then a new route is planned)."""
        pos = np.asarray(pos, float).reshape(-1, 2)
        kept: list[int] = []
        for stop in self.stops:
            d = np.hypot(*(pos - stop).T)
            d[kept] = np.inf
            if len(d) and d.min() <= self.radius:
                kept.append(int(np.argmin(d)))
        if not kept:
            return None

        def leg(a: int | None, b: int | None) -> float:
            """Travel from stop a (None: the agent) to stop b (None: the open route's end, free)."""
            return 0.0 if b is None else float(start[b] if a is None else pairwise[a, b])

        for new in sorted(set(range(len(pos))) - set(kept), key=lambda i: (start[i], i)):
            # the extra length of putting `new` between each pair of neighbours on the route
            pairs = zip([None, *kept], [*kept, None], strict=True)
            costs = [leg(a, new) + leg(new, b) - leg(a, b) for a, b in pairs]
            kept.insert(int(np.argmin(costs)), new)
        return kept


__all__ = ["Commitment", "Promises", "RouteMemory"]
