"""The study server: the operator's and the participant's pages, their JSON API, and the study's own live
command stream, on the policy server of :mod:`jgrounding.serving` (its page, ``/api/info`` and ``/ws`` stay
where they are when the design needs the model).

One :class:`jgrounding.serving.Stream` runs at 30 Hz for the whole session; ``/study/ws`` subscribers (the
operator's page, a robot's bridge) receive its ticks, JSON to a text-frame subscriber and msgpack to a binary
one (:mod:`jgrounding.serving.wire`), and keep it alive (a stream nobody acknowledges glides to rest). Playing
an episode plans one trajectory from the command the stream will be executing, as the stream's own
``respond`` does, by its block's condition: held still (``av_only``), sampled start-conditioned with the
episode's seed (``trunk``: :func:`jgrounding.sample`), or a library demonstration blended in through the
safety gate (``scripted``). The sha256 of the planned float32 trajectory is committed before its first
command goes out, and the sha256 of the commands the stream then executed when its last one has: an episode
counts as played only when the two agree.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import dataclasses
import datetime as dt
import hashlib
import hmac
import json
import math
import time
import types

import numpy as np

from jgrounding.config import NUM_TENDONS, SampleConfig
from jgrounding.io import package_file
from jgrounding.serving import CONTROL_HZ, Limits, Stream, encode, hold, scene
from jgrounding.serving.stream import LEAD_TICKS, MAX_LEAD_TICKS, PLAN_TRIES
from jgrounding.study.design import Design
from jgrounding.study.store import Store, StudyError

STATIC = package_file("study", "static")


def episode_seed(design_seed: int, number: int, position: int, episode: int) -> int:
    """The seed of participant ``number``'s ``episode`` in block ``position`` (31 bits, as the server's)."""
    return int(np.random.SeedSequence([design_seed, number, position, episode]).generate_state(1)[0] & 0x7FFFFFFF)


def trajectory_sha256(u: np.ndarray) -> str:
    """sha256 of a trajectory's float32 bytes in C order (what ``executions.planned_sha256`` records)."""
    return hashlib.sha256(np.ascontiguousarray(u, np.float32).tobytes()).hexdigest()


def to_json(obj) -> str:
    """JSON of an API reply: arrays as lists (6 decimals), numpy scalars as numbers, timestamps in ISO 8601 UTC."""

    def default(v):
        if isinstance(v, np.ndarray):
            return np.round(v.astype(np.float64), 6).tolist()
        if isinstance(v, np.generic):
            return v.item()
        if isinstance(v, dt.datetime):
            return v.isoformat() + "Z"
        raise TypeError(f"cannot encode {type(v).__name__}")

    return json.dumps(obj, default=default, allow_nan=False)


@dataclasses.dataclass
class _Watch:
    """An episode being executed: its first tick, its length, the hash of what the stream sent so far."""

    start: int
    length: int
    execution: asyncio.Future
    hasher: object = dataclasses.field(default_factory=hashlib.sha256)
    count: int = 0


class StudyServer:
    """The study's app around a :class:`Design`, a :class:`Store` and (when the design needs it) a
    :class:`jgrounding.serving.Policy`; :meth:`app` is served by uvicorn (:func:`jgrounding.study.serve`,
    :class:`jgrounding.serving.Running`)."""

    def __init__(self, design: Design, store: Store, policy=None, token: str | None = None, library=None):
        if design.needs_model and policy is None:
            raise ValueError("this design has a trunk condition or a text to ground: give it the policy")
        self.design, self.store, self.policy, self.token = design, store, policy, token
        self.session_id = store.open_session(design)
        self.library = library
        self.pool = concurrent.futures.ThreadPoolExecutor(max_workers=2, thread_name_prefix="jg-study")
        self.stream: Stream | None = None
        self.subscribers: dict = {}  # websocket -> binary
        self.watch: _Watch | None = None
        self.play_lock = asyncio.Lock()
        self.model_s = 0.0
        self.num_tendons = policy.num_tendons if policy is not None else NUM_TENDONS

    async def _call(self, fn, *args, **kwargs):
        return await asyncio.get_running_loop().run_in_executor(self.pool, lambda: fn(*args, **kwargs))

    # -- the stream --

    def ensure_stream(self) -> Stream:
        if self.stream is None or self.stream.done:
            policy = self.policy or types.SimpleNamespace(num_tendons=self.num_tendons, start_conditioning=True)
            self.stream = Stream(policy, self.broadcast, stall_s=self.design.stall_s, sim=self.design.sim).start()
        return self.stream

    async def broadcast(self, msg: dict) -> None:
        """The stream's ``send``: hash the commands of the episode being executed, then fan the tick out."""
        w = self.watch
        if w is not None and msg.get("type") == "tick" and msg["tick"] >= w.start:
            w.hasher.update(np.ascontiguousarray(msg["u"], np.float32).tobytes())
            w.count += 1
            if w.count == w.length:
                self.watch = None
                asyncio.ensure_future(self._completed(w))
        for ws, binary in list(self.subscribers.items()):
            try:
                data = encode(msg, binary)
                await (ws.send_bytes(data) if binary else ws.send_text(data))
            except Exception:  # noqa: BLE001 (a subscriber that went away is dropped)
                self.subscribers.pop(ws, None)

    async def _completed(self, w: _Watch) -> None:
        execution = await w.execution
        await self._call(self.store.complete_execution, execution, w.hasher.hexdigest())

    def stream_state(self) -> dict:
        s = self.stream
        playing = None if self.watch is None else {"done": self.watch.count, "of": self.watch.length}
        if s is None:
            return {"running": False, "playing": playing}
        return {"running": not s.done, "tick": s.tick, "state": s.state, "playing": playing}

    # -- planning an episode --

    def plan(self, condition: str, seed: int, intent, intensity, start: np.ndarray, still: bool):
        """``(trajectory (T, N_u), source, realization)`` for one episode starting at command ``start``."""
        if condition == "av_only" or still:
            return hold(start), "hold", None
        if condition == "trunk":
            import jax

            steps = self.design.steps or SampleConfig.steps
            u = self.policy.sample(
                jax.random.key(seed),
                intent,
                intensity,
                1,
                steps=steps,
                current=start,
                start_conditioned=self.policy.start_conditioning,
            )
            return np.asarray(u, np.float32), "model", None
        from jgrounding import safety
        from jgrounding.vocabulary import intensity_index, intent_index

        lib = self.library_split()
        idx = np.flatnonzero((lib.intent == intent_index(intent)) & (lib.intensity == intensity_index(intensity)))
        if not len(idx):
            raise StudyError(f"the library has no training realization of ({intent}, {intensity})")
        pick = idx[seed % len(idx)]
        u = safety.emit(lib.u[pick], num_channels=self.num_tendons, current=start)
        return u, "library", int(lib.realization[pick])

    def library_split(self):
        if self.library is None:
            from jgrounding.library import load_library

            self.library = load_library()
        return getattr(self.library, "train", self.library)

    async def play(self, pid: str) -> dict:
        """Play participant ``pid``'s next episode on the stream; what was planned and when it starts."""
        async with self.play_lock:
            prog = await self._call(self.store.progress, pid)
            if prog["phase"] != "episode":
                raise StudyError(f"participant {pid} has no episode to play now ({prog['phase']})")
            if self.watch is not None:
                raise StudyError("the previous episode is still playing; wait until it has finished")
            p = await self._call(self.store.participant, pid)
            pos, cond, e = prog["position"], prog["condition"], prog["episode"]
            episode = self.design.episodes[e]
            seed = episode_seed(self.design.seed, p["number"], pos, e)
            intent, intensity, confidence, still = episode.intent, episode.intensity, None, False
            if episode.text is not None and cond != "av_only":
                decision = await self._call(self.policy.decide, episode.text)
                intent, intensity, still = decision.intent, decision.intensity, decision.hold
                confidence = float(decision.grounding.confidence)
            stream = self.ensure_stream()
            for _ in range(PLAN_TRIES):
                lead = min(MAX_LEAD_TICKS, max(LEAD_TICKS, math.ceil(1.5 * self.model_s * CONTROL_HZ) + 1))
                s = stream.tick + lead
                start = stream.command_at(s).copy()
                t0 = time.perf_counter()
                u, source, realization = await self._call(self.plan, cond, seed, intent, intensity, start, still)
                self.model_s = max(0.8 * self.model_s, time.perf_counter() - t0)
                if stream.tick < s:
                    break
            else:
                raise StudyError("the model did not answer in time to join the stream; play the episode again")
            execution = asyncio.get_running_loop().create_future()
            self.watch = _Watch(s, len(u), execution)  # no await between these two: no tick is missed
            stream.replace_plan(s, u, "hold" if source == "hold" else "move")
            fields = dict(
                intent=intent,
                intensity=intensity,
                confidence=confidence,
                source=source,
                realization=realization,
                seed=seed,
                num_steps=len(u),
                start_tick=s,
                planned_sha256=trajectory_sha256(u),
            )
            try:
                eid = await self._call(self.store.record_execution, pid, pos, cond, e, **fields)
            except Exception as err:
                execution.set_exception(err)
                raise
            execution.set_result(eid)
            return {"execution": eid, "position": pos, "condition": cond, "episode": e, "say": episode.say,
                    "u": u, **fields}  # fmt: skip

    # -- what the pages see --

    def design_info(self) -> dict:
        d = self.design
        return {
            "name": d.name,
            "session": self.session_id,
            "conditions": list(d.conditions),
            "episodes": [dataclasses.asdict(e) for e in d.episodes],
            "questions": [dataclasses.asdict(q) for q in d.questions],
            "labels": list(d.labels),
            "sim": d.sim,
            "scene": scene(),
            "control_hz": CONTROL_HZ,
        }

    def participant_view(self, pid: str) -> dict:
        """What the participant's page may know: the phase and the questions, never the condition's name."""
        prog = self.store.progress(pid)
        view = {k: prog[k] for k in ("participant", "phase", "blocks") if k in prog}
        if "position" in prog:
            view["position"] = prog["position"]
        if prog["phase"] == "questionnaire":
            missing = set(prog["missing"])
            view["questions"] = [dataclasses.asdict(q) for q in self.design.questions]
            view["answered"] = [q.dimension for q in self.design.questions if q.dimension not in missing]
            view["labels"] = list(self.design.labels)
        return view

    def authorized(self, conn) -> bool:
        if self.token is None:
            return True
        given = conn.query_params.get("token") or ""
        header = conn.headers.get("authorization", "")
        if header.lower().startswith("bearer "):
            given = header[7:]
        return hmac.compare_digest(given.encode(), self.token.encode())

    async def subscribe(self, ws) -> None:
        """``/study/ws``: the stream's ticks; every message heard keeps the stream alive."""
        from jgrounding.serving import Server

        await ws.accept()
        if not self.authorized(ws) or not Server.same_origin(ws):
            await ws.close(code=1008, reason="unauthorized or cross-origin")
            return
        stream = self.ensure_stream()
        try:
            while True:
                event = await ws.receive()
                if event["type"] == "websocket.disconnect":
                    break
                self.subscribers[ws] = event.get("bytes") is not None
                stream.heard()
        finally:
            self.subscribers.pop(ws, None)

    def app(self):
        from starlette.applications import Starlette
        from starlette.responses import FileResponse, JSONResponse, RedirectResponse, Response
        from starlette.routing import Mount, Route, WebSocketRoute

        def page(name):
            async def serve_page(request):
                return FileResponse(STATIC / name, headers={"Cache-Control": "no-store"})

            return serve_page

        def api(fn, method="GET"):
            async def endpoint(request):
                if not self.authorized(request):
                    return JSONResponse({"error": "unauthorized: this server needs its token"}, status_code=401)
                try:
                    body = await request.json() if method == "POST" else {}
                    if not isinstance(body, dict):
                        raise StudyError("the request body must be a JSON object")
                    result = await fn(request, body)
                except (StudyError, KeyError, TypeError, ValueError) as e:
                    return JSONResponse({"ok": False, "error": str(e)}, status_code=400)
                return Response(to_json({"ok": True, **result}), media_type="application/json")

            return Route(f"/study/api/{fn.__name__}", endpoint, methods=[method])

        async def design(request, body):
            return self.design_info()

        async def participants(request, body):
            return {"participants": await self._call(self.store.participants, self.session_id)}

        async def enrol(request, body):
            return await self._call(self.store.enrol, self.session_id)

        async def participant(request, body):
            pid = request.query_params["p"]
            return {
                **await self._call(self.store.participant, pid),
                "progress": await self._call(self.store.progress, pid),
            }

        async def state(request, body):
            return await self._call(self.participant_view, request.query_params["p"])

        async def play(request, body):
            return await self.play(str(body["participant"]))

        async def rate(request, body):
            pid, pos, dim, value = str(body["participant"]), body["position"], str(body["dimension"]), body["value"]
            if isinstance(pos, bool) or not isinstance(pos, int):
                raise StudyError(f"position must be an integer, got {pos!r}")
            return await self._call(self.store.add_rating, pid, pos, dim, value)

        async def withdraw(request, body):
            await self._call(self.store.set_status, str(body["participant"]), "withdrawn")
            return {"withdrawn": body["participant"]}

        async def stream(request, body):
            return self.stream_state()

        routes = [
            Route("/study", lambda r: RedirectResponse("/study/operator" + (f"?{r.url.query}" if r.url.query else ""))),
            Route("/study/operator", page("operator.html")),
            Route("/study/participant", page("participant.html")),
            Route("/study/study.js", page("study.js")),
            api(design),
            api(participants),
            api(enrol, "POST"),
            api(participant),
            api(state),
            api(play, "POST"),
            api(rate, "POST"),
            api(withdraw, "POST"),
            api(stream),
            WebSocketRoute("/study/ws", self.subscribe),
        ]
        if self.policy is not None:  # the policy server's page, /api/info and /ws, unchanged
            from jgrounding.serving import Server

            routes.append(Mount("/", app=Server(self.policy, Limits(), self.token).app()))
        return Starlette(routes=routes)
