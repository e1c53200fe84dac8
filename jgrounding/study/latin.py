"""Counterbalancing: the balanced Latin square of Williams (1949).

For ``n`` conditions, each condition appears once in every position, and each ordered pair of conditions
is adjacent (one right after the other) equally often: once in the ``n`` rows of an even ``n``, twice in
the ``2n`` rows (the square and its mirror) of an odd ``n``. Participant ``k`` (0-based, in order of
enrolment) gets row ``k mod len(rows)``; complete sets of rows counterbalance order and first-order carryover.
"""

from __future__ import annotations


def williams(n: int) -> tuple[tuple[int, ...], ...]:
    """The rows of a Williams design for ``n >= 1`` conditions (indices ``0..n-1``).

    The first row is ``0, 1, n-1, 2, n-2, ...``; row ``i`` adds ``i`` to it (mod ``n``). An odd ``n`` adds
    each row's reverse.
    """
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"a Williams design needs a number of conditions >= 1, got {n!r}")
    first, lo, hi = [0], 1, n - 1
    while len(first) < n:
        first.append(lo)
        lo += 1
        if len(first) < n:
            first.append(hi)
            hi -= 1
    rows = [tuple((c + i) % n for c in first) for i in range(n)]
    if n % 2:
        rows += [r[::-1] for r in rows]
    return tuple(rows)


def order_for(number: int, conditions: tuple[str, ...]) -> tuple[int, tuple[str, ...]]:
    """``(row, conditions in that row's order)`` for the participant enrolled ``number``-th (0-based)."""
    rows = williams(len(conditions))
    row = number % len(rows)
    return row, tuple(conditions[i] for i in rows[row])
