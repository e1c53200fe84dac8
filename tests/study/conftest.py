"""Fixtures of the study's tests: a real PostgreSQL server started in a temporary folder on a free port (Debian's
postgresql-15 binaries; skipped, saying why, where they or the psycopg driver are missing), and small designs."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

PG_BIN = Path("/usr/lib/postgresql/15/bin")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _unavailable(why: str):
    """Skip on a developer's machine; in CI (CI=true) fail, as the browser tests do: a skip there proves nothing."""
    if os.environ.get("CI"):
        pytest.fail(why)
    pytest.skip(why)


@pytest.fixture(scope="session")
def postgres_url():
    """``postgresql+psycopg://`` URL of a throw-away server (trust auth, loopback only), stopped at the end."""
    if not (PG_BIN / "initdb").exists() or not (PG_BIN / "pg_ctl").exists():
        _unavailable(f"PostgreSQL binaries not found in {PG_BIN} (scripts/install_system.sh installs postgresql)")
    try:
        import psycopg  # noqa: F401
    except ImportError:
        _unavailable("the psycopg driver is not installed (requirements.txt pins psycopg[binary])")
    as_user: list[str] = []
    root = tempfile.mkdtemp(prefix="jg-pg-")
    if os.geteuid() == 0:  # postgres refuses to run as root: run it as Debian's postgres user
        if shutil.which("runuser") is None:
            _unavailable("running as root without runuser: cannot start postgres as another user")
        as_user = ["runuser", "-u", "postgres", "--"]
        shutil.chown(root, "postgres")
    data, port = str(Path(root) / "data"), _free_port()
    run = lambda *cmd: subprocess.run([*as_user, *cmd], check=True, capture_output=True, text=True, timeout=120)
    run(str(PG_BIN / "initdb"), "-D", data, "-U", "postgres", "--auth=trust", "-E", "UTF8", "--no-sync")
    opts = f"-p {port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off"
    run(str(PG_BIN / "pg_ctl"), "-D", data, "-o", opts, "-l", str(Path(root) / "log"), "-w", "-t", "60", "start")
    try:
        yield f"postgresql+psycopg://postgres@127.0.0.1:{port}/postgres"
    finally:
        subprocess.run([*as_user, str(PG_BIN / "pg_ctl"), "-D", data, "-m", "immediate", "stop"], capture_output=True)
        time.sleep(0.2)
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request, tmp_path):
    """Each store test runs on SQLite and on PostgreSQL (a fresh database each time)."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'study.db'}"
        return
    import sqlalchemy as sa

    base = request.getfixturevalue("postgres_url")
    name = f"t{os.getpid()}_{time.monotonic_ns()}"
    admin = sa.create_engine(base, isolation_level="AUTOCOMMIT")
    with admin.connect() as c:
        c.execute(sa.text(f"CREATE DATABASE {name}"))
    yield base.rsplit("/", 1)[0] + f"/{name}"
    with admin.connect() as c:
        c.execute(sa.text(f"DROP DATABASE {name} WITH (FORCE)"))
    admin.dispose()


@pytest.fixture
def design():
    """Two conditions that need no model (a hold and a library demonstration), two episodes."""
    from jgrounding.study import Design, Episode

    return Design(
        name="test",
        conditions=("av_only", "scripted"),
        episodes=(
            Episode("Hello there!", intent="greeting", intensity="moderate"),
            Episode("Come here, please.", intent="beckoning", intensity="subtle"),
        ),
        sim=False,
        stall_s=60.0,
    )
