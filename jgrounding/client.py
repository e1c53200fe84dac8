"""Client of the policy server (``python -m jgrounding.serve``): what a lab's robot code imports.

>>> from jgrounding.client import Client
>>> with Client() as c:                                   # ws://127.0.0.1:8765/ws
...     r = c.sample(text="User seems sad; respond calmly")
...     r["grounding"], r["u"].shape                       # the grounding, (150, 4) commands in [0, 1]
...     for tick in c.stream(text="Wave hello"):           # one command per 1/30 s
...         robot.send(tick.u)

Messages are msgpack maps over one WebSocket (docs/serving.md), in the server's own codec
(:mod:`jgrounding.serving.wire`); arrays come back as numpy arrays.
``python -m jgrounding.client "User seems sad; respond calmly"`` prints the grounding and a summary.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import sys
import time

import numpy as np

from jgrounding.serving import wire

DEFAULT_URL = "ws://127.0.0.1:8765/ws"
ACK_EVERY = 10  # ticks between keep-alives of a stream (the server glides to rest after its stall time)


class ServerError(RuntimeError):
    """An error reply of the server: ``code`` (bad_request, too_large, rate_limited, unauthorized, ...)."""

    def __init__(self, code: str, message: str):
        super().__init__(f"{code}: {message}")
        self.code = code


@dataclasses.dataclass(frozen=True)
class Tick:
    """One streamed command: ``u`` (N_u,) in [0, 1] to execute now; ``state``: move, hold, glide, rest."""

    tick: int
    u: np.ndarray
    state: str
    seq: int  # which response the command belongs to (0: none yet)
    backbone: np.ndarray | None = None  # (11, 3) simulated trunk, when streamed with sim=True
    received: float = 0.0  # time.perf_counter() at arrival


class Client:
    """A connection to the server. ``token``: the server's secret, when it has one."""

    def __init__(self, url: str = DEFAULT_URL, token: str | None = None, timeout: float = 60.0):
        from websockets.sync.client import connect

        headers = {"Authorization": f"Bearer {token}"} if token else None
        self.timeout = timeout
        self._connection = connect(url, additional_headers=headers, max_size=64 << 20, open_timeout=timeout)
        self.ws = self._connection.__enter__()  # websockets 17: connect() is a context manager
        self._ids = itertools.count(1)
        self.events: list[dict] = []  # non-tick messages that arrived while streaming

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        self.ws.close()

    def send(self, message: dict) -> int:
        """Send one request (a map with ``type``); returns its ``id``."""
        message = dict(message)
        message.setdefault("id", next(self._ids))
        try:
            self.ws.send(wire.encode_request(message))
        except Exception as e:
            self._closed(e)
        return message["id"]

    @staticmethod
    def _closed(e: Exception):
        from websockets.exceptions import ConnectionClosed

        if not isinstance(e, ConnectionClosed):
            raise e
        if e.rcvd is not None and e.rcvd.code == 1008:  # the server refused the connection
            raise ServerError("unauthorized", e.rcvd.reason) from None
        raise ConnectionError(f"the server closed the connection ({e})") from None

    def receive(self, timeout: float | None = None) -> dict:
        try:
            frame = self.ws.recv(timeout=self.timeout if timeout is None else timeout)
        except Exception as e:
            self._closed(e)
        return wire.decode_reply(frame)  # JSON: the server answers an unauthorized connection so, then closes

    def request(self, message: dict) -> dict:
        """Send a request and return its reply (ticks of a running stream are kept aside); raises
        :class:`ServerError` for an error reply."""
        rid = self.send(message)
        while True:
            reply = self.receive()
            if reply.get("type") == "error" and reply.get("id") in (rid, None):
                raise ServerError(reply.get("code", "error"), reply.get("error", ""))
            if reply.get("id") == rid:
                return reply
            self.events.append(reply)

    def info(self) -> dict:
        return self.request({"type": "info"})

    def ground(self, text: str) -> dict:
        """The grounding of a response text: ``{"intent", "intensity", "confidence", "confident", ...}``."""
        return self.request({"type": "ground", "text": text})["grounding"]

    def sample(self, text: str | None = None, *, intent=None, intensity="moderate", **options) -> dict:
        """Trajectories for a text (grounded by the server) or a tuple. ``options``: ``num_samples``,
        ``steps``, ``current`` ("rest", None or N_u numbers), ``start_conditioned``, ``seed``, ``force``,
        ``rollout`` (backbone of the simulated trunk). Returns the reply: ``u`` (numpy, shaped as
        ``jg.sample`` returns it), ``grounding``, ``hold_still``, ``model``, ``seed``."""
        msg = {"type": "sample", **options}
        if text is not None:
            msg["text"] = text
        else:
            msg.update(intent=intent, intensity=intensity)
        return self.request(msg)

    def stream(self, text: str | None = None, *, intent=None, intensity="moderate", **options) -> Stream:
        """Start the 30 Hz stream (optionally with a first response); iterate over it for :class:`Tick` s.
        ``options``: ``sim`` (stream the simulated backbone too), ``stall_s``, ``steps``, ``seed``, ``force``."""
        msg = {"type": "stream", **options}
        if text is not None:
            msg["text"] = text
        elif intent is not None:
            msg.update(intent=intent, intensity=intensity)
        reply = self.request(msg)
        return Stream(self, reply)


class Stream:
    """Iterate for ticks; :meth:`respond` to switch to a new response mid-motion; :meth:`stop` to glide to
    rest and get the server's statistics. Sends a keep-alive every :data:`ACK_EVERY` ticks."""

    def __init__(self, client: Client, started: dict):
        self.client, self.started = client, started
        self.responses: list[dict] = [started] if "seq" in started else []
        self.stats: dict | None = None
        self._pending: dict[int, str] = {}
        self._count = 0
        # Ticks that arrived while the stream request was being answered come first.
        self._backlog = [m for m in client.events if m.get("type") == "tick"]
        client.events[:] = [m for m in client.events if m.get("type") != "tick"]

    def respond(self, text: str | None = None, *, intent=None, intensity="moderate", **options) -> int:
        """Ask for a new response without waiting (the stream keeps ticking); its reply lands in
        :attr:`responses`. Returns the request id."""
        msg = {"type": "respond", **options}
        if text is not None:
            msg["text"] = text
        else:
            msg.update(intent=intent, intensity=intensity)
        rid = self.client.send(msg)
        self._pending[rid] = "respond"
        return rid

    def _other(self, msg: dict) -> None:
        if msg.get("type") == "error":
            self._pending.pop(msg.get("id"), None)
            raise ServerError(msg.get("code", "error"), msg.get("error", ""))
        if msg.get("type") == "respond":
            self._pending.pop(msg.get("id"), None)
            self.responses.append(msg)
        elif msg.get("type") == "stream_end":
            self.stats = msg["stats"]
        else:
            self.client.events.append(msg)

    def __iter__(self):
        while self.stats is None:
            msg = self._backlog.pop(0) if self._backlog else self.client.receive()
            if msg.get("type") != "tick":
                self._other(msg)
                continue
            self._count += 1
            if self._count % ACK_EVERY == 0:
                self.client.send({"type": "ack", "tick": msg["tick"]})
            yield Tick(
                msg["tick"],
                np.asarray(msg["u"], np.float32),
                msg["state"],
                msg["seq"],
                None if msg.get("backbone") is None else np.asarray(msg["backbone"]),
                time.perf_counter(),
            )

    def stop(self) -> dict:
        """Glide to rest, drain the remaining ticks and return the server's stream statistics."""
        self.client.send({"type": "stop"})
        for _ in self:
            pass
        return self.stats


def shown(reply: dict) -> str:
    """What a text's reply says first: "holding still: <reason>; ..." with the tuple after it in small print
    ("nearest: ...") for a held text, else the grounded tuple and its confidence."""
    g = reply["grounding"]
    if reply.get("hold_still"):
        return f"{reply['message']}\n  ({g.get('nearest') or 'nearest: ' + g['intent'] + ', ' + g['intensity']})"
    return f"grounding: ({g['intent']}, {g['intensity']})  confidence {g['confidence']:.2f}  acting on it"


def summarize(u: np.ndarray) -> str:
    """A few lines on a ``(T, N_u)`` trajectory: duration, range and the busiest tendon."""
    u = np.asarray(u).reshape(-1, *np.shape(u)[-2:])[0]
    steps, n = u.shape
    span = u.max(0) - u.min(0)
    lines = [
        f"trajectory: {steps} steps x {n} tendons ({steps / 30:.1f} s at 30 Hz), commands in "
        f"[{u.min():.3f}, {u.max():.3f}]",
        f"  start {np.round(u[0], 3).tolist()}  end {np.round(u[-1], 3).tolist()}",
        f"  largest step {np.abs(np.diff(u, axis=0)).max():.4f} (slew bound 0.1); most motion on tendon "
        f"{int(span.argmax())} (range {span.max():.3f})",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m jgrounding.client", description="Ask a running jgrounding server for a response's motion."
    )
    p.add_argument("text", help="the robot's response, e.g. 'User seems sad; respond calmly'")
    p.add_argument("--url", default=DEFAULT_URL, help="server WebSocket (default %(default)s)")
    p.add_argument("--token", default=None, help="the server's token, if it has one")
    p.add_argument("--samples", type=int, default=1, help="trajectories to ask for (default 1)")
    p.add_argument("--steps", type=int, default=50, help="sampler steps (default 50)")
    p.add_argument("--stream", type=float, default=0.0, metavar="SECONDS", help="also stream it live this long")
    args = p.parse_args(argv)
    try:
        with Client(args.url, args.token) as c:
            t0 = time.perf_counter()
            r = c.sample(args.text, num_samples=args.samples, steps=args.steps)
            ms = 1e3 * (time.perf_counter() - t0)
            m = r["model"]
            print(shown(r))
            print(
                f"model: {m['checkpoint']} ({m['method']}), library {m['library_version']}, "
                f"jgrounding {m['package_version']}  [{ms:.1f} ms round trip]"
            )
            print(summarize(r["u"]))
            if args.stream > 0:
                s = c.stream(args.text)
                n = int(args.stream * 30)
                for i, tick in enumerate(s):
                    if i + 1 >= n:
                        break
                stats = s.stop()
                print(
                    f"stream: {stats['ticks']} ticks, {stats['missed_ticks']} missed, {stats['violations']} violations"
                )
    except ServerError as e:
        print(f"error from server: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(
            f"error: cannot reach the server at {args.url} ({e}); start it with python -m jgrounding.serve",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
