"""Travel on the graph's stops (`planning.travel`): the shortest open route through a set of stops, exact
for a few and by local search beyond."""

import itertools

import numpy as np

from activesplat.planning.travel import shortest_tour


def _line(x: np.ndarray, agent: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, float)
    return np.abs(x - agent), np.abs(x[:, None] - x[None])


def test_the_shortest_tour_finishes_one_side_before_crossing_to_the_other():
    # stops on a line, the agent at 0: nearest-first goes 1, 2, 3, 4 and then back to -3 (4 + 7 = 11 m);
    # the route that takes -3 first walks 3 + 7 = 10 m
    start, pairwise = _line([-3.0, 1.0, 2.0, 3.0, 4.0])
    assert shortest_tour(start, pairwise) == [0, 1, 2, 3, 4]
    start, pairwise = _line([-1.0, 2.0, 3.0, 4.0])  # here the near side first is shorter
    assert shortest_tour(start, pairwise) == [0, 1, 2, 3]
    assert shortest_tour(np.array([2.0]), np.zeros((1, 1))) == [0]
    assert shortest_tour(np.zeros(0), np.zeros((0, 0))) == []


def _route_length(start: np.ndarray, pairwise: np.ndarray, route: list[int]) -> float:
    return start[route[0]] + sum(pairwise[a, b] for a, b in zip(route[:-1], route[1:], strict=False))


def test_the_shortest_tour_matches_the_best_order_on_small_random_sets():
    rng = np.random.default_rng(3)
    for _ in range(10):
        pts, agent = rng.uniform(0, 10, (6, 2)), rng.uniform(0, 10, 2)
        start = np.hypot(*(pts - agent).T)
        pairwise = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1))

        best = min(_route_length(start, pairwise, list(p)) for p in itertools.permutations(range(6)))
        assert np.isclose(_route_length(start, pairwise, shortest_tour(start, pairwise)), best)
        # the local search (used beyond `exact_up_to` stops) is a heuristic: a valid route, near the best
        local = shortest_tour(start, pairwise, exact_up_to=0)
        assert sorted(local) == list(range(6)) and _route_length(start, pairwise, local) <= 1.1 * best
