"""The policy server over its WebSocket: requests, replies, limits, tokens and the message formats."""

from __future__ import annotations

import json

import msgpack
import numpy as np
import pytest

from jgrounding import safety
from jgrounding.apps import server
from jgrounding.client import Client, ServerError

TEXT = "User seems sad; respond calmly"


def test_info_ground_and_sample(running):
    with Client(running.url) as c:
        info = c.info()
        assert info["model"]["method"] == "tuple_spline_rf" and info["model"]["library_version"]
        assert info["model"]["package_version"] and info["control_hz"] == 30
        g = c.ground(TEXT)
        assert set(g) >= {"intent", "intensity", "confidence", "confident"} and 0 <= g["confidence"] <= 1
        r = c.sample(TEXT, seed=3, rollout=True)
        assert r["grounding"] == g and r["u"].shape == (150, 4) and r["u"].dtype == np.float32
        assert safety.is_safe(r["u"], current=np.zeros(4)) and r["backbone"].shape == (150, 11, 3)
        assert r["model"]["checkpoint"] and r["seed"] == 3
        again = c.sample(TEXT, seed=3)  # deterministic per seed, and what jg.sample gives
        np.testing.assert_array_equal(again["u"], r["u"])
        many = c.sample(intent=["greeting", "nodding"], intensity="subtle", num_samples=3, steps=2)
        assert many["u"].shape == (2, 3, 150, 4) and many["grounding"] is None
        mid = r["u"][75]
        sc = c.sample(intent="comforting", intensity="moderate", current=mid.tolist(), start_conditioned=True)
        np.testing.assert_allclose(sc["u"][0], mid, atol=1e-6)
        assert safety.is_safe(sc["u"], current=mid)


def test_json_text_frames_get_json_replies(running):
    from websockets.sync.client import connect

    with connect(running.url) as ws:
        ws.send(json.dumps({"type": "sample", "id": "a", "intent": 2, "intensity": 1, "seed": 1}))
        reply = json.loads(ws.recv(timeout=30))
        assert reply["id"] == "a" and reply["ok"] and np.asarray(reply["u"]).shape == (150, 4)


def test_low_confidence_holds_still(running):
    with Client(running.url) as c:
        r = c.sample("asdf qwer zxcv", current=[0.2, 0.1, 0.0, 0.3], num_samples=2)
        assert not r["grounding"]["confident"] and r["hold_still"]
        np.testing.assert_allclose(r["u"], np.broadcast_to([0.2, 0.1, 0.0, 0.3], (2, 150, 4)), atol=1e-6)
        forced = c.sample("asdf qwer zxcv", force=True)
        assert not forced["hold_still"] and np.ptp(forced["u"]) > 0


@pytest.mark.parametrize(
    "message, code, words",
    [
        ({"type": "sample", "text": "x" * 1001}, "too_large", "at most 1000"),
        ({"type": "sample", "intent": "greeting", "num_samples": 65}, "bad_request", "1..64"),
        ({"type": "sample", "intent": "greeting", "num_samples": "3"}, "bad_request", "num_samples must be"),
        ({"type": "sample", "intent": "greeting", "steps": 0}, "bad_request", "steps must be"),
        ({"type": "sample", "intent": "wave"}, "bad_request", "valid intents"),
        ({"type": "sample", "intent": "greeting", "current": [2, 0, 0, 0]}, "bad_request", "[0, 1]"),
        ({"type": "sample", "intent": "greeting", "current": None, "start_conditioned": True}, "bad_request", "needs"),
        ({"type": "sample", "intent": ["greeting"] * 20, "num_samples": 64}, "too_large", "at most 1024"),
        ({"type": "sample", "text": 5}, "bad_request", "text must be a string"),
        ({"type": "ground", "text": "  "}, "bad_request", "empty"),
        ({"type": "launch"}, "bad_request", "valid types"),
        ({"type": "respond", "text": "hi"}, "bad_request", "no stream"),
    ],
)
def test_bad_requests_get_clear_errors_and_the_connection_serves_on(running, message, code, words):
    with Client(running.url) as c:
        with pytest.raises(ServerError) as err:
            c.request(message)
        assert err.value.code == code and words in str(err.value)
        assert c.sample(intent="greeting", seed=0)["u"].shape == (150, 4)


def test_malformed_frames(running):
    from websockets.sync.client import connect

    frames = [b"\xc1\xff\x00garbage", b"\x93\x01\x02\x03", "{not json", "[1, 2]", "null", b"x" * (100 << 10)]
    with connect(running.url, max_size=None) as ws:
        for frame in frames:
            ws.send(frame)
            raw = ws.recv(timeout=10)
            reply = msgpack.unpackb(raw) if isinstance(raw, bytes) else json.loads(raw)
            assert reply["type"] == "error" and reply["error"], frame[:20]
        ws.send(msgpack.packb({"type": "info", "id": 7}))
        assert msgpack.unpackb(ws.recv(timeout=10))["id"] == 7


def test_rate_limit(policy):
    run = server.Running(server.Server(policy, server.Limits(rate=2.0, burst=3)))
    try:
        with Client(run.url) as c:
            for _ in range(3):
                c.info()
            with pytest.raises(ServerError, match="rate limit: at most 2 requests/s"):
                c.info()
    finally:
        run.stop()


def test_token_and_bind(policy):
    with pytest.raises(ValueError, match="--token"):
        server.check_bind("0.0.0.0", None)
    server.check_bind("0.0.0.0", "secret")
    server.check_bind("127.0.0.1", None)
    run = server.Running(server.Server(policy, token="s3cret"))
    try:
        with Client(run.url) as c:
            with pytest.raises(ServerError, match="unauthorized"):
                c.info()
        with Client(run.url, token="wrong") as c, pytest.raises(ServerError, match="unauthorized"):
            c.info()
        with Client(run.url, token="s3cret") as c:
            assert c.info()["auth"] is True
        with Client(run.url + "?token=s3cret") as c:  # what the page does
            assert c.ground(TEXT)["intent"]
    finally:
        run.stop()
