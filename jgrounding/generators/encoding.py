"""The generators' normalization of their targets: controls and actuation in ~[0, 1] <-> [-1, 1]."""

from __future__ import annotations


def encode(y):
    """Controls / actuation in ~[0, 1] -> the generators' normalized [-1, 1]."""
    return 2.0 * y - 1.0


def decode(x):
    """The generators' normalized [-1, 1] -> controls / actuation in ~[0, 1]."""
    return 0.5 * (x + 1.0)
