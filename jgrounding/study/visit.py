"""Simulated participants through a running study server: ``python -m jgrounding.study simulate URL``.

Each simulated participant is enrolled through the server's API, as the operator's page enrols people; every
episode of its blocks is played on the study's live stream (in real time: 150 commands at 30 Hz, 5 s each),
and after each block it answers the questionnaire with ratings drawn from known distributions
(:class:`jgrounding.study.simulate.SimulatedParticipant`: the paper's positive ratios for ``av_only`` and
``trunk``; any other condition is rated at the mean of the two). While it runs, a robot's bridge on
``/study/ws`` acknowledges the stream, so the episodes play as they do with a robot attached. The ratings land
in the server's database like anyone's; ``python -m jgrounding.study analyze DB`` then reads them. It checks
the whole study path (pages' API, stream, hashes, store, analysis) without people.
"""

from __future__ import annotations

import json
import threading
import time
import urllib.error
import urllib.parse
import urllib.request

import numpy as np

from jgrounding.study.design import POSITIVE_FROM
from jgrounding.study.simulate import PAPER_RATIOS, SimulatedParticipant, TrueRatings, likert


def model_for(conditions, dimensions, correlation: float = 0.3, dropout: float = 0.0) -> TrueRatings:
    """What simulated participants answer for a server's conditions and dimensions: the paper's positive
    ratio where it reports one (``av_only``, ``trunk``; its six dimensions), else the condition's mean over
    its dimensions, and for a condition the paper did not run the mean of its two."""
    from jgrounding.study.design import DIMENSIONS

    known = {c: dict(zip(DIMENSIONS, r)) for c, r in PAPER_RATIOS.items()}
    known["other"] = {d: float(np.mean([known[c][d] for c in PAPER_RATIOS])) for d in DIMENSIONS}

    def ratio(c, d):
        table = known.get(c, known["other"])
        return table.get(d, float(np.mean(list(table.values()))))

    probs = np.array([[likert(ratio(c, d)) for d in dimensions] for c in conditions])
    return TrueRatings(tuple(conditions), tuple(dimensions), probs, correlation=correlation, dropout=dropout)


class _Api:
    """JSON calls to ``/study/api/<path>`` of the server at ``base`` (with its token, when it has one)."""

    def __init__(self, base: str, token: str | None = None, timeout: float = 60.0):
        self.base, self.token, self.timeout = base.rstrip("/"), token, timeout

    def __call__(self, path: str, body: dict | None = None) -> dict:
        headers = {"Content-Type": "application/json"}
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(f"{self.base}/study/api/{path}", data=data, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as r:
                reply = json.loads(r.read())
        except urllib.error.HTTPError as e:
            reply = json.loads(e.read() or b"{}")
            raise RuntimeError(f"{path}: the server answered {e.code}: {reply.get('error', reply)}") from None
        except urllib.error.URLError as e:
            raise RuntimeError(f"cannot reach the study server at {self.base} ({e.reason})") from None
        return reply


class _Bridge(threading.Thread):
    """A robot's bridge on ``/study/ws``: reads the stream's ticks and acknowledges every tenth."""

    def __init__(self, base: str, token: str | None):
        super().__init__(daemon=True)
        from websockets.sync.client import connect

        from jgrounding.serving import encode_request

        parts = urllib.parse.urlsplit(base)
        scheme = "wss" if parts.scheme == "https" else "ws"
        query = f"?token={urllib.parse.quote(token)}" if token else ""
        self.ws = connect(f"{scheme}://{parts.netloc}/study/ws{query}")
        self.ack = encode_request({"type": "ack"})
        self.ws.send(self.ack)
        self.stopped = threading.Event()

    def run(self):
        heard = 0
        while not self.stopped.is_set():
            try:
                self.ws.recv(timeout=5)
            except TimeoutError:
                continue
            except Exception:  # noqa: BLE001 (the connection closes when the run ends)
                return
            heard += 1
            if heard % 10 == 0:
                self.ws.send(self.ack)

    def close(self):
        self.stopped.set()
        self.ws.close()


def _next(api: _Api, pid: str, prog: dict, timeout: float) -> dict:
    """Poll participant ``pid``'s progress until it moves on from ``prog`` (the episode just started has been
    executed as planned: its hash is committed after its last command)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        now = api(f"participant?p={pid}")["progress"]
        if now != prog:
            return now
        time.sleep(0.1)
    raise RuntimeError(
        f"participant {pid}: the episode of block {prog['position'] + 1} did not finish within {timeout:.0f} s"
    )


def run(
    base: str,
    participants: int = 4,
    seed: int = 0,
    dropout: float = 0.0,
    token: str | None = None,
    episode_timeout: float = 60.0,
    say=print,
) -> list[str]:
    """Enrol ``participants`` simulated participants at the study server ``base`` and walk each through
    every block (episodes played on the stream, then the questionnaire); after each block one leaves with
    probability ``dropout`` (withdrawn, as the operator would). Returns their ids."""
    if participants < 1:
        raise ValueError(f"participants must be at least 1, got {participants}")
    if not 0.0 <= dropout < 1.0:
        raise ValueError(f"dropout must be a probability in [0, 1), got {dropout}")
    api = _Api(base, token)
    info = api("design")
    dimensions = [q["dimension"] for q in info["questions"]]
    model = model_for(info["conditions"], dimensions, dropout=dropout)
    bridge = _Bridge(base, token)
    bridge.start()
    ids = []
    try:
        for k in range(participants):
            person = SimulatedParticipant(model, np.random.default_rng([seed, k]))
            pid = api("enrol", {})["participant"]
            ids.append(pid)
            prog = api(f"participant?p={pid}")["progress"]
            while prog["phase"] in ("episode", "questionnaire"):
                if prog["phase"] == "episode":
                    api("play", {"participant": pid})
                    prog = _next(api, pid, prog, episode_timeout)
                    continue
                answers = person.rate(prog["condition"], prog["position"])
                for dim in prog["missing"]:
                    api("rate", {"participant": pid, "position": prog["position"], "dimension": dim,
                                 "value": answers[dim]})  # fmt: skip
                positive = sum(v >= POSITIVE_FROM for v in answers.values())
                say(f"participant {pid}: block {prog['position'] + 1} of {prog['blocks']} ({prog['condition']}) "
                    f"rated, {positive} of {len(answers)} positive")  # fmt: skip
                last = prog["position"] + 1 == prog["blocks"]
                if not last and person.drops_out():
                    api("withdraw", {"participant": pid})
                    say(f"participant {pid}: leaves after block {prog['position'] + 1} (withdrawn)")
                prog = api(f"participant?p={pid}")["progress"]
            say(f"participant {pid}: {prog['phase']} ({k + 1} of {participants})")
    finally:
        bridge.close()
    return ids
