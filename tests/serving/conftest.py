"""One warm model for every serving test (loading and compiling it is the slow part)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def policy():
    from jgrounding.apps import server

    return server.Policy()


@pytest.fixture(scope="module")
def running(policy):
    from jgrounding.apps import server

    run = server.Running(server.Server(policy))
    yield run
    run.stop()
