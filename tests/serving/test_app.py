"""The app (jgrounding/serving/app.py) over its WebSocket and routes: info, ground and sample, holding still,
the rate bucket, the token, and the dispatch table."""

from __future__ import annotations

import json
import urllib.request

import numpy as np
import pytest

from jgrounding import safety, serving
from jgrounding.client import Client, ServerError
from jgrounding.serving import app, protocol

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


def test_low_confidence_holds_still(running):
    with Client(running.url) as c:
        r = c.sample("asdf qwer zxcv", current=[0.2, 0.1, 0.0, 0.3], num_samples=2)
        assert not r["grounding"]["confident"] and r["hold_still"]
        np.testing.assert_allclose(r["u"], np.broadcast_to([0.2, 0.1, 0.0, 0.3], (2, 150, 4)), atol=1e-6)
        forced = c.sample("asdf qwer zxcv", force=True)
        assert not forced["hold_still"] and np.ptp(forced["u"]) > 0


def test_http_routes_info_and_health(running):
    with urllib.request.urlopen(running.http + "api/info", timeout=30) as r:
        info = json.load(r)
    assert info["num_steps"] == 150 and info["control_hz"] == 30 and info["limits"]["max_text"] == 1000
    with urllib.request.urlopen(running.http + "healthz", timeout=30) as r:
        assert json.load(r)["ok"] is True


def test_rate_limit(policy):
    run = serving.Running(serving.Server(policy, serving.Limits(rate=2.0, burst=3)))
    try:
        with Client(run.url) as c:
            for _ in range(3):
                c.info()
            with pytest.raises(ServerError, match="rate limit: at most 2 requests/s"):
                c.info()
    finally:
        run.stop()


def test_rate_bucket_refills_at_its_rate():
    bucket = app.RateBucket(rate=1000.0, burst=2)
    bucket.take(), bucket.take()
    with pytest.raises(protocol.RequestError, match="bursts of 2") as err:
        bucket.take()
    assert err.value.code == "rate_limited"
    bucket.refill -= 0.01  # 10 ms later: 10 tokens' worth, capped at the burst
    bucket.take(), bucket.take()
    with pytest.raises(protocol.RequestError):
        bucket.take()


def test_token(policy):
    run = serving.Running(serving.Server(policy, token="s3cret"))
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


def test_the_dispatch_table_answers_every_request_type():
    assert set(app.OPS) == set(protocol.REQUEST_TYPES)
    assert all(callable(handler) for handler in app.OPS.values())
