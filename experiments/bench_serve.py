"""`python -m experiments.bench serve`: the policy server measured over its socket, on localhost only.

Starts ``python -m jgrounding.serve`` in its own process on a free loopback port and, as its clients:
1. round-trip latency of a single sample (first call apart, then warm p50/p99);
2. 8 concurrent clients x 200 requests (p50/p99, errors);
3. a 30 Hz stream held for 60 s while responses arrive every 2 s (tick jitter, missed ticks, bound/slew
   violations, seam steps and jerk beside the in-trajectory ones);
4. a client killed mid-stream while another streams; malformed, oversized, wrongly typed messages and
   random bytes (every one answered with an error, the server still serving);
5. the start-conditioned quality check: share of samples within RMS r of a realization of their tuple,
   from rest and start-conditioned mid-motion (the benchmark's Prec@r: :func:`prec_r`, :func:`start_quality`).
Writes results/bench_serve.md. The test suite runs the same functions for shorter (tests/serving).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "bench_serve.md"
TEXTS = (
    "Wave hello to our new visitor!",
    "User seems sad; respond calmly",
    "That is wonderful news, let's celebrate!",
    "I am listening, tell me more.",
    "Please step back, that is not allowed.",
    "Look over there, at the door.",
)


def percentiles(x_ms) -> dict:
    x = np.asarray(x_ms, np.float64)
    return {"p50": float(np.percentile(x, 50)), "p99": float(np.percentile(x, 99)), "max": float(x.max()), "n": len(x)}


# --- latency and load ------------------------------------------------------------------------------------


def single_latency(url: str, n: int = 1000) -> dict:
    """Round trip of one single-trajectory sample request (msgpack over the WebSocket), on a fresh
    connection: the first call apart, then ``n`` warm calls cycling through tuples."""
    from jgrounding.client import Client

    with Client(url) as c:
        t0 = time.perf_counter()
        c.sample(intent="greeting", intensity="moderate", seed=0)
        first = 1e3 * (time.perf_counter() - t0)
        times = []
        for i in range(n):
            t0 = time.perf_counter()
            c.sample(intent=i % 16, intensity=(i // 16) % 4, seed=i)
            times.append(1e3 * (time.perf_counter() - t0))
    return {"first_ms": first, **percentiles(times)}


def load(url: str, clients: int = 8, requests: int = 200) -> dict:
    """``clients`` connections at once, each sending ``requests`` sample requests back to back."""
    from jgrounding.client import Client

    times, errors = [], []
    barrier = threading.Barrier(clients)

    def worker(w: int) -> None:
        try:
            with Client(url) as c:
                barrier.wait(timeout=60)
                for i in range(requests):
                    t0 = time.perf_counter()
                    try:
                        r = c.sample(intent=(w + i) % 16, intensity=i % 4, seed=i)
                        assert r["u"].shape == (150, 4)
                    except Exception as e:  # noqa: BLE001 (counted)
                        errors.append(repr(e))
                    times.append(1e3 * (time.perf_counter() - t0))
        except Exception as e:  # noqa: BLE001
            errors.append(repr(e))

    t0 = time.perf_counter()
    threads = [threading.Thread(target=worker, args=(w,)) for w in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=600)
    wall = time.perf_counter() - t0
    return {
        "clients": clients,
        "requests": clients * requests,
        "errors": len(errors),
        "first_errors": errors[:3],
        "seconds": wall,
        "throughput": clients * requests / wall,
        **percentiles(times),
    }


# --- the stream ---------------------------------------------------------------------------------------


def stream_soak(url: str, seconds: float = 60.0, every: float = 2.0, seed: int = 0) -> dict:
    """Hold a 30 Hz stream for ``seconds`` while a new response arrives every ``every`` seconds; checks
    every received command against the bounds and the slew limit and every seam for continuity."""
    from jgrounding import safety
    from jgrounding.client import Client

    with Client(url) as c:
        s = c.stream(TEXTS[0], seed=seed)
        ticks, arrivals, cmds = [], [], []
        next_response, k = time.perf_counter() + every, 1
        end = time.perf_counter() + seconds
        for tick in s:
            ticks.append(tick.tick)
            arrivals.append(tick.received)
            cmds.append(tick.u)
            if tick.received >= next_response:
                s.respond(TEXTS[k % len(TEXTS)], seed=seed + k)
                k += 1
                next_response += every
            if tick.received >= end:
                break
        server = s.stop()
    u = np.asarray(cmds, np.float64)
    ticks = np.asarray(ticks)
    gaps = int(np.sum(np.diff(ticks) - 1))
    dt = np.diff(np.asarray(arrivals)) * 1e3
    jitter = np.abs(dt - 1e3 / 30)
    steps = np.abs(np.diff(u, axis=0)).max(-1)  # step into tick i + 1
    out_of_bounds = int(np.sum((u < -1e-6) | (u > 1 + 1e-6)))
    slew = int(np.sum(steps > safety.MAX_SLEW + 1e-6))
    seam_steps, seam_mismatch, seam_ticks = [], 0.0, []
    for r in s.responses:
        i = int(np.searchsorted(ticks, r["starts_at_tick"]))
        if 0 < i < len(ticks) - 1 and ticks[i] == r["starts_at_tick"]:
            seam_ticks.append(i)
            seam_mismatch = max(seam_mismatch, float(np.abs(u[i] - np.asarray(r["start"])).max()))
            seam_steps.append(max(steps[i - 1], steps[i]))
    inside = np.ones(len(steps), bool)
    for i in seam_ticks:
        inside[max(i - 1, 0) : i + 1] = False
    return {
        "seconds": seconds,
        "ticks": len(ticks),
        "responses": len(s.responses),
        "missed_ticks_client": gaps,
        "missed_ticks_server": server["missed_ticks"],
        "jitter_ms": percentiles(jitter),
        "interval_ms": percentiles(dt),
        "violations_client": out_of_bounds + slew,
        "violations_server": server["violations"],
        "seam_start_mismatch": seam_mismatch,
        "max_step_seam": max(seam_steps) if seam_steps else 0.0,
        "max_step_inside": float(steps[inside].max()),
        "server": server,
    }


def killed_client(url: str, seconds: float = 3.0) -> dict:
    """A streaming client process killed (SIGKILL) mid-stream while this one streams on."""
    from jgrounding.client import Client

    code = (
        "import sys; from jgrounding.client import Client\n"
        "c = Client(sys.argv[1]); s = c.stream('Wave hello to our new visitor!')\n"
        "for i, t in enumerate(s):\n"
        "    print(t.tick, flush=True)\n"
    )
    victim = subprocess.Popen([sys.executable, "-c", code, url], stdout=subprocess.PIPE, text=True)
    # Wait until the victim streams before this client starts: a fresh process on a loaded machine can take
    # longer to import than the whole window, which left no ticks after the kill to count.
    victim.stdout.readline()
    with Client(url) as c:
        s = c.stream(TEXTS[1])
        received, killed_at = 0, None
        t0 = time.perf_counter()
        for tick in s:
            received += 1
            if killed_at is None and time.perf_counter() - t0 > seconds / 3:
                victim.kill()
                victim.wait(timeout=10)
                killed_at = received
            if time.perf_counter() - t0 > seconds:
                break
        stats = s.stop()
        after = c.sample(intent="nodding", seed=1)["u"].shape
    return {
        "ticks_after_kill": received - (killed_at or 0),
        "missed_ticks": stats["missed_ticks"],
        "violations": stats["violations"],
        "served_after": after == (150, 4),
    }


def fuzz(url: str, n: int = 200, seed: int = 0) -> dict:
    """Malformed, oversized, wrongly typed messages and random bytes on one connection: each must get an
    error reply and the connection must still answer a valid request afterwards."""
    import msgpack
    from websockets.sync.client import connect

    rng = random.Random(seed)
    typed = [
        {"type": "sample", "intent": "greeting", "num_samples": "many"},
        {"type": "sample", "intent": [1.5]},
        {"type": "sample", "text": ["a"]},
        {"type": "sample", "intent": "greeting", "current": "moving"},
        {"type": "sample", "intent": "greeting", "current": [0.1, 0.2]},
        {"type": "sample", "intent": "greeting", "seed": -1},
        {"type": "ground", "text": None},
        {"type": "stream", "stall_s": "long"},
        {"type": 7},
        {"no": "type"},
        {"type": "sample", "intent": "greeting", "num_samples": 10**9},
        {"type": "sample", "text": "y" * 5000},
    ]
    answered = 0
    with connect(url, max_size=None) as ws:
        for i in range(n):
            kind = i % 4
            if kind == 0:
                frame = rng.randbytes(rng.randint(1, 300))
            elif kind == 1:
                frame = msgpack.packb(typed[i // 4 % len(typed)])
            elif kind == 2:
                frame = "".join(rng.choice('{}[]":,0123456789abc \\') for _ in range(rng.randint(1, 80)))
            else:
                frame = rng.randbytes(rng.randint(65 << 10, 200 << 10))  # oversized
            ws.send(frame)
            raw = ws.recv(timeout=30)
            try:
                reply = msgpack.unpackb(raw) if isinstance(raw, bytes) else json.loads(raw)
            except ValueError:
                reply = {}
            if reply.get("type") == "error" and reply.get("error"):
                answered += 1
            elif reply.get("type") == "stream" and reply.get("ok"):  # a random frame that is valid: stop it
                ws.send(msgpack.packb({"type": "stop"}))
        ws.send(msgpack.packb({"type": "sample", "intent": "greeting", "id": "after"}))
        while True:
            reply = msgpack.unpackb(ws.recv(timeout=30))
            if reply.get("id") == "after":
                break
    return {"sent": n, "error_replies": answered, "served_after": bool(reply.get("ok"))}


# --- start-conditioned quality ---------------------------------------------------------------------------


def prec_r(u: np.ndarray, intents, intensities, from_step: int = 0, ev=None) -> float:
    """The benchmark's Prec@r (:mod:`jgrounding.evaluation.distribution`) of ``u (N, K, 150, N_u)`` against
    the library's evaluation set, over steps ``from_step:`` (r from the same window)."""
    import jgrounding as jg
    from jgrounding.evaluation import distribution

    ev = jg.load_library().evaluation if ev is None else ev
    return distribution.score(u, intents, intensities, ev, with_frechet=False, from_step=from_step).mean("prec_r")


FIRST_KEY = 50  # the first key moment (t = 5/3 s): after it, a motion that started mid-motion is on its way


def start_quality(k: int = 30, seed: int = 0) -> dict:
    """Samples of every library tuple from rest, and start-conditioned (and blended) from a state
    mid-motion: the command at t = 2.5 s of a sample of another tuple. Returns the benchmark's Prec@r of
    each, over the whole trajectory and after the first key moment (``FIRST_KEY``)."""
    import jax

    import jgrounding as jg

    lib = jg.load_library()
    tuples = sorted({(int(m), int(z)) for m, z in zip(lib.train.intent, lib.train.intensity)})
    ms, zs = [m for m, _ in tuples], [z for _, z in tuples]
    key = jax.random.key(seed)
    rest = jg.sample(jax.random.fold_in(key, 0), ms, zs, k)
    cond, blend = [], []
    for i, (m, z) in enumerate(tuples):
        other = jg.sample(jax.random.fold_in(key, 1000 + i), (m + 1 + i % 15) % 16, (z + i) % 4)
        mid = other[75]  # t = 2.5 s
        kk = jax.random.fold_in(key, 2000 + i)
        cond.append(jg.sample(kk, m, z, k, current=mid, start_conditioned=True))
        blend.append(jg.sample(kk, m, z, k, current=mid))
    runs = {"rest": rest, "start_conditioned": np.stack(cond), "blend": np.stack(blend)}
    return {
        "k": k,
        "tuples": len(tuples),
        **{name: prec_r(u, ms, zs, ev=lib.evaluation) for name, u in runs.items()},
        **{f"{name}_after_first_key": prec_r(u, ms, zs, FIRST_KEY, lib.evaluation) for name, u in runs.items()},
    }


# --- the server process ------------------------------------------------------------------------------------


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ServerProcess:
    """``python -m jgrounding.serve`` on a free loopback port, stopped on exit."""

    def __init__(self, *args: str):
        self.port = free_port()
        self.url = f"ws://127.0.0.1:{self.port}/ws"
        env = dict(os.environ, JAX_PLATFORMS=os.environ.get("JAX_PLATFORMS", "cpu"))
        cmd = [sys.executable, "-m", "jgrounding.serve", "--port", str(self.port), "--log-level", "warning", *args]
        self.t0 = time.perf_counter()
        self.proc = subprocess.Popen(
            cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        self.output: list[str] = []
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError("server exited: " + (self.proc.stdout.read() or ""))
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=0.5):
                    break
            except OSError:
                time.sleep(0.2)
        else:
            raise RuntimeError("server did not start within 180 s")
        self.startup_s = time.perf_counter() - self.t0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.proc.terminate()
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def _fmt(d: dict, keys=("p50", "p99", "max")) -> str:
    return " / ".join(f"{d[k]:.3f}" for k in keys)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.bench serve")
    p.add_argument("--seconds", type=float, default=60.0, help="length of the stream soak (default 60)")
    p.add_argument("--single", type=int, default=1000, help="warm single-sample round trips (default 1000)")
    p.add_argument("--no-write", action="store_true", help="print only; do not write results/bench_serve.md")
    args = p.parse_args(argv)
    load_avg = os.getloadavg()[0]
    with ServerProcess() as srv:
        print(f"server started (load + compile + warm-up) in {srv.startup_s:.1f} s on port {srv.port}", flush=True)
        single = single_latency(srv.url, args.single)
        print(
            f"single sample: first {single['first_ms']:.2f} ms; warm p50 {single['p50']:.3f} ms, p99 {single['p99']:.3f} ms"
        )
        loaded = load(srv.url)
        print(f"load 8 x 200: p50 {loaded['p50']:.2f} ms, p99 {loaded['p99']:.2f} ms, errors {loaded['errors']}")
        soak = stream_soak(srv.url, args.seconds)
        print(f"stream {args.seconds:.0f} s: {json.dumps({k: v for k, v in soak.items() if k != 'server'})}")
        killed = killed_client(srv.url)
        print(f"killed client: {killed}")
        fz = fuzz(srv.url)
        print(f"fuzz: {fz}")
    quality = start_quality()
    print(f"start-conditioned quality: {quality}")
    ok = (
        loaded["errors"] == 0
        and soak["missed_ticks_client"] == soak["missed_ticks_server"] == 0
        and soak["violations_client"] == soak["violations_server"] == 0
        and soak["max_step_seam"] <= 0.1 + 1e-6
        and killed["served_after"]
        and fz["error_replies"] == fz["sent"]
    )
    sv = soak["server"]
    lines = [
        "Serving benchmark (`python -m experiments.bench serve`): `python -m jgrounding.serve` in its own process on "
        f"127.0.0.1, clients in another (msgpack over the WebSocket). Load average {load_avg:.2f} at the start on "
        f"{os.cpu_count()} cores. Server start (load, compile, warm-up): {srv.startup_s:.1f} s.",
        "",
        "| what | value | goal |",
        "|---|---|---|",
        f"| single sample round trip, first call on a new connection | {single['first_ms']:.3f} ms | reported apart |",
        f"| single sample round trip, warm p50 / p99 / max ({single['n']} calls) | {_fmt(single)} ms | p50 <= 3 ms, p99 <= 10 ms |",
        f"| 8 clients x 200 requests: p50 / p99 / max | {_fmt(loaded)} ms | 0 errors |",
        f"| 8 clients x 200 requests: errors, throughput | {loaded['errors']}, {loaded['throughput']:.0f} req/s | 0 errors |",
        f"| stream {args.seconds:.0f} s at 30 Hz, response every 2 s: ticks, responses | {soak['ticks']}, {soak['responses']} | |",
        f"| missed ticks (client gaps, server deadlines) | {soak['missed_ticks_client']}, {soak['missed_ticks_server']} | 0 |",
        f"| tick jitter at the client, p50 / p99 / max | {_fmt(soak['jitter_ms'])} ms | |",
        f"| tick lateness at the server, p50 / p99 / max | {_fmt(sv['tick_lateness_ms'])} ms | |",
        f"| bound or slew violations (client check, server check) | {soak['violations_client']}, {soak['violations_server']} | 0 |",
        f"| largest step: across seams / inside trajectories | {soak['max_step_seam']:.4f} / {soak['max_step_inside']:.4f} | seam <= 0.1 (slew bound) |",
        f"| largest jerk (3rd difference): across seams / inside | {sv['max_jerk_seam']:.4f} / {sv['max_jerk_inside']:.4f} | |",
        f"| new response's first command vs the command executed at its tick | {soak['seam_start_mismatch']:.2e} | 0 |",
        f"| client killed mid-stream: other stream's ticks after, missed, violations; served after | "
        f"{killed['ticks_after_kill']}, {killed['missed_ticks']}, {killed['violations']}; {killed['served_after']} | 0 missed |",
        f"| fuzz: bad messages answered with an error / sent; served after | {fz['error_replies']} / {fz['sent']}; {fz['served_after']} | all |",
        f"| Prec@r (the benchmark's), whole trajectory: from rest / start-conditioned from the command at t = 2.5 s of another tuple's sample / blended in from it | {quality['rest']:.3f} / {quality['start_conditioned']:.3f} / {quality['blend']:.3f} | |",
        f"| Prec@r after the first key moment (steps {FIRST_KEY}..149): from rest / start-conditioned / blended | {quality['rest_after_first_key']:.3f} / {quality['start_conditioned_after_first_key']:.3f} / {quality['blend_after_first_key']:.3f} | start-conditioned within 0.03 of rest |",
        "",
        f"All checks {'passed' if ok else 'FAILED'}. Quality: {quality['tuples']} tuples x {quality['k']} samples each "
        "against the library's evaluation set (16 realizations per tuple, never trained on), the benchmark's Prec@r "
        "(jgrounding/evaluation/distribution.py). Every demonstration starts at rest, so a motion that starts "
        "mid-motion is far from all of them during its first key interval whatever the sampler does; after it, "
        "the comparison is fair.",
    ]
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        from jgrounding.io import write_atomic

        write_atomic(OUT, text)
        print(f"wrote {OUT}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
