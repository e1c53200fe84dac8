"""The Williams design: every condition once per position, every ordered adjacent pair equally often."""

import collections
import itertools

import pytest

from jgrounding.study.latin import order_for, williams


@pytest.mark.parametrize("n", range(1, 8))
def test_each_condition_once_in_every_position_and_row(n):
    rows = williams(n)
    assert len(rows) == (n if n % 2 == 0 else 2 * n) or n == 1
    for row in rows:
        assert sorted(row) == list(range(n))
    for position in range(n):
        counts = collections.Counter(row[position] for row in rows)
        assert set(counts.values()) == {len(rows) // n}


@pytest.mark.parametrize("n", range(2, 8))
def test_first_order_carryover_is_balanced(n):
    rows = williams(n)
    pairs = collections.Counter((a, b) for row in rows for a, b in itertools.pairwise(row))
    assert set(pairs) == {(a, b) for a in range(n) for b in range(n) if a != b}
    assert set(pairs.values()) == {1 if n % 2 == 0 else 2}


def test_known_squares():
    assert williams(2) == ((0, 1), (1, 0))
    assert williams(4) == ((0, 1, 3, 2), (1, 2, 0, 3), (2, 3, 1, 0), (3, 0, 2, 1))
    assert williams(3)[:3] == ((0, 1, 2), (1, 2, 0), (2, 0, 1)) and williams(3)[3] == (2, 1, 0)


def test_participants_cycle_through_the_rows():
    conditions = ("av_only", "trunk", "scripted")
    orders = [order_for(k, conditions) for k in range(12)]
    assert [row for row, _ in orders] == [0, 1, 2, 3, 4, 5] * 2
    assert orders[0][1] == ("av_only", "trunk", "scripted") and orders[3][1] == ("scripted", "trunk", "av_only")
    with pytest.raises(ValueError, match="conditions >= 1"):
        williams(0)
