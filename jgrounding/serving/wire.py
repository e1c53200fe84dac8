"""The wire format, one codec for both ends (the server and :mod:`jgrounding.client`).

A binary WebSocket frame is msgpack, a text frame JSON; each request is answered in its own encoding.
Arrays in msgpack replies are maps ``{"__ndarray__": true, "data": bytes, "dtype": "<f4", "shape": [...]}``
(openpi's ``msgpack_numpy`` convention), in JSON replies nested lists. Requests carry arrays as lists: the
server's decoder accepts no binary data at all (``max_bin_len=0``).

- server: :func:`decode` a request frame, :func:`encode` a reply;
- client: :func:`encode_request`, :func:`decode_reply` (arrays back as writable numpy arrays,
  :func:`decode_ndarrays`).
"""

from __future__ import annotations

import json

import msgpack
import numpy as np

from jgrounding.serving.protocol import REQUEST_TYPES, Limits, RequestError


def _default(array):
    """A msgpack / JSON ``default``: numpy arrays as ``array(obj)`` makes them, numpy scalars as numbers."""

    def default(obj):
        if isinstance(obj, np.ndarray):
            return array(obj)
        if isinstance(obj, np.generic):
            return obj.item()
        raise TypeError(f"cannot encode {type(obj).__name__}")

    return default


def _raw(obj: np.ndarray) -> dict:  # openpi's msgpack_numpy convention: raw bytes with dtype and shape
    arr = np.ascontiguousarray(obj)
    return {"__ndarray__": True, "data": arr.tobytes(), "dtype": arr.dtype.str, "shape": list(arr.shape)}


_pack_default = _default(_raw)  # replies in msgpack
_json_default = _default(lambda a: np.round(a.astype(np.float64), 6).tolist())  # replies in JSON
_request_default = _default(np.ndarray.tolist)  # requests: lists, exactly (a request holds no binary data)


def encode(message: dict, binary: bool) -> bytes | str:
    """A reply: msgpack (arrays as raw bytes) when ``binary``, else JSON (arrays as lists, 6 decimals)."""
    if binary:
        return msgpack.packb(message, default=_pack_default, use_bin_type=True)
    return json.dumps(message, default=_json_default, allow_nan=False)


def decode_ndarrays(obj):
    """msgpack ``object_hook``: maps written by :func:`encode` back to (writable) numpy arrays."""
    if isinstance(obj, dict) and obj.get("__ndarray__") is True:
        return np.frombuffer(obj["data"], dtype=np.dtype(obj["dtype"])).reshape(obj["shape"]).copy()
    return obj


def decode(frame: bytes | str, limits: Limits) -> dict:
    """A request map from a frame; :class:`RequestError` for anything that is not one."""
    size = len(frame) if isinstance(frame, bytes) else len(frame.encode("utf-8", "surrogatepass"))
    if size > limits.max_message:
        raise RequestError(f"message of {size} bytes exceeds the limit of {limits.max_message} bytes", "too_large")
    try:
        if isinstance(frame, bytes):
            msg = msgpack.unpackb(frame, raw=False, strict_map_key=False, max_bin_len=0, max_ext_len=0)
        else:
            msg = json.loads(frame)
    except Exception as e:  # noqa: BLE001 (any parse failure is the client's)
        kind = "msgpack (binary frame)" if isinstance(frame, bytes) else "JSON (text frame)"
        raise RequestError(f"malformed message: not valid {kind}: {type(e).__name__}: {str(e)[:120]}") from None
    if not isinstance(msg, dict):
        raise RequestError(f"a request must be a map with a 'type', got {type(msg).__name__}")
    kind = msg.get("type")
    if kind not in REQUEST_TYPES:
        raise RequestError(f"unknown request type {kind!r}; valid types: {', '.join(REQUEST_TYPES)}")
    return msg


def encode_request(message: dict) -> bytes:
    """A request as a binary frame: msgpack, arrays (a ``current`` command) as lists."""
    return msgpack.packb(message, default=_request_default, use_bin_type=True)


def decode_reply(frame: bytes | str) -> dict:
    """A reply frame: msgpack with arrays back as numpy arrays, or JSON (the server answers a connection it
    refuses in JSON, before any request was read)."""
    if isinstance(frame, str):
        return json.loads(frame)
    return msgpack.unpackb(frame, raw=False, object_hook=decode_ndarrays)
