"""rovernav.evaluation.pool.map_runs, the benchmarks' process pool: every item run once in another
process, the pairs in the items' order or as the runs end, and a run's exception passed on."""

from __future__ import annotations

import os
import time

import pytest

from rovernav.evaluation.pool import map_runs


def square(x: int) -> tuple[int, int]:
    return x * x, os.getpid()


def pause_then(delay_s: float, value: str) -> str:
    time.sleep(delay_s)
    return value


def fail_on_three(x: int) -> int:
    if x == 3:
        raise ValueError("three")
    return x


def test_ordered_pairs_follow_the_items_and_run_elsewhere():
    pairs = list(map_runs(square, [3, 1, 2], 2))
    assert [(item, result[0]) for item, result in pairs] == [(3, 9), (1, 1), (2, 4)]
    assert all(result[1] != os.getpid() for _, result in pairs)


def test_unordered_pairs_come_as_runs_end_with_star_arguments():
    items = [(1.5, "slow"), (0.0, "fast")]
    pairs = list(map_runs(pause_then, items, 2, ordered=False, star=True))
    assert pairs == [((0.0, "fast"), "fast"), ((1.5, "slow"), "slow")]


def test_a_run_that_raises_raises_when_its_pair_is_due():
    got = []
    with pytest.raises(ValueError, match="three"):
        for _item, result in map_runs(fail_on_three, [1, 2, 3, 4], 1):
            got.append(result)
    assert got == [1, 2]


def test_no_items_no_pairs():
    assert list(map_runs(square, [], 1)) == []
