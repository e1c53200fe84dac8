"""What a request may say and what the server may be asked: :class:`Limits`, :class:`RequestError`, the parsed
requests (:class:`SampleRequest`, :class:`RespondRequest`, :class:`StreamRequest`) and the field parsers they
are built from, and the maps replies carry (:func:`grounding_dict`, :func:`scene`).

Every refusal is a :class:`RequestError` whose message names the field, what it must be and what was given;
the server answers it as ``{"type": "error", "code": ..., "error": ...}`` and serves on (docs/serving.md).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import secrets
from typing import Any

import numpy as np

from jgrounding import safety
from jgrounding.config import MAX_SAMPLE_STEPS, SampleConfig
from jgrounding.vocabulary import INTENTS

REQUEST_TYPES = ("info", "ground", "sample", "stream", "respond", "stop", "ack")
WS_MAX_SIZE = 4 << 20  # larger frames are refused by the WebSocket layer itself (close code 1009)
STALL_S = (0.1, 60.0)  # seconds of client silence a stream may be given before it glides to rest
SEEDS = (0, (1 << 31) - 1)

# Limits' integer fields: (lowest, highest, the option of ``python -m jgrounding.serve`` that sets it).
_INTEGER_LIMITS = {
    "max_text": (1, 100_000, "--max-text"),
    "max_samples": (1, 4096, "--max-samples"),
    "max_trajectories": (1, 65_536, None),
    "max_steps": (1, MAX_SAMPLE_STEPS, None),
    "max_message": (1, WS_MAX_SIZE, None),  # a request cannot be larger than a frame the WebSocket accepts
    "burst": (1, 1_000_000, "--burst"),
}


class RequestError(Exception):
    """A request the server refuses; answered as ``{"type": "error", "code": code, "error": message}``."""

    def __init__(self, message: str, code: str = "bad_request"):
        super().__init__(message)
        self.code = code


@dataclasses.dataclass(frozen=True)
class Limits:
    """What one request and one connection may ask of the server (``--max-*`` options). A value out of its
    range is refused here, with a ``ValueError`` naming the field, its range and its option."""

    max_text: int = 1000  # characters of a response text
    max_samples: int = 64  # num_samples per tuple
    max_trajectories: int = 1024  # tuples x num_samples per request
    max_steps: int = 100  # sampler steps
    max_message: int = 64 << 10  # bytes of one request
    rate: float = 1000.0  # requests per second per connection (token bucket)
    burst: int = 1000  # requests in a burst (the bucket's size)
    stall_s: float = 1.0  # a streaming client silent this long is stalled: the stream glides to rest

    def __post_init__(self):
        def name(field: str, option: str | None) -> str:
            return f"Limits.{field}" + (f" ({option})" if option else "")

        for field, (lo, hi, option) in _INTEGER_LIMITS.items():
            v = getattr(self, field)
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or not lo <= v <= hi:
                raise ValueError(f"{name(field, option)} must be an integer in {lo}..{hi}, got {v!r}")
        if not _is_number(self.rate) or not (math.isfinite(self.rate) and self.rate > 0):
            raise ValueError(f"{name('rate', '--rate')} must be a finite number > 0 (requests/s), got {self.rate!r}")
        lo, hi = STALL_S
        if not _is_number(self.stall_s) or not lo <= self.stall_s <= hi:
            raise ValueError(
                f"{name('stall_s', '--stall')} must be a number of seconds in {lo:g}..{hi:g}, got {self.stall_s!r}"
            )


def _is_number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


# --- the fields of a request -----------------------------------------------------------------------------------


def parse_int(msg: dict, name: str, default: int, lo: int, hi: int) -> int:
    v = msg.get(name, default)
    if v is None:
        v = default
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise RequestError(f"{name} must be an integer in {lo}..{hi}, got {v!r}")
    return v


def parse_bool(msg: dict, name: str, default: bool = False) -> bool:
    v = msg.get(name, default)
    if not isinstance(v, bool):
        raise RequestError(f"{name} must be true or false, got {v!r}")
    return v


def parse_seed(msg: dict) -> int:
    """``seed``, or a fresh random one."""
    return parse_int(msg, "seed", secrets.randbelow(SEEDS[1] + 1), *SEEDS)


def parse_text(msg: dict, limits: Limits) -> str:
    text = msg.get("text")
    if not isinstance(text, str):
        raise RequestError(f"text must be a string, got {type(text).__name__}")
    if not text.strip():
        raise RequestError("text is empty; give a response such as 'User seems sad; respond calmly'")
    if len(text) > limits.max_text:
        raise RequestError(f"text has {len(text)} characters; at most {limits.max_text}", "too_large")
    return text


def parse_current(msg: dict, num_tendons: int):
    """``current``: ``"rest"`` (the default), None, or one command per tendon (as ``float32``)."""
    cur = msg.get("current", safety.REST)
    try:
        safety.current_command(cur, num_tendons)
    except ValueError as e:
        raise RequestError(str(e)) from None
    return cur if cur is None or isinstance(cur, str) else np.asarray(cur, np.float32)


def parse_tuples(msg: dict, limits: Limits):
    """(intent, intensity, number of tuples) of a request naming them, validated like :func:`jgrounding.sample`
    does."""
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


# --- the requests ----------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class SampleRequest:
    """A ``sample`` request, checked: a ``text`` to ground first, or ``intent`` / ``intensity``."""

    num_samples: int
    steps: int
    seed: int
    start_conditioned: bool
    force: bool
    rollout: bool
    sampler: str | None
    current: Any  # "rest", None or a float32 command per tendon
    text: str | None  # grounded by the server (then intent and intensity are None)
    intent: Any = None  # a name, an index or a list of them
    intensity: Any = None
    tuples: int = 1  # how many (intent, intensity) tuples the request names

    @classmethod
    def parse(cls, msg: dict, limits: Limits, num_tendons: int) -> SampleRequest:
        num_samples = parse_int(msg, "num_samples", 1, 1, limits.max_samples)
        steps = parse_int(msg, "steps", SampleConfig.steps, 1, limits.max_steps)
        seed = parse_seed(msg)
        start_conditioned, force, rollout = (parse_bool(msg, n) for n in ("start_conditioned", "force", "rollout"))
        sampler = msg.get("sampler")
        if sampler is not None and not isinstance(sampler, str):
            raise RequestError(f"sampler must be a string, got {type(sampler).__name__}")
        current = parse_current(msg, num_tendons)
        text = intent = intensity = None
        n = 1
        if "text" in msg:
            if "intent" in msg or "intensity" in msg:
                raise RequestError("give either text or intent/intensity, not both")
            text = parse_text(msg, limits)
        else:
            intent, intensity, n = parse_tuples(msg, limits)
        if n * num_samples > limits.max_trajectories:
            raise RequestError(
                f"{n} tuples x {num_samples} samples = {n * num_samples} trajectories; at most "
                f"{limits.max_trajectories} per request",
                "too_large",
            )
        if start_conditioned and current is None:
            raise RequestError("start_conditioned needs current ('rest' or a command per tendon)")
        return cls(
            num_samples, steps, seed, start_conditioned, force, rollout, sampler, current, text, intent, intensity, n
        )


@dataclasses.dataclass(frozen=True)
class RespondRequest:
    """A response for a running stream (``respond``, or the first one of ``stream``): one tuple or a text."""

    force: bool
    seed: int
    text: str | None  # grounded by the server (then intent and intensity are None)
    intent: Any = None
    intensity: Any = None

    @classmethod
    def parse(cls, msg: dict, limits: Limits) -> RespondRequest:
        force, seed = parse_bool(msg, "force"), parse_seed(msg)
        if "text" in msg:
            return cls(force, seed, parse_text(msg, limits))
        intent, intensity, n = parse_tuples(msg, limits)
        if n != 1:
            raise RequestError("a stream plays one tuple at a time; give one intent and one intensity")
        return cls(force, seed, None, intent, intensity)


@dataclasses.dataclass(frozen=True)
class StreamRequest:
    """A ``stream`` request: ``stall_s``, ``sim`` (stream the simulated backbone), ``steps``; ``first``: it
    also names a first response (parsed by :meth:`RespondRequest.parse`)."""

    stall_s: float
    sim: bool
    steps: int
    first: bool

    @classmethod
    def parse(cls, msg: dict, limits: Limits) -> StreamRequest:
        lo, hi = STALL_S
        stall_s = msg.get("stall_s", limits.stall_s)
        if isinstance(stall_s, bool) or not isinstance(stall_s, (int, float)) or not lo <= stall_s <= hi:
            raise RequestError(f"stall_s must be a number of seconds in {lo:g}..{hi:g}, got {stall_s!r}")
        sim = parse_bool(msg, "sim")
        steps = parse_int(msg, "steps", SampleConfig.steps, 1, limits.max_steps)
        return cls(float(stall_s), sim, steps, "text" in msg or "intent" in msg)


# --- what replies carry ----------------------------------------------------------------------------------------


def grounding_dict(g) -> dict:
    return {
        "intent": g.intent,
        "intensity": g.intensity,
        "confidence": round(float(g.confidence), 4),
        "confident": bool(g.confident),
        "backend": g.backend,
        "reason": g.reason,
    }


def decision_dict(decision) -> dict:
    """The grounding of a :class:`jgrounding.policy.respond.Decision` with its ``note`` (what the snap onto the
    checkpoint's tuples changed) and, for a held text, ``nearest`` (:attr:`Decision.nearest`: the tuple it was not
    acted on, for small print after the reply's ``message``)."""
    return {**grounding_dict(decision.grounding), "note": decision.note, "nearest": decision.nearest}


async def resolve(req: SampleRequest | RespondRequest, policy, call) -> tuple[Any, dict | None, Any, Any]:
    """``(decision, grounding, intent, intensity)`` of a request: a text is decided by ``policy`` (through ``call``,
    which runs the model off the event loop), ``grounding`` is its map for the reply; a named tuple has neither."""
    if req.text is None:
        return None, None, req.intent, req.intensity
    decision = await call(policy.decide, req.text, req.force)
    return decision, decision_dict(decision), decision.intent, decision.intensity


def scene() -> dict:
    """What the page needs to draw the trunk and the user (metres, world frame; x toward the user, z up)."""
    from jgrounding.sim import mjcf as tm

    return {
        "base": [0.0, 0.0, tm.BASE_HEIGHT],
        "trunk_length": tm.TRUNK_LENGTH,
        "user_torso": {"x": tm.USER_TORSO_X, "z": list(tm.USER_TORSO_Z), "radius": tm.USER_TORSO_RADIUS},
        "user_head": list(tm.USER_HEAD),
    }
