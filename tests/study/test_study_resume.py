"""Nothing is lost when the server dies: the study server runs as its own process (``python -m jgrounding.study
serve``), is killed with SIGKILL between ratings and in the middle of an episode, and every committed rating and
execution is in the database; a new server resumes the participant where the last commit left them."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from study_helpers import call, ok, wait_played

SQLALCHEMY = pytest.importorskip(
    "sqlalchemy", reason="the study's database needs sqlalchemy (requirements.txt pins it)"
)
from jgrounding.study import Store  # noqa: E402 (after the skip: the store imports sqlalchemy)

ROOT = Path(__file__).resolve().parents[2]
DESIGN = """name = "resume"
conditions = ["av_only", "scripted"]
sim = false
stall_s = 60
[[episodes]]
say = "Hello!"
intent = "greeting"
intensity = "moderate"
"""


class Server:
    def __init__(self, design: Path, db: Path):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.port = s.getsockname()[1]
        self.base = f"http://127.0.0.1:{self.port}"
        cmd = [sys.executable, "-m", "jgrounding.study", "serve", "--design", str(design), "--db", str(db)]
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        self.proc = subprocess.Popen(
            [*cmd, "--port", str(self.port)], cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT
        )
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            assert self.proc.poll() is None, self.proc.stdout.read().decode()
            try:
                if call(self.base, "design")[0] == 200:
                    return
            except OSError:
                pass
            time.sleep(0.2)
        raise AssertionError("the study server did not start")

    def kill(self) -> None:
        os.kill(self.proc.pid, signal.SIGKILL)
        assert self.proc.wait(timeout=10) == -signal.SIGKILL


def test_sigkill_between_ratings_and_mid_episode_loses_nothing(tmp_path):
    design, db = tmp_path / "study.toml", tmp_path / "study.db"
    design.write_text(DESIGN)
    dims = [
        "naturalness",
        "appropriateness",
        "expressiveness",
        "perceived_safety",
        "engagement",
        "overall_satisfaction",
    ]
    server = Server(design, db)
    pid = ok(server.base, "enrol", {})["participant"]
    ok(server.base, "play", {"participant": pid})
    wait_played(server.base)
    given = [
        ok(server.base, "rate", {"participant": pid, "position": 0, "dimension": d, "value": 2 + i})
        for i, d in enumerate(dims[:3])
    ]
    server.kill()  # between two ratings

    store = Store(db)
    saved = store.table("ratings")
    assert [(r["dimension"], r["value"]) for r in saved] == [(d, 2 + i) for i, d in enumerate(dims[:3])]
    assert [r["rated_at"].isoformat() + "Z" for r in saved] == [g["rated_at"] for g in given]
    assert store.progress(pid)["missing"] == dims[3:]

    server = Server(design, db)  # resumes: the same session, the participant at their fourth question
    assert ok(server.base, f"state?p={pid}")["answered"] == dims[:3]
    for d in dims[3:]:
        ok(server.base, "rate", {"participant": pid, "position": 0, "dimension": d, "value": 4})
    played = ok(server.base, "play", {"participant": pid})
    assert played["condition"] == "scripted"
    time.sleep(1.0)
    server.kill()  # in the middle of the episode

    row = [e for e in store.table("executions") if e["id"] == played["execution"]][0]
    assert row["planned_sha256"] == played["planned_sha256"] and row["executed_sha256"] is None
    assert store.progress(pid)["phase"] == "episode"  # an episode cut short is played again

    server = Server(design, db)
    again = ok(server.base, "play", {"participant": pid})
    assert again["planned_sha256"] == played["planned_sha256"] and again["seed"] == played["seed"]  # reproducible
    wait_played(server.base)
    for d in dims:
        ok(server.base, "rate", {"participant": pid, "position": 1, "dimension": d, "value": 5})
    assert ok(server.base, f"participant?p={pid}")["progress"]["phase"] == "done"
    server.kill()
    assert len(store.table("ratings")) == 12 and len(store.table("executions")) == 3
    assert len(store.sessions()) == 1
