"""The live 30 Hz command stream: the plan it executes, the tick scheduler, glides to rest and holds, and the
statistics of every streamed command (:class:`SeamStats`).

A :class:`Stream` knows nothing of sockets: it hands each message to a ``send`` callback (the server's
connection) and runs the model through a ``call`` callback (the server's worker threads); ``sim=True`` steps
the built-in trunk (:mod:`jgrounding.sim`) one command at a time and streams its backbone. Holds and glides
pass :func:`jgrounding.safety.emit`, trajectories come from the policy (:func:`jgrounding.sample`, the gate),
and every command is checked against the bounds and the slew limit.
"""

from __future__ import annotations

import asyncio
import collections
import math
import time
from collections.abc import Awaitable, Callable
from typing import Any

import numpy as np

from jgrounding import safety
from jgrounding.config import NUM_STEPS, NUM_TENDONS, SampleConfig
from jgrounding.serving.protocol import Limits, RequestError, RespondRequest, resolve

CONTROL_HZ = 30  # NUM_STEPS steps over 5 s: one command per control step of the simulation (1/30 s)
LEAD_TICKS = 2  # a new response starts this many ticks after it is ready to be planned (66 ms at 30 Hz)
MAX_LEAD_TICKS = 2 * CONTROL_HZ  # however slow the model has been, a response is planned at most 2 s ahead
PLAN_TRIES = 4  # a plan that comes too late is planned again from a later tick, this many times in all
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


class SimulatedTrunk:
    """The built-in trunk of :mod:`jgrounding.sim`, stepped one control step (``SUBSTEPS`` physics steps) per
    streamed command; :meth:`step` returns its backbone ``(NUM_POINTS, 3)``."""

    def __init__(self, trunk: str | None = None):
        import mujoco

        from jgrounding import sim

        self.model = sim.load_model(trunk)
        self.data = mujoco.MjData(self.model)
        self._mj_step, self.substeps, self.points = mujoco.mj_step, sim.SUBSTEPS, sim.NUM_POINTS

    def step(self, u: np.ndarray) -> np.ndarray:
        self.data.ctrl[:] = u
        for _ in range(self.substeps):
            self._mj_step(self.model, self.data)
        return self.data.sensordata[: 3 * self.points].reshape(self.points, 3).astype(np.float32)


async def _in_thread(fn, *args, **kwargs):
    return await asyncio.to_thread(fn, *args, **kwargs)


class Stream:
    """A 30 Hz command stream of one client.

    The stream executes a *plan*: commands from tick ``plan_start`` on (the last one held after the plan
    ends). A new response at tick ``i`` is planned from the command the stream will execute at
    ``s = i + LEAD_TICKS``: the trajectory is sampled start-conditioned on it, so its first command is
    exactly that one, and replaces the plan from ``s`` on (re-planned from a later tick if the model was
    late). A client silent for ``stall_s`` (no message, not even ``ack``) gets a glide to rest; a
    non-confident grounding holds the command being executed; ``stop`` glides to rest and ends.

    ``policy``: the server's :class:`jgrounding.serving.app.Policy` (``decide``, ``sample``, ``num_tendons``,
    ``start_conditioning``, ``model_info``); ``send``: an async callback that delivers one message to the client;
    ``call``: an async ``call(fn, *args, **kwargs)`` that runs the model off the event loop (default: a thread).
    """

    def __init__(
        self,
        policy,
        send: Callable[[dict], Awaitable[None]],
        *,
        call: Callable[..., Awaitable[Any]] = _in_thread,
        limits: Limits = Limits(),
        stall_s: float | None = None,
        sim: bool = False,
        steps: int = SampleConfig.steps,
    ):
        self.policy, self.send, self.call, self.limits = policy, send, call, limits
        n = self.policy.num_tendons
        self.tick = 0
        self.plan_start, self.plan = 0, np.zeros((1, n), np.float32)
        self.queued: tuple | None = None  # (start tick, plan, state) waiting for its tick
        self.state = "rest"
        self.seq = 0
        self.stall_s, self.steps = limits.stall_s if stall_s is None else stall_s, steps
        self.last_heard = time.monotonic()
        self.stats = SeamStats()
        self.lateness: collections.deque = collections.deque(maxlen=20000)
        self.missed = 0
        self.late_plans = 0
        self.model_s = 0.0  # how long the model took to plan lately (sets how far ahead a response is planned)
        self.responses = 0
        self.stopping = self.done = self.closed = False
        self.task: asyncio.Task | None = None
        trunk = getattr(self.policy, "trunk", None)
        self.sim = SimulatedTrunk(trunk) if sim and n == NUM_TENDONS else None  # the built-in trunk only

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
        req = RespondRequest.parse(msg, self.limits)
        decision, grounding, intent, intensity = await resolve(req, self.policy, self.call)
        self.seq += 1
        seq = self.seq
        t_request = time.perf_counter()
        for _ in range(PLAN_TRIES):
            lead = min(MAX_LEAD_TICKS, max(LEAD_TICKS, math.ceil(1.5 * self.model_s * CONTROL_HZ) + 1))
            s = self.tick + lead
            start = self.command_at(s).copy()
            if decision is not None and decision.hold:
                plan, state = hold(start), "hold"
            else:
                t_model = time.perf_counter()
                plan = await self.call(
                    self.policy.sample,
                    jax.random.key(req.seed),
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
                    "hold_still": state == "hold",
                    "message": decision.message(start) if state == "hold" else None,
                    "seq": seq,
                    "grounding": grounding,
                    "starts_at_tick": s,
                    "start": start,
                    "seed": req.seed,
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
                    msg["backbone"] = self.sim.step(u)
                await self.send(msg)
                if self.stopping and self.queued is None and i >= len(self.plan) - 1:
                    break
                self.tick += 1
            self.done = True
            if not self.closed:
                await self.send({"type": "stream_end", "ok": True, "stats": self.summary()})
        finally:
            self.done = True

    def start(self) -> Stream:
        """Start ticking (on the running event loop)."""
        self.task = asyncio.create_task(self.run())
        return self

    async def close(self) -> None:
        """End the stream now (its client is gone): no more messages, the tick task cancelled."""
        self.closed = True
        if self.task is not None:
            self.task.cancel()
            try:
                await self.task
            except (asyncio.CancelledError, Exception):  # noqa: BLE001
                pass

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
