"""HTTP helpers of the study's server tests (the standard library only)."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request


def call(base: str, path: str, body: dict | None = None, token: str | None = None) -> tuple[int, dict]:
    """``(status, reply)`` of ``GET`` (no body) or ``POST`` (a JSON body) to ``/study/api/<path>``."""
    headers = {"Content-Type": "application/json"}
    if token:
        headers["Authorization"] = f"Bearer {token}"
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(f"{base.rstrip('/')}/study/api/{path}", data=data, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=60) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def ok(base: str, path: str, body: dict | None = None) -> dict:
    status, reply = call(base, path, body)
    assert status == 200 and reply["ok"], reply
    return reply


def wait_phase(base: str, pid: str, phase: str, timeout: float = 30.0) -> dict:
    """Poll until participant ``pid`` reaches ``phase`` (an episode takes 5 s at 30 Hz)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        prog = ok(base, f"participant?p={pid}")["progress"]
        if prog["phase"] == phase:
            return prog
        time.sleep(0.1)
    raise AssertionError(f"{pid} did not reach {phase}: {prog}")


def wait_played(base: str, timeout: float = 30.0) -> None:
    """Poll until the episode being executed has sent its last command."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if ok(base, "stream")["playing"] is None:
            time.sleep(0.3)  # its executed sha256 is committed right after
            return
        time.sleep(0.1)
    raise AssertionError("the episode did not finish")
