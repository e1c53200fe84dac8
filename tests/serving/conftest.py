"""One warm model for every serving test (loading and compiling it is the slow part)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def policy():
    from jgrounding import serving

    return serving.Policy()


@pytest.fixture(scope="module")
def running(policy):
    from jgrounding import serving

    run = serving.Running(serving.Server(policy))
    yield run
    run.stop()
