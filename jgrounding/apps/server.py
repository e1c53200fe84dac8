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
"""

from __future__ import annotations

import asyncio
import collections
import concurrent.futures
import dataclasses
import hmac
import ipaddress
import json
import logging
import math
import secrets
import time
from pathlib import Path
from typing import Any

import msgpack
import numpy as np

from jgrounding import safety
from jgrounding.config import NUM_STEPS, SampleConfig
from jgrounding.vocabulary import INTENSITIES, INTENTS

log = logging.getLogger("jgrounding.serve")

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
CONTROL_HZ = 30  # 150 steps over 5 s
STATIC = Path(__file__).resolve().parent / "static"
REQUEST_TYPES = ("info", "ground", "sample", "stream", "respond", "stop", "ack")
WS_MAX_SIZE = 4 << 20  # larger frames are refused by the WebSocket layer itself (close code 1009)


@dataclasses.dataclass(frozen=True)
class Limits:
    """What one request and one connection may ask of the server (``--max-*`` options)."""

    max_text: int = 1000  # characters of a response text
    max_samples: int = 64  # num_samples per tuple
    max_trajectories: int = 1024  # tuples x num_samples per request
    max_steps: int = 100  # sampler steps
    max_message: int = 64 << 10  # bytes of one request
    rate: float = 1000.0  # requests per second per connection (token bucket)
    burst: int = 1000  # requests in a burst (the bucket's size)
    stall_s: float = 1.0  # a streaming client silent this long is stalled: the stream glides to rest


class RequestError(Exception):
    """A request the server refuses; answered as ``{"type": "error", "code": code, "error": message}``."""

    def __init__(self, message: str, code: str = "bad_request"):
        super().__init__(message)
        self.code = code


# --- the model -----------------------------------------------------------------------------------------


class Policy:
    """The server's handle on the one decision path (:class:`jgrounding.policy.respond.Responder`): the shipped
    model (or a lab's ``checkpoint``) and the grounding, loaded and compiled once. Groundings are snapped onto
    the checkpoint's tuples and held or moved exactly as the CLI does."""

    def __init__(self, checkpoint: str | Path | None = None, allow_library_mismatch: bool = False, warm: bool = True):
        from jgrounding.policy.respond import Responder

        self.responder = Responder(checkpoint, allow_library_mismatch=allow_library_mismatch)
        self.checkpoint = self.responder.checkpoint
        self.allow_library_mismatch = self.responder.allow_library_mismatch
        self.responder.model  # noqa: B018  (refusals happen here, at start)
        self.num_tendons = self.responder.num_tendons
        self.start_conditioning = self.responder.inpaints  # else streams blend in from the command
        self.model_info = self.responder.info
        if warm:
            self.warm()

    def warm(self) -> None:
        """Compile what the server answers most (the Responder's warm-up, and the stream's own gated plans)."""
        self.responder.warm()
        rest = np.zeros(self.num_tendons, np.float32)
        glide_to_rest(rest + 0.5), hold(rest)

    def decide(self, text: str, force: bool = False):
        """:meth:`Responder.decide` of a text: the grounding on this checkpoint's tuples and whether to hold."""
        return self.responder.decide(text, force=force)

    def ground(self, text: str):
        return self.decide(text).grounding

    def hold(self, current, num_samples: int = 1) -> np.ndarray:
        return self.responder.hold(current, num_samples)

    def sample(self, key, intent, intensity, num_samples=1, **kwargs) -> np.ndarray:
        return self.responder.trajectory(key, intent, intensity, num_samples, **kwargs)

    @staticmethod
    def rollout(u: np.ndarray) -> np.ndarray:
        """Backbone positions ``(T, 11, 3)`` of the simulated trunk for one trajectory ``(T, 4)``."""
        from jgrounding import sim

        return sim.rollout(u[None], engine="native").backbone[0].astype(np.float32)


def grounding_dict(g) -> dict:
    return {
        "intent": g.intent,
        "intensity": g.intensity,
        "confidence": round(float(g.confidence), 4),
        "confident": bool(g.confident),
        "backend": g.backend,
        "reason": g.reason,
    }


def scene() -> dict:
    """What the page needs to draw the trunk and the user (metres, world frame; x toward the user, z up)."""
    from jgrounding.sim import model as tm

    return {
        "base": [0.0, 0.0, tm.BASE_HEIGHT],
        "trunk_length": tm.TRUNK_LENGTH,
        "user_torso": {"x": tm.USER_TORSO_X, "z": list(tm.USER_TORSO_Z), "radius": tm.USER_TORSO_RADIUS},
        "user_head": list(tm.USER_HEAD),
    }


# --- wire format ---------------------------------------------------------------------------------------


def _pack_default(obj):
    if isinstance(obj, np.ndarray):  # openpi's msgpack_numpy convention: raw bytes with dtype and shape
        arr = np.ascontiguousarray(obj)
        return {"__ndarray__": True, "data": arr.tobytes(), "dtype": arr.dtype.str, "shape": list(arr.shape)}
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot encode {type(obj).__name__}")


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return np.round(obj.astype(np.float64), 6).tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot encode {type(obj).__name__}")


def encode(message: dict, binary: bool) -> bytes | str:
    if binary:
        return msgpack.packb(message, default=_pack_default, use_bin_type=True)
    return json.dumps(message, default=_json_default, allow_nan=False)


def decode_ndarrays(obj):
    """msgpack ``object_hook``: maps written by :func:`encode` back to numpy arrays."""
    if isinstance(obj, dict) and obj.get("__ndarray__") is True:
        return np.frombuffer(obj["data"], dtype=np.dtype(obj["dtype"])).reshape(obj["shape"])
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


# --- validation ------------------------------------------------------------------------------------------


def _int(msg: dict, name: str, default: int, lo: int, hi: int) -> int:
    v = msg.get(name, default)
    if v is None:
        v = default
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise RequestError(f"{name} must be an integer in {lo}..{hi}, got {v!r}")
    return v


def _bool(msg: dict, name: str, default: bool = False) -> bool:
    v = msg.get(name, default)
    if not isinstance(v, bool):
        raise RequestError(f"{name} must be true or false, got {v!r}")
    return v


def _text(msg: dict, limits: Limits) -> str:
    text = msg.get("text")
    if not isinstance(text, str):
        raise RequestError(f"text must be a string, got {type(text).__name__}")
    if not text.strip():
        raise RequestError("text is empty; give a response such as 'User seems sad; respond calmly'")
    if len(text) > limits.max_text:
        raise RequestError(f"text has {len(text)} characters; at most {limits.max_text}", "too_large")
    return text


def _current(msg: dict, num_tendons: int):
    cur = msg.get("current", safety.REST)
    try:
        safety.current_command(cur, num_tendons)
    except ValueError as e:
        raise RequestError(str(e)) from None
    return cur if cur is None or isinstance(cur, str) else np.asarray(cur, np.float32)


def _tuples(msg: dict, limits: Limits):
    """(intent, intensity) of a request naming them, validated like :func:`jgrounding.sample` does."""
    from jgrounding.vocabulary import intensity_index, intent_index

    intent, intensity = msg.get("intent"), msg.get("intensity", "moderate")
    if intent is None:
        raise RequestError(f"give text or intent (one of {', '.join(INTENTS)}) with intensity")
    for name, value in (("intent", intent), ("intensity", intensity)):
        if isinstance(value, list) and not 1 <= len(value) <= limits.max_trajectories:
            raise RequestError(f"{name} lists hold 1..{limits.max_trajectories} entries, got {len(value)}")
    try:
        for v in intent if isinstance(intent, list) else [intent]:
            intent_index(v)
        for v in intensity if isinstance(intensity, list) else [intensity]:
            intensity_index(v)
    except (TypeError, ValueError) as e:
        raise RequestError(str(e)) from None
    n = max(len(x) if isinstance(x, list) else 1 for x in (intent, intensity))
    return intent, intensity, n


# --- the server -------------------------------------------------------------------------------------------


class Server:
    """The Starlette app around a :class:`Policy`; :meth:`app` is served by uvicorn."""

    def __init__(self, policy: Policy, limits: Limits = Limits(), token: str | None = None, workers: int = 2):
        self.policy = policy
        self.limits = limits
        self.token = token
        self.pool = concurrent.futures.ThreadPoolExecutor(max_workers=workers, thread_name_prefix="jg-model")
        self.started = time.time()
        self.connections = 0
        self.served = collections.Counter()

    # The model runs in worker threads (JAX releases the GIL), so streams keep ticking meanwhile.
    async def _call(self, fn, *args, **kwargs):
        return await asyncio.get_running_loop().run_in_executor(self.pool, lambda: fn(*args, **kwargs))

    def info(self) -> dict:
        return {
            "model": self.policy.model_info,
            "limits": dataclasses.asdict(self.limits),
            "control_hz": CONTROL_HZ,
            "num_steps": 150,
            "max_slew": safety.MAX_SLEW,
            "intents": list(INTENTS),
            "intensities": list(INTENSITIES),
            "scene": scene(),
            "auth": self.token is not None,
        }

    def authorized(self, websocket_or_request) -> bool:
        if self.token is None:
            return True
        given = websocket_or_request.query_params.get("token") or ""
        header = websocket_or_request.headers.get("authorization", "")
        if header.lower().startswith("bearer "):
            given = header[7:]
        return hmac.compare_digest(given.encode(), self.token.encode())

    @staticmethod
    def same_origin(ws) -> bool:
        """A browser's page from another site may not drive the robot (cross-site WebSocket hijacking)."""
        origin = ws.headers.get("origin")
        if origin is None:  # not a browser
            return True
        host = ws.headers.get("host", "")
        return origin.split("://", 1)[-1].rstrip("/") == host

    # -- requests --

    async def ground(self, msg: dict) -> dict:
        decision = await self._call(self.policy.decide, _text(msg, self.limits))
        return {
            "grounding": {**grounding_dict(decision.grounding), "note": decision.note},
            "hold_still": decision.hold,
            "message": decision.message(),
        }

    async def sample(self, msg: dict) -> dict:
        import jax

        lim = self.limits
        num_samples = _int(msg, "num_samples", 1, 1, lim.max_samples)
        steps = _int(msg, "steps", 50, 1, lim.max_steps)
        seed = _int(msg, "seed", secrets.randbelow(1 << 31), 0, (1 << 31) - 1)
        start_conditioned, force, rollout = (_bool(msg, n) for n in ("start_conditioned", "force", "rollout"))
        sampler = msg.get("sampler")
        if sampler is not None and not isinstance(sampler, str):
            raise RequestError(f"sampler must be a string, got {type(sampler).__name__}")
        current = _current(msg, self.policy.num_tendons)
        grounding = None
        if "text" in msg:
            if "intent" in msg or "intensity" in msg:
                raise RequestError("give either text or intent/intensity, not both")
            decision = await self._call(self.policy.decide, _text(msg, lim), force)
            grounding = {**grounding_dict(decision.grounding), "note": decision.note}
            intent, intensity, n = decision.intent, decision.intensity, 1
        else:
            decision = None
            intent, intensity, n = _tuples(msg, lim)
        if n * num_samples > lim.max_trajectories:
            raise RequestError(
                f"{n} tuples x {num_samples} samples = {n * num_samples} trajectories; at most "
                f"{lim.max_trajectories} per request",
                "too_large",
            )
        if start_conditioned and current is None:
            raise RequestError("start_conditioned needs current ('rest' or a command per tendon)")
        hold = decision is not None and decision.hold
        t0 = time.perf_counter()
        if hold:  # as the CLI does: the current command, held, in the shape a sample would have
            u = self.policy.hold(current, num_samples)
        else:
            try:
                u = await self._call(
                    self.policy.sample,
                    jax.random.key(seed),
                    intent,
                    intensity,
                    num_samples,
                    steps=steps,
                    sampler=sampler,
                    current=current,
                    start_conditioned=start_conditioned,
                )
            except ValueError as e:  # e.g. an unknown sampler, a tuple the checkpoint lacks
                raise RequestError(str(e)) from None
        reply = {
            "u": np.asarray(u, np.float32),
            "grounding": grounding,
            "hold_still": hold,
            "message": decision.message(current) if hold else None,
            "seed": seed,
            "steps": steps,
            "start_conditioned": start_conditioned,
            "model": self.policy.model_info,
            "compute_ms": round(1e3 * (time.perf_counter() - t0), 3),
        }
        if rollout:
            first = np.asarray(u, np.float32).reshape(-1, 150, self.policy.num_tendons)[0]
            if self.policy.num_tendons != 4:
                raise RequestError("rollout simulates the built-in 4-tendon trunk; this checkpoint has other tendons")
            reply["backbone"] = await self._call(self.policy.rollout, first)
        return reply

    # -- the connection --

    async def websocket(self, ws) -> None:
        from starlette.websockets import WebSocketDisconnect

        await ws.accept()
        if not self.authorized(ws) or not self.same_origin(ws):
            why = "unauthorized: this server needs its token" if not self.authorized(ws) else "cross-origin refused"
            await ws.send_text(json.dumps({"type": "error", "ok": False, "code": "unauthorized", "error": why}))
            await ws.close(code=1008, reason=why[:100])
            return
        self.connections += 1
        conn = _Connection(self, ws)
        try:
            while True:
                event = await ws.receive()
                if event["type"] == "websocket.disconnect":
                    break
                frame = event.get("bytes")
                binary = frame is not None
                await conn.handle(frame if binary else (event.get("text") or ""), binary)
        except (WebSocketDisconnect, RuntimeError, ConnectionError):
            pass
        finally:
            self.connections -= 1
            await conn.close()

    def app(self):
        from starlette.applications import Starlette
        from starlette.responses import FileResponse, JSONResponse
        from starlette.routing import Route, WebSocketRoute

        async def index(request):
            return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

        async def info(request):
            if not self.authorized(request):
                return JSONResponse({"error": "unauthorized: this server needs its token"}, status_code=401)
            return JSONResponse(json.loads(encode(self.info(), binary=False)))

        async def health(request):
            return JSONResponse({"ok": True, "connections": self.connections, "served": dict(self.served)})

        return Starlette(
            routes=[
                Route("/", index),
                Route("/api/info", info),
                Route("/healthz", health),
                WebSocketRoute("/ws", self.websocket),
            ]
        )


class _Connection:
    """One client: its rate bucket, its send lock and (at most) one stream."""

    def __init__(self, server: Server, ws):
        self.server, self.ws = server, ws
        self.lock = asyncio.Lock()
        self.tokens = float(server.limits.burst)
        self.refill = time.monotonic()
        self.stream: Stream | None = None
        self.binary = True

    async def send(self, message: dict, binary: bool | None = None) -> None:
        data = encode(message, self.binary if binary is None else binary)
        async with self.lock:
            if isinstance(data, bytes):
                await self.ws.send_bytes(data)
            else:
                await self.ws.send_text(data)

    def _take_token(self) -> None:
        lim = self.server.limits
        now = time.monotonic()
        self.tokens = min(lim.burst, self.tokens + (now - self.refill) * lim.rate)
        self.refill = now
        if self.tokens < 1.0:
            wait = (1.0 - self.tokens) / lim.rate
            raise RequestError(
                f"rate limit: at most {lim.rate:g} requests/s per connection (bursts of {lim.burst}); "
                f"retry in {1e3 * wait:.0f} ms",
                "rate_limited",
            )
        self.tokens -= 1.0

    async def handle(self, frame, binary: bool) -> None:
        self.binary = binary
        req_id = None
        try:
            if self.stream is not None:
                self.stream.heard()
            self._take_token()
            msg = decode(frame, self.server.limits)
            req_id = msg.get("id")
            kind = msg["type"]
            self.server.served[kind] += 1
            if kind == "info":
                reply = self.server.info()
            elif kind == "ground":
                reply = await self.server.ground(msg)
            elif kind == "sample":
                reply = await self.server.sample(msg)
            elif kind == "stream":
                reply = await self.start_stream(msg)
            elif kind == "respond":
                if self.stream is None:
                    raise RequestError("no stream on this connection; send a 'stream' request first")
                reply = await self.stream.respond(msg)
            elif kind == "stop":
                if self.stream is None:
                    raise RequestError("no stream on this connection; send a 'stream' request first")
                self.stream.stop()
                reply = {"stopping": True}
            else:  # ack: a keep-alive of a streaming client
                return
            await self.send({"type": kind, "id": req_id, "ok": True, **reply})
        except RequestError as e:
            self.server.served["error"] += 1
            await self.send({"type": "error", "id": req_id, "ok": False, "code": e.code, "error": str(e)})
        except Exception as e:  # noqa: BLE001 (a bug must not take the server down; say what it was)
            log.exception("request failed")
            self.server.served["error"] += 1
            await self.send(
                {"type": "error", "id": req_id, "ok": False, "code": "internal", "error": f"{type(e).__name__}: {e}"}
            )

    async def start_stream(self, msg: dict) -> dict:
        if self.stream is not None and not self.stream.done:
            raise RequestError("this connection already streams; send 'respond' to change the motion or 'stop'")
        stall_s = msg.get("stall_s", self.server.limits.stall_s)
        if isinstance(stall_s, bool) or not isinstance(stall_s, (int, float)) or not 0.1 <= stall_s <= 60:
            raise RequestError(f"stall_s must be a number of seconds in 0.1..60, got {stall_s!r}")
        self.stream = Stream(self, stall_s=float(stall_s), sim=_bool(msg, "sim"), steps=_int(msg, "steps", 50, 1, 100))
        self.stream.task = asyncio.create_task(self.stream.run())
        reply = {"control_hz": CONTROL_HZ, "stall_s": float(stall_s)}
        if "text" in msg or "intent" in msg:
            reply.update(await self.stream.respond(msg))
        return reply

    async def close(self) -> None:
        if self.stream is not None:
            self.stream.closed = True
            if self.stream.task is not None:
                self.stream.task.cancel()
                try:
                    await self.stream.task
                except (asyncio.CancelledError, Exception):  # noqa: BLE001
                    pass


# --- the live stream ---------------------------------------------------------------------------------------

LEAD_TICKS = 2  # a new response starts this many ticks after it is ready to be planned (66 ms at 30 Hz)
GLIDE_TICKS = 30  # a glide to rest takes 1 s: a half-cosine moves <= pi / 60 ~ 0.052 per step


def glide_to_rest(start: np.ndarray, ticks: int = GLIDE_TICKS) -> np.ndarray:
    """``(ticks + 1, N_u)`` from ``start`` to 0 along a half-cosine, through the safety gate."""
    w = 0.5 * (1.0 + np.cos(np.pi * np.arange(ticks + 1) / ticks))
    return safety.emit(w[:, None] * start[None], num_channels=len(start), current=start)


def hold(start: np.ndarray, ticks: int = NUM_STEPS) -> np.ndarray:
    return safety.emit(np.broadcast_to(start, (ticks, len(start))), num_channels=len(start), current=start)


class SeamStats:
    """Largest step and jerk (third difference) of the streamed commands, across seams and inside plans.

    A seam is the tick ``s`` where a new plan starts (its first command is the one executed at ``s``); the
    steps into and out of ``s`` and the jerk windows ``[t-3, t]`` with ``t - 3 <= s < t`` count as across it.
    """

    def __init__(self):
        self.last = collections.deque(maxlen=3)
        self.seams: collections.deque = collections.deque(maxlen=8)
        self.max_step = {"seam": 0.0, "inside": 0.0}
        self.max_jerk = {"seam": 0.0, "inside": 0.0}
        self.violations = 0
        self.count = 0

    def seam(self, tick: int) -> None:
        self.seams.append(tick)

    def add(self, tick: int, u: np.ndarray) -> None:
        u = np.asarray(u, np.float64)
        if not (
            np.all(np.isfinite(u)) and u.min() >= safety.ACTUATION_MIN - 1e-6 and u.max() <= safety.ACTUATION_MAX + 1e-6
        ):
            self.violations += 1
        if self.last:
            step = float(np.abs(u - self.last[-1]).max())
            if step > safety.MAX_SLEW + 1e-6:
                self.violations += 1
            where = "seam" if any(tick in (s, s + 1) for s in self.seams) else "inside"
            self.max_step[where] = max(self.max_step[where], step)
        if len(self.last) == 3:
            a, b, c = self.last
            jerk = float(np.abs(u - 3 * c + 3 * b - a).max())
            where = "seam" if any(tick - 3 <= s < tick for s in self.seams) else "inside"
            self.max_jerk[where] = max(self.max_jerk[where], jerk)
        self.last.append(u)
        self.count += 1

    def summary(self) -> dict:
        return {
            "max_step_seam": round(self.max_step["seam"], 6),
            "max_step_inside": round(self.max_step["inside"], 6),
            "max_jerk_seam": round(self.max_jerk["seam"], 6),
            "max_jerk_inside": round(self.max_jerk["inside"], 6),
            "violations": self.violations,
        }


class Stream:
    """A 30 Hz command stream on one connection.

    The stream executes a *plan*: commands from tick ``plan_start`` on (the last one held after the plan
    ends). A new response at tick ``i`` is planned from the command the stream will execute at
    ``s = i + LEAD_TICKS``: the trajectory is sampled start-conditioned on it, so its first command is
    exactly that one, and replaces the plan from ``s`` on (re-planned from a later tick if the model was
    late). A client silent for ``stall_s`` (no message, not even ``ack``) gets a glide to rest; a
    non-confident grounding holds the command being executed; ``stop`` glides to rest and ends.
    """

    def __init__(self, conn: _Connection, stall_s: float, sim: bool = False, steps: int = SampleConfig.steps):
        self.conn, self.policy = conn, conn.server.policy
        n = self.policy.num_tendons
        self.tick = 0
        self.plan_start, self.plan = 0, np.zeros((1, n), np.float32)
        self.queued: tuple | None = None  # (start tick, plan, state) waiting for its tick
        self.state = "rest"
        self.seq = 0
        self.stall_s, self.steps = stall_s, steps
        self.last_heard = time.monotonic()
        self.stats = SeamStats()
        self.lateness: collections.deque = collections.deque(maxlen=20000)
        self.missed = 0
        self.late_plans = 0
        self.model_s = 0.0  # how long the model took to plan lately (sets how far ahead a response is planned)
        self.responses = 0
        self.stopping = self.done = self.closed = False
        self.task: asyncio.Task | None = None
        self.sim = None
        if sim and n == 4:
            import mujoco

            from jgrounding.sim import native

            model = native.load_model()
            self.sim = (model, mujoco.MjData(model), mujoco)

    def heard(self) -> None:
        self.last_heard = time.monotonic()

    def command_at(self, tick: int) -> np.ndarray:
        """The command the stream executes at ``tick`` (>= the current tick), the queued plan included."""
        if self.queued is not None and tick >= self.queued[0]:
            start, plan = self.queued[0], self.queued[1]
        else:
            start, plan = self.plan_start, self.plan
        return plan[min(max(tick - start, 0), len(plan) - 1)]

    def replace_plan(self, start_tick: int, plan: np.ndarray, state: str) -> None:
        """From ``start_tick`` on, execute ``plan`` (its first command is the one the stream would have
        executed then); until then the current plan goes on."""
        self.queued = (start_tick, np.asarray(plan, np.float32), state)
        self.stats.seam(start_tick)

    def _advance(self) -> None:
        if self.queued is not None and self.tick >= self.queued[0]:
            self.plan_start, self.plan, self.state = self.queued
            self.queued = None

    def stop(self) -> None:
        if not self.stopping:
            self.stopping = True
            s = self.tick + 1
            self.replace_plan(s, glide_to_rest(self.command_at(s)), "glide")

    async def respond(self, msg: dict) -> dict:
        """Plan a new response (``text`` or ``intent``/``intensity``; ``force``, ``seed``) into the stream."""
        import jax

        if self.stopping or self.done:
            raise RequestError("the stream is stopping; start a new one with 'stream'")
        lim = self.conn.server.limits
        force = _bool(msg, "force")
        seed = _int(msg, "seed", secrets.randbelow(1 << 31), 0, (1 << 31) - 1)
        grounding = decision = None
        if "text" in msg:
            decision = await self.conn.server._call(self.policy.decide, _text(msg, lim), force)
            grounding = {**grounding_dict(decision.grounding), "note": decision.note}
            intent, intensity = decision.intent, decision.intensity
        else:
            intent, intensity, n = _tuples(msg, lim)
            if n != 1:
                raise RequestError("a stream plays one tuple at a time; give one intent and one intensity")
        self.seq += 1
        seq = self.seq
        t_request = time.perf_counter()
        for _ in range(4):
            lead = min(CONTROL_HZ * 2, max(LEAD_TICKS, math.ceil(1.5 * self.model_s * CONTROL_HZ) + 1))
            s = self.tick + lead
            start = self.command_at(s).copy()
            if decision is not None and decision.hold:
                plan, state = hold(start), "hold"
            else:
                t_model = time.perf_counter()
                plan = await self.conn.server._call(
                    self.policy.sample,
                    jax.random.key(seed),
                    intent,
                    intensity,
                    1,
                    steps=self.steps,
                    current=start,
                    start_conditioned=self.policy.start_conditioning,
                )
                self.model_s = max(0.8 * self.model_s, time.perf_counter() - t_model)  # slow to forget a stall
                state = "move"
            if self.tick < s and not self.stopping:  # in time: the plan takes over at s
                self.replace_plan(s, plan, state)
                self.responses += 1
                return {
                    "seq": seq,
                    "grounding": grounding,
                    "hold_still": state == "hold",
                    "starts_at_tick": s,
                    "start": start,
                    "seed": seed,
                    "plan_ms": round(1e3 * (time.perf_counter() - t_request), 3),
                    "model": self.policy.model_info,
                }
            self.late_plans += 1
            if self.stopping:
                break
        raise RequestError("the model did not answer in time to join the stream; the stream goes on", "model_late")

    async def run(self) -> None:
        period = 1.0 / CONTROL_HZ
        t0 = time.perf_counter()
        try:
            while not self.closed:
                target = t0 + self.tick * period
                delay = target - time.perf_counter()
                if delay > 0:
                    await asyncio.sleep(delay)
                late = time.perf_counter() - target
                self.lateness.append(late)
                if late > period:
                    self.missed += 1
                if (
                    not self.stopping
                    and self.state not in ("rest", "glide-stalled")
                    and time.monotonic() - self.last_heard > self.stall_s
                ):
                    s = self.tick
                    self.replace_plan(s, glide_to_rest(self.command_at(s)), "glide-stalled")
                self._advance()
                u = self.command_at(self.tick)
                self.stats.add(self.tick, u)
                i = self.tick - self.plan_start
                state = self.state
                if state.startswith("glide") and i >= len(self.plan) - 1:
                    state = "rest"
                elif state == "move" and i >= len(self.plan):
                    state = "hold"
                msg: dict[str, Any] = {"type": "tick", "tick": self.tick, "u": u, "state": state, "seq": self.seq}
                if self.sim is not None:
                    model, data, mujoco = self.sim
                    from jgrounding.sim.measures import NUM_POINTS, SUBSTEPS

                    data.ctrl[:] = u
                    for _ in range(SUBSTEPS):
                        mujoco.mj_step(model, data)
                    msg["backbone"] = data.sensordata[: 3 * NUM_POINTS].reshape(NUM_POINTS, 3).astype(np.float32)
                await self.conn.send(msg)
                if self.stopping and self.queued is None and i >= len(self.plan) - 1:
                    break
                self.tick += 1
            self.done = True
            if not self.closed:
                await self.conn.send({"type": "stream_end", "ok": True, "stats": self.summary()})
        finally:
            self.done = True

    def summary(self) -> dict:
        late = np.asarray(self.lateness, np.float64) * 1e3
        return {
            "ticks": self.tick + 1,
            "missed_ticks": self.missed,
            "tick_lateness_ms": {
                "p50": round(float(np.percentile(late, 50)), 3) if len(late) else 0.0,
                "p99": round(float(np.percentile(late, 99)), 3) if len(late) else 0.0,
                "max": round(float(late.max()), 3) if len(late) else 0.0,
            },
            "responses": self.responses,
            "late_plans": self.late_plans,
            **self.stats.summary(),
        }


# --- running it -----------------------------------------------------------------------------------------


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_bind(host: str, token: str | None) -> None:
    """Refuse to listen beyond this machine without a token clients must send."""
    if not is_loopback(host) and not token:
        raise ValueError(
            f"binding to {host!r} exposes the robot to the network; give --token (or JGROUNDING_TOKEN) so that "
            "clients must authenticate, or bind to 127.0.0.1 (the default)"
        )


class Running:
    """A server listening in a background thread (tests, benchmarks): ``.url``, ``.stop()``."""

    def __init__(self, server: Server, host: str = DEFAULT_HOST, port: int = 0, log_level: str = "warning"):
        import socket
        import threading

        import uvicorn

        check_bind(host, server.token)
        self.server = server
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, port))
        self.host, self.port = self.sock.getsockname()[:2]
        config = uvicorn.Config(server.app(), log_level=log_level, ws_max_size=WS_MAX_SIZE, lifespan="off")
        self.uvicorn = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.uvicorn.run, kwargs={"sockets": [self.sock]}, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + 30
        while not self.uvicorn.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("the server did not start")
            time.sleep(0.01)

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}/ws"

    @property
    def http(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def stop(self) -> None:
        self.uvicorn.should_exit = True
        self.thread.join(timeout=10)
        self.sock.close()


def serve(
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_PORT,
    *,
    checkpoint=None,
    token: str | None = None,
    limits: Limits = Limits(),
    allow_library_mismatch: bool = False,
    log_level: str = "info",
) -> None:
    """Load the model once and serve until interrupted (what ``python -m jgrounding.serve`` runs)."""
    import uvicorn

    check_bind(host, token)
    t0 = time.perf_counter()
    policy = Policy(checkpoint, allow_library_mismatch)
    print(
        f"jgrounding serve: model {policy.model_info['checkpoint']} (library {policy.model_info['library_version']}) "
        f"loaded and compiled in {time.perf_counter() - t0:.1f} s",
        flush=True,
    )
    server = Server(policy, limits, token)
    shown = "localhost" if host == DEFAULT_HOST else host
    print(f"  page:      http://{shown}:{port}/" + ("?token=..." if token else ""), flush=True)
    print(f"  websocket: ws://{shown}:{port}/ws  (python -m jgrounding.client --url ws://{shown}:{port}/ws ...)")
    uvicorn.run(server.app(), host=host, port=port, log_level=log_level, ws_max_size=WS_MAX_SIZE, lifespan="off")
