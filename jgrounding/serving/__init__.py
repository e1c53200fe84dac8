"""The policy server: one process keeps the model and the grounding warm and serves them over a WebSocket,
a live 30 Hz command stream, and a page for people (``python -m jgrounding.serve``; docs/serving.md).

Starlette (routes, WebSocket) on uvicorn (the ASGI server). One WebSocket, ``/ws``, carries every request;
a binary frame is msgpack and is answered in msgpack (robots: :mod:`jgrounding.client`), a text frame is
JSON and is answered in JSON (the page). Requests (a map with ``type``; ``id`` is echoed back):

- ``info``: versions of the package, model and library, the limits, the scene for drawing the trunk.
- ``ground``: ``text`` -> the grounding (intent, intensity, confidence, confident).
- ``sample``: ``text`` (grounded first) or ``intent`` / ``intensity`` (names, indices or lists of them),
  ``num_samples``, ``steps``, ``current``, ``start_conditioned``, ``seed``, ``force``, ``rollout`` ->
  trajectories ``u`` shaped as :func:`jgrounding.sample` returns them, with the grounding and versions.
- ``stream``: start a 30 Hz command stream on this connection (one ``tick`` message per control step);
  later ``respond`` messages switch it to a new response, generated from the command being executed
  (start-conditioned sampling); ``stop`` glides it to rest and ends it with its statistics.

Every trajectory comes from :func:`jgrounding.sample` (the safety gate); the stream's holds and glides pass
:func:`jgrounding.safety.emit`, and every streamed command is checked against the bounds and the slew limit.

The modules, in the order they build on each other:

- :mod:`jgrounding.serving.protocol`: :class:`Limits`, :class:`RequestError`, the parsed requests;
- :mod:`jgrounding.serving.wire`: the msgpack / JSON codec with numpy arrays, shared with the client;
- :mod:`jgrounding.serving.stream`: the 30 Hz :class:`Stream` (it talks to its client through a callback);
- :mod:`jgrounding.serving.app`: :class:`Policy`, :class:`Server` (routes, auth, rate bucket, dispatch table);
- :mod:`jgrounding.serving.run`: :func:`check_bind`, :class:`Running` (a server in a thread), :func:`serve`.
"""

from jgrounding.serving.app import OPS, Policy, RateBucket, Server
from jgrounding.serving.protocol import (
    REQUEST_TYPES,
    WS_MAX_SIZE,
    Limits,
    RequestError,
    RespondRequest,
    SampleRequest,
    StreamRequest,
    grounding_dict,
    scene,
)
from jgrounding.serving.run import DEFAULT_HOST, DEFAULT_PORT, Running, check_bind, is_loopback, serve
from jgrounding.serving.stream import CONTROL_HZ, SeamStats, Stream, glide_to_rest, hold
from jgrounding.serving.wire import decode, decode_ndarrays, decode_reply, encode, encode_request

__all__ = [
    "CONTROL_HZ",
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "OPS",
    "REQUEST_TYPES",
    "WS_MAX_SIZE",
    "Limits",
    "Policy",
    "RateBucket",
    "RequestError",
    "RespondRequest",
    "Running",
    "SampleRequest",
    "SeamStats",
    "Server",
    "Stream",
    "StreamRequest",
    "check_bind",
    "decode",
    "decode_ndarrays",
    "decode_reply",
    "encode",
    "encode_request",
    "glide_to_rest",
    "grounding_dict",
    "hold",
    "is_loopback",
    "scene",
    "serve",
]
