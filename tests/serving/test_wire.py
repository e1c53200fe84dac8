"""The wire format (jgrounding/serving/wire.py): arrays both ways, JSON for text frames, malformed frames, and
one codec shared by the server and the client."""

from __future__ import annotations

import inspect
import json

import msgpack
import numpy as np
import pytest

from jgrounding import client
from jgrounding.serving import protocol, wire


def test_json_text_frames_get_json_replies(running):
    from websockets.sync.client import connect

    with connect(running.url) as ws:
        ws.send(json.dumps({"type": "sample", "id": "a", "intent": 2, "intensity": 1, "seed": 1}))
        reply = json.loads(ws.recv(timeout=30))
        assert reply["id"] == "a" and reply["ok"] and np.asarray(reply["u"]).shape == (150, 4)


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


def test_arrays_round_trip():
    u = np.linspace(0, 1, 600, dtype=np.float32).reshape(150, 4)
    reply = {"type": "sample", "u": u, "seed": np.int64(3), "nested": {"b": np.zeros((2, 3), np.float64)}}
    back = wire.decode_reply(wire.encode(reply, binary=True))
    assert back["u"].dtype == np.float32 and back["u"].shape == (150, 4) and back["seed"] == 3
    np.testing.assert_array_equal(back["u"], u)
    back["u"][0, 0] = 0.5  # a writable copy, not a view of the frame
    assert back["nested"]["b"].dtype == np.float64 and back["nested"]["b"].shape == (2, 3)
    text = wire.encode(reply, binary=False)
    assert isinstance(text, str) and np.asarray(json.loads(text)["u"]).shape == (150, 4)
    np.testing.assert_allclose(wire.decode_reply(text)["u"], u, atol=1e-6)  # 6 decimals in JSON
    with pytest.raises(TypeError, match="cannot encode"):
        wire.encode({"x": object()}, binary=True)


def test_requests_carry_arrays_as_lists_the_server_accepts():
    current = np.array([0.25, 0.5, 0.0, 1.0], np.float32)
    msg = wire.decode(wire.encode_request({"type": "sample", "current": current}), protocol.Limits())
    assert msg["current"] == current.tolist()
    with pytest.raises(protocol.RequestError, match="malformed"):  # a request may hold no binary data
        wire.decode(wire.encode({"type": "sample", "current": current}, binary=True), protocol.Limits())


@pytest.mark.parametrize(
    "frame, code, words",
    [
        (b"x" * 100, "too_large", "exceeds the limit of 64 bytes"),
        ("{not json", "bad_request", "not valid JSON"),
        (b"\xc1", "bad_request", "not valid msgpack"),
        ("[1, 2]", "bad_request", "must be a map"),
        (msgpack.packb({"type": "launch"}), "bad_request", "valid types: info, ground"),
    ],
)
def test_decode_refuses_what_is_not_a_request(frame, code, words):
    with pytest.raises(protocol.RequestError, match=words) as err:
        wire.decode(frame, protocol.Limits(max_message=64))
    assert err.value.code == code


def test_the_client_uses_the_servers_codec():
    assert client.wire is wire
    source = inspect.getsource(client)
    assert "import msgpack" not in source and "__ndarray__" not in source and "frombuffer" not in source
    own = [n for n, v in vars(client).items() if inspect.isfunction(v) and v.__module__ == client.__name__]
    assert not [n for n in own if "pack" in n or "code" in n], own  # no encoder or decoder of its own
