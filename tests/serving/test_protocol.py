"""The protocol (jgrounding/serving/protocol.py): limits that check themselves, requests parsed with errors
that name the field and its valid choices, over the socket (the connection serves on) and directly."""

from __future__ import annotations

import numpy as np
import pytest

from jgrounding.client import Client, ServerError
from jgrounding.serving import protocol
from jgrounding.serving.protocol import Limits, RequestError, RespondRequest, SampleRequest, StreamRequest


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


@pytest.mark.parametrize(
    "field, value, words",
    [
        ("max_text", 0, "Limits.max_text (--max-text) must be an integer in 1..100000, got 0"),
        ("max_samples", 4097, "Limits.max_samples (--max-samples) must be an integer in 1..4096"),
        ("max_samples", 2.0, "got 2.0"),
        ("max_trajectories", 0, "Limits.max_trajectories must be an integer in 1.."),
        ("max_steps", 1001, "Limits.max_steps must be an integer in 1..1000"),
        ("max_message", 5 << 20, "Limits.max_message must be an integer in 1..4194304"),
        ("burst", True, "Limits.burst (--burst) must be an integer"),
        ("rate", 0.0, "Limits.rate (--rate) must be a finite number > 0"),
        ("rate", float("nan"), "Limits.rate"),
        ("stall_s", 0.05, "Limits.stall_s (--stall) must be a number of seconds in 0.1..60, got 0.05"),
        ("stall_s", "1", "Limits.stall_s"),
    ],
)
def test_limits_validate_themselves(field, value, words):
    with pytest.raises(ValueError) as err:
        Limits(**{field: value})
    assert words in str(err.value)


def test_limits_accept_their_ranges():
    Limits()
    Limits(max_text=1, max_samples=4096, max_trajectories=1, max_steps=1000, max_message=4 << 20, rate=2, burst=1)
    Limits(stall_s=0.1), Limits(stall_s=60)


def test_sample_requests_parse_with_defaults_and_refuse_mixtures():
    lim = Limits()
    r = SampleRequest.parse({"type": "sample", "intent": ["greeting", "nodding"], "intensity": 1}, lim, 4)
    assert (r.tuples, r.num_samples, r.steps, r.text, r.current) == (2, 1, 50, None, "rest")
    assert 0 <= r.seed < 1 << 31 and not (r.force or r.rollout or r.start_conditioned)
    r = SampleRequest.parse({"type": "sample", "text": "hi", "current": [0.1, 0, 0, 0], "seed": 4}, lim, 4)
    assert r.text == "hi" and r.intent is None and r.seed == 4 and r.current.dtype == np.float32
    with pytest.raises(RequestError, match="either text or intent"):
        SampleRequest.parse({"type": "sample", "text": "hi", "intent": "greeting"}, lim, 4)
    with pytest.raises(RequestError, match="sampler must be a string"):
        SampleRequest.parse({"type": "sample", "intent": "greeting", "sampler": 3}, lim, 4)
    with pytest.raises(RequestError, match="give text or intent"):
        SampleRequest.parse({"type": "sample"}, lim, 4)


def test_stream_and_respond_requests():
    lim = Limits(stall_s=2.0)
    s = StreamRequest.parse({"type": "stream"}, lim)
    assert (s.stall_s, s.sim, s.steps, s.first) == (2.0, False, 50, False)
    assert StreamRequest.parse({"type": "stream", "intent": "greeting", "stall_s": 1}, lim).first
    with pytest.raises(RequestError, match="stall_s must be a number of seconds in 0.1..60"):
        StreamRequest.parse({"type": "stream", "stall_s": 0}, lim)
    r = RespondRequest.parse({"type": "respond", "intent": "greeting", "seed": 1}, lim)
    assert (r.intent, r.intensity, r.seed, r.text) == ("greeting", "moderate", 1, None)
    with pytest.raises(RequestError, match="one tuple at a time"):
        RespondRequest.parse({"type": "respond", "intent": ["greeting", "nodding"]}, lim)


def test_field_parsers():
    assert protocol.parse_int({"n": None}, "n", 3, 1, 5) == 3
    with pytest.raises(RequestError, match="n must be an integer in 1..5, got True"):
        protocol.parse_int({"n": True}, "n", 3, 1, 5)
    with pytest.raises(RequestError, match="force must be true or false"):
        protocol.parse_bool({"force": 1}, "force")
    assert protocol.parse_current({"current": None}, 4) is None
    with pytest.raises(RequestError, match="intensity lists hold"):
        protocol.parse_tuples({"intent": "greeting", "intensity": []}, Limits())
