"""The server's app: the :class:`Policy` handle, the Starlette routes (the page, ``/api/info``, ``/healthz``,
the ``/ws`` WebSocket), the token and origin checks, each connection's rate bucket, and the dispatch table
:data:`OPS` from a request's ``type`` to its handler.

The model runs in worker threads (JAX releases the GIL), so a connection's 30 Hz stream
(:class:`jgrounding.serving.stream.Stream`) keeps ticking while another request is computed.
"""

from __future__ import annotations

import asyncio
import collections
import concurrent.futures
import dataclasses
import hmac
import json
import logging
import time
from collections.abc import Awaitable, Callable
from pathlib import Path

import numpy as np

from jgrounding import safety
from jgrounding.config import NUM_STEPS, NUM_TENDONS
from jgrounding.io import package_file
from jgrounding.serving.protocol import (
    Limits,
    RequestError,
    SampleRequest,
    StreamRequest,
    decision_dict,
    parse_text,
    resolve,
    scene,
)
from jgrounding.serving.stream import CONTROL_HZ, Stream, glide_to_rest, hold
from jgrounding.serving.wire import decode, encode
from jgrounding.vocabulary import INTENSITIES, INTENTS

log = logging.getLogger("jgrounding.serve")

STATIC = package_file("apps", "static")  # the page (package data of jgrounding.apps)


# --- the model -----------------------------------------------------------------------------------------------


class Policy:
    """The server's handle on the one decision path (:class:`jgrounding.policy.respond.Responder`): the shipped
    model (or a lab's ``checkpoint``) and the grounding, loaded and compiled once. Groundings are snapped onto
    the checkpoint's tuples and held or moved exactly as the CLI does."""

    def __init__(
        self,
        checkpoint: str | Path | None = None,
        allow_library_mismatch: bool = False,
        warm: bool = True,
        trunk: str | None = None,
    ):
        from jgrounding.policy.respond import Responder

        self.responder = Responder(checkpoint, allow_library_mismatch=allow_library_mismatch, trunk=trunk)
        self.trunk = self.responder.trunk  # the simulated trunk of screening, replies' backbones and the stream
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

    def act(self, key, decision, num_samples: int = 1, **kwargs):
        """Hold still or sample, as ``decision`` says (:meth:`Responder.act`, the one place)."""
        return self.responder.act(key, decision, num_samples, **kwargs)

    def sample(self, key, intent, intensity, num_samples=1, **kwargs) -> np.ndarray:
        return self.responder.trajectory(key, intent, intensity, num_samples, **kwargs)

    def rollout(self, u: np.ndarray) -> np.ndarray:
        """Backbone positions ``(T, 11, 3)`` of the simulated trunk for one trajectory ``(T, N_u)``."""
        from jgrounding import sim

        return sim.rollout(u[None], engine="native", trunk=self.trunk).backbone[0].astype(np.float32)


# --- the server ------------------------------------------------------------------------------------------------


class Server:
    """The Starlette app around a :class:`Policy`; :meth:`app` is served by uvicorn
    (:class:`jgrounding.serving.run.Running`, :func:`jgrounding.serving.run.serve`)."""

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
            "num_steps": NUM_STEPS,
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
        decision = await self._call(self.policy.decide, parse_text(msg, self.limits))
        return {  # a held text's message ("holding still: <reason>; ...") first, the grounding after it
            "hold_still": decision.hold,
            "message": decision.message(),
            "grounding": decision_dict(decision),
        }

    async def sample(self, msg: dict) -> dict:
        import jax

        req = SampleRequest.parse(msg, self.limits, self.policy.num_tendons)
        decision, grounding, intent, intensity = await resolve(req, self.policy, self._call)
        hold = decision is not None and decision.hold
        t0 = time.perf_counter()
        options = dict(steps=req.steps, sampler=req.sampler, start_conditioned=req.start_conditioned)
        key = jax.random.key(req.seed)
        try:
            if decision is not None:  # a text: the Responder carries out its decision, as the CLI's act does
                u = (
                    await self._call(self.policy.act, key, decision, req.num_samples, current=req.current, **options)
                ).u
            else:  # a named tuple: sampled as asked
                u = await self._call(
                    self.policy.sample, key, intent, intensity, req.num_samples, current=req.current, **options
                )
        except ValueError as e:  # e.g. an unknown sampler, a tuple the checkpoint lacks
            raise RequestError(str(e)) from None
        reply = {
            "hold_still": hold,
            "message": decision.message(req.current) if hold else None,
            "u": np.asarray(u, np.float32),
            "grounding": grounding,
            "seed": req.seed,
            "steps": req.steps,
            "start_conditioned": req.start_conditioned,
            "model": self.policy.model_info,
            "compute_ms": round(1e3 * (time.perf_counter() - t0), 3),
        }
        if req.rollout:
            if self.policy.num_tendons != NUM_TENDONS:
                raise RequestError(
                    f"rollout simulates the built-in {NUM_TENDONS}-tendon trunk; this checkpoint has "
                    f"{self.policy.num_tendons} tendons"
                )
            first = np.asarray(u, np.float32).reshape(-1, NUM_STEPS, self.policy.num_tendons)[0]
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


class RateBucket:
    """A token bucket: ``rate`` requests per second in bursts of at most ``burst``."""

    def __init__(self, rate: float, burst: int):
        self.rate, self.burst = rate, burst
        self.tokens = float(burst)
        self.refill = time.monotonic()

    def take(self) -> None:
        """Spend one token; :class:`RequestError` (``rate_limited``) when none is left."""
        now = time.monotonic()
        self.tokens = min(self.burst, self.tokens + (now - self.refill) * self.rate)
        self.refill = now
        if self.tokens < 1.0:
            wait = (1.0 - self.tokens) / self.rate
            raise RequestError(
                f"rate limit: at most {self.rate:g} requests/s per connection (bursts of {self.burst}); "
                f"retry in {1e3 * wait:.0f} ms",
                "rate_limited",
            )
        self.tokens -= 1.0


class _Connection:
    """One client: its rate bucket, its send lock and (at most) one stream."""

    def __init__(self, server: Server, ws):
        self.server, self.ws = server, ws
        self.lock = asyncio.Lock()
        self.bucket = RateBucket(server.limits.rate, server.limits.burst)
        self.stream: Stream | None = None
        self.binary = True  # replies (and stream ticks) in the encoding of the last request

    async def send(self, message: dict, binary: bool | None = None) -> None:
        data = encode(message, self.binary if binary is None else binary)
        async with self.lock:
            if isinstance(data, bytes):
                await self.ws.send_bytes(data)
            else:
                await self.ws.send_text(data)

    async def handle(self, frame, binary: bool) -> None:
        self.binary = binary
        req_id = None
        try:
            if self.stream is not None:
                self.stream.heard()
            self.bucket.take()
            msg = decode(frame, self.server.limits)
            req_id = msg.get("id")
            kind = msg["type"]
            self.server.served[kind] += 1
            reply = await OPS[kind](self, msg)
            if reply is None:  # ack: a keep-alive of a streaming client
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

    def streaming(self) -> Stream:
        """This connection's stream; :class:`RequestError` when it has none."""
        if self.stream is None:
            raise RequestError("no stream on this connection; send a 'stream' request first")
        return self.stream

    async def start_stream(self, msg: dict) -> dict:
        if self.stream is not None and not self.stream.done:
            raise RequestError("this connection already streams; send 'respond' to change the motion or 'stop'")
        server = self.server
        req = StreamRequest.parse(msg, server.limits)
        self.stream = Stream(
            server.policy,
            self.send,
            call=server._call,
            limits=server.limits,
            stall_s=req.stall_s,
            sim=req.sim,
            steps=req.steps,
        ).start()
        reply = {"control_hz": CONTROL_HZ, "stall_s": req.stall_s}
        if req.first:
            reply.update(await self.stream.respond(msg))
        return reply

    async def close(self) -> None:
        if self.stream is not None:
            await self.stream.close()


# --- the dispatch table: a request's type -> its handler (a reply's fields; None: no reply) ---------------------


async def _info(conn: _Connection, msg: dict) -> dict:
    return conn.server.info()


async def _ground(conn: _Connection, msg: dict) -> dict:
    return await conn.server.ground(msg)


async def _sample(conn: _Connection, msg: dict) -> dict:
    return await conn.server.sample(msg)


async def _stream(conn: _Connection, msg: dict) -> dict:
    return await conn.start_stream(msg)


async def _respond(conn: _Connection, msg: dict) -> dict:
    return await conn.streaming().respond(msg)


async def _stop(conn: _Connection, msg: dict) -> dict:
    conn.streaming().stop()
    return {"stopping": True}


async def _ack(conn: _Connection, msg: dict) -> None:
    return None  # a keep-alive: the stream has heard from its client (handle), nothing to answer


OPS: dict[str, Callable[[_Connection, dict], Awaitable[dict | None]]] = {
    "info": _info,
    "ground": _ground,
    "sample": _sample,
    "stream": _stream,
    "respond": _respond,
    "stop": _stop,
    "ack": _ack,
}
