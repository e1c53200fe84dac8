"""The study server without people: the API walks a participant through the design, refuses what is out of
turn, and the sha256 it records is that of the commands the stream sent (read back exactly from its msgpack
ticks, as a robot receives them)."""

from __future__ import annotations

import dataclasses
import hashlib
import threading

import numpy as np
import pytest
from study_helpers import call, ok, wait_played

SQLALCHEMY = pytest.importorskip(
    "sqlalchemy", reason="the study's database needs sqlalchemy (requirements.txt pins it)"
)
from jgrounding.study import Store  # noqa: E402 (after the skip: the store imports sqlalchemy)


@pytest.fixture
def study(tmp_path, design):
    from jgrounding.serving import Running
    from jgrounding.study.app import StudyServer

    store = Store(tmp_path / "study.db")
    server = StudyServer(dataclasses.replace(design, stall_s=1.0, episodes=design.episodes[:1]), store)
    run = Running(server)
    yield run, store
    run.stop()


class Robot(threading.Thread):
    """A robot's bridge on ``/study/ws``: msgpack ticks (float32 commands, exact), an ack every 10 ticks."""

    def __init__(self, url: str):
        super().__init__(daemon=True)
        from websockets.sync.client import connect

        from jgrounding.serving import encode_request

        self.ws, self.encode = connect(url), encode_request
        self.ticks: dict[int, np.ndarray] = {}
        self.ws.send(self.encode({"type": "ack"}))
        self.stopped = threading.Event()

    def run(self):
        from jgrounding.serving import decode_reply

        while not self.stopped.is_set():
            try:
                msg = decode_reply(self.ws.recv(timeout=5))
            except Exception:  # noqa: BLE001 (closed at the end of the test)
                return
            if msg["type"] == "tick":
                self.ticks[msg["tick"]] = msg["u"]
                if msg["tick"] % 10 == 0:
                    self.ws.send(self.encode({"type": "ack"}))

    def close(self):
        self.stopped.set()
        self.ws.close()


def test_a_participant_goes_through_and_the_executed_commands_are_recorded(study, design):
    run, store = study
    base = run.http
    robot = Robot(run.url.replace("/ws", "/study/ws"))
    robot.start()
    try:
        info = ok(base, "design")
        assert info["conditions"] == ["av_only", "scripted"] and len(info["questions"]) == 6
        pid = ok(base, "enrol", {})["participant"]
        for position, condition in enumerate(["av_only", "scripted"]):
            for episode in range(1):
                played = ok(base, "play", {"participant": pid})
                assert (played["condition"], played["episode"], played["position"]) == (condition, episode, position)
                status, busy = call(base, "play", {"participant": pid})
                assert status == 400 and "still playing" in busy["error"]
                state = ok(base, f"state?p={pid}")
                assert state["phase"] == "episode" and "condition" not in state  # the participant is not told
                wait_played(base)
                assert ok(base, f"state?p={pid}")["phase"] == "questionnaire"
                start = played["start_tick"]
                sent = np.stack([robot.ticks[t] for t in range(start, start + played["num_steps"])])
                assert sent.dtype == np.float32 and sent.shape == (150, 4)
                digest = hashlib.sha256(sent.tobytes()).hexdigest()
                row = [e for e in store.table("executions") if e["id"] == played["execution"]][0]
                assert row["planned_sha256"] == row["executed_sha256"] == digest == played["planned_sha256"]
                if condition == "av_only":
                    assert row["source"] == "hold" and np.ptp(sent) == 0
                else:
                    assert row["source"] == "library" and row["realization"] is not None and sent.max() > 0.2
            status, early = call(
                base, "rate", {"participant": pid, "position": 1 - position, "dimension": "engagement", "value": 3}
            )
            assert status == 400 and "not open" in early["error"]
            for i, q in enumerate(info["questions"]):
                reply = ok(
                    base,
                    "rate",
                    {"participant": pid, "position": position, "dimension": q["dimension"], "value": 1 + i % 5},
                )
                assert reply["rated_at"].endswith("Z")
        assert ok(base, f"participant?p={pid}")["progress"]["phase"] == "done"
        status, done = call(base, "play", {"participant": pid})
        assert status == 400 and "no episode" in done["error"]
        assert len(store.long_ratings()) == 12
    finally:
        robot.close()


def test_a_token_is_required_when_set(tmp_path, design):
    from jgrounding.serving import Running
    from jgrounding.study.app import StudyServer

    run = Running(StudyServer(design, Store(tmp_path / "s.db"), token="s3cret"))
    try:
        assert call(run.http, "design")[0] == 401
        status, reply = call(run.http, "design", token="s3cret")
        assert status == 200 and reply["name"] == "test"
    finally:
        run.stop()


def test_a_design_that_needs_the_model_refuses_to_start_without_it(tmp_path):
    from jgrounding.study import Design
    from jgrounding.study.app import StudyServer

    with pytest.raises(ValueError, match="give it the policy"):
        StudyServer(Design(), Store(tmp_path / "s.db"))
