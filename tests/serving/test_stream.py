"""The 30 Hz stream (jgrounding/serving/stream.py) on its own, no socket: a send callback collects its
messages and a stub policy plans smooth motions. Glides and holds pass the gate, the seam statistics, a new
response that starts at the command being executed, a stop that glides to rest, the simulated backbone."""

from __future__ import annotations

import asyncio

import numpy as np

from jgrounding import safety
from jgrounding.config import NUM_STEPS, NUM_TENDONS
from jgrounding.serving import stream
from jgrounding.serving.stream import SeamStats, Stream, glide_to_rest, hold

TARGET = np.array([0.6, 0.2, 0.4, 0.1], np.float32)


class Planner:
    """A stub policy: each plan eases from the start command to TARGET over NUM_STEPS steps."""

    num_tendons = NUM_TENDONS
    start_conditioning = True
    model_info = {"checkpoint": "stub"}

    def __init__(self):
        self.calls = []

    def sample(self, key, intent, intensity, num_samples, *, steps, current, start_conditioned):
        self.calls.append((intent, intensity, num_samples, steps, start_conditioned))
        w = 0.5 - 0.5 * np.cos(np.pi * np.linspace(0.0, 1.0, NUM_STEPS))[:, None]
        return (current[None] + w * (TARGET - current)[None]).astype(np.float32)


def test_glide_and_hold_pass_the_gate():
    start = np.array([0.9, 0.0, 0.5, 1.0], np.float32)
    g = glide_to_rest(start)
    assert g.shape == (stream.GLIDE_TICKS + 1, 4) and np.allclose(g[0], start) and np.abs(g[-1]).max() <= 1e-6
    assert safety.is_safe(g[None], current=start)
    h = hold(start)
    assert h.shape == (NUM_STEPS, 4) and np.allclose(h, start)


def test_seam_stats_tell_seams_from_inside_and_count_violations():
    stats = SeamStats()
    for t in range(5):
        stats.add(t, np.full(4, 0.01 * t))
    stats.seam(5)
    stats.add(5, np.full(4, 0.09))  # a step of 0.05 into the seam
    stats.add(6, np.full(4, 0.3))  # too large a step out of it: a violation
    s = stats.summary()
    assert s["max_step_inside"] == 0.01 and s["max_step_seam"] == 0.21 and s["violations"] == 1
    assert s["max_jerk_inside"] == 0.04 and s["max_jerk_seam"] == 0.12  # the window [2, 5] ends at s: inside
    outside = SeamStats()
    outside.add(0, np.array([0.0, 1.5, 0.0, 0.0]))  # out of bounds
    outside.add(1, np.array([0.0, np.nan, 0.0, 0.0]))  # not finite
    assert outside.summary()["violations"] == 2


def test_a_stream_on_a_send_callback():
    sent: list[dict] = []
    policy = Planner()

    async def send(message: dict) -> None:
        sent.append(message)

    async def main():
        s = Stream(policy, send, stall_s=5.0, sim=True, steps=3).start()
        await asyncio.sleep(0.1)
        reply = await s.respond({"intent": "greeting", "intensity": "subtle", "seed": 1})
        while s.tick < reply["starts_at_tick"] + 10:
            await asyncio.sleep(0.02)
        s.stop()
        await asyncio.wait_for(s.task, 10)
        return s, reply

    s, reply = asyncio.run(main())
    assert policy.calls and set(policy.calls) == {("greeting", "subtle", 1, 3, True)}
    assert s.late_plans == len(policy.calls) - 1  # a plan later than its lead is planned again further ahead
    ticks = [m for m in sent if m["type"] == "tick"]
    assert [m["tick"] for m in ticks] == list(range(len(ticks)))
    u = np.asarray([m["u"] for m in ticks])
    first = reply["starts_at_tick"]
    np.testing.assert_allclose(u[first], reply["start"], atol=1e-6)  # the plan starts at the executed command
    assert np.abs(u[:first]).max() == 0 and np.abs(u[first + 5] - u[first]).max() > 0  # at rest, then moving
    assert ticks[-1]["state"] == "rest" and np.abs(u[-1]).max() <= 1e-6  # stop glided to rest
    assert "glide" in {m["state"] for m in ticks} and safety.is_safe(u[None], current=np.zeros(4))
    assert ticks[0]["backbone"].shape == (11, 3) and ticks[0]["backbone"].dtype == np.float32
    end = sent[-1]
    assert end["type"] == "stream_end" and end["stats"]["violations"] == 0 and end["stats"]["responses"] == 1
    assert end["stats"]["ticks"] == len(ticks)


def test_a_closed_stream_sends_nothing_more():
    sent: list[dict] = []

    async def send(message: dict) -> None:
        sent.append(message)

    async def main():
        s = Stream(Planner(), send).start()
        await asyncio.sleep(0.1)
        await s.close()
        n = len(sent)
        await asyncio.sleep(0.1)
        return s, n

    s, n = asyncio.run(main())
    assert s.done and s.closed and len(sent) == n and all(m["type"] == "tick" for m in sent)
