"""MLLM backend (Eqs. 2 and 4): any OpenAI-compatible chat endpoint (vLLM, Ollama, llama.cpp server).

- :func:`grounding_specification` renders the grounding specification C of Sec. III-A: the trunk's
  affordances and feasibility limits, the supported tuples with canonical descriptions, few-shot
  examples and the JSON output schema.
- :func:`ground_mllm` asks the server for ``{"intent": ..., "intensity": ...}`` (Eq. 4), validates the
  reply against the schema and the vocabulary, retries a bounded number of times, and falls back to the
  embedded reducer with a logged reason.
- :func:`reason` is Eq. (2): a typed :class:`Observation` (visual description or image, transcript,
  tactile events) plus a short history of past tuples -> an open-vocabulary response text.

Standard library only (``urllib``); configure with arguments or ``JGROUNDING_MLLM_URL``,
``JGROUNDING_MLLM_MODEL``, ``JGROUNDING_MLLM_API_KEY``.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import logging
import os
import re
import urllib.error
import urllib.request
from pathlib import Path

from jgrounding import vocabulary as voc
from jgrounding.vocabulary import INTENSITIES, INTENTS

log = logging.getLogger(__name__)

SCHEMA = {
    "type": "object",
    "properties": {
        "intent": {"type": "string", "enum": list(INTENTS)},
        "intensity": {"type": "string", "enum": list(INTENSITIES)},
        "confidence": {"type": "number", "minimum": 0, "maximum": 1},
    },
    "required": ["intent", "intensity"],
}
FEW_SHOT = (
    ("User seems sad; respond calmly with a gentle touch.", "comforting", "moderate"),
    ("The kids are cheering, we won! Celebrate with them as much as possible!", "celebrating", "emphatic"),
    ("The user stepped back when I moved; give them a little space.", "withdrawal", "subtle"),
    ("They asked whether I followed; clearly acknowledge.", "nodding", "pronounced"),
)


@dataclasses.dataclass(frozen=True)
class Config:
    url: str = ""
    model: str = "qwen3-vl"
    api_key: str = ""
    timeout_s: float = 20.0
    retries: int = 2

    @staticmethod
    def from_env(**overrides) -> "Config":
        env = {
            "url": os.environ.get("JGROUNDING_MLLM_URL", ""),
            "model": os.environ.get("JGROUNDING_MLLM_MODEL", "qwen3-vl"),
            "api_key": os.environ.get("JGROUNDING_MLLM_API_KEY", ""),
        }
        env.update({k: v for k, v in overrides.items() if v is not None})
        return Config(**env)


@dataclasses.dataclass(frozen=True)
class Observation:
    """o_t of Eq. (1): what the robot perceives this turn."""

    visual: str = ""  # description of the scene
    image: str | None = None  # path of an image, sent as a data URL to vision models
    transcript: str = ""  # what the user said
    tactile: tuple[str, ...] = ()  # touch events on the trunk


def grounding_specification() -> str:
    """The grounding specification C as a system prompt."""
    tuples = "\n".join(f"- {m}: {voc.describe(m)}" for m in INTENTS)
    levels = "\n".join(f"- {z}: performed {voc.INTENSITY_DESCRIPTIONS[z]}" for z in INTENSITIES)
    shots = "\n".join(f'Response: "{r}"\nAnswer: {{"intent": "{m}", "intensity": "{z}"}}' for r, m, z in FEW_SHOT)
    return f"""You ground a social robot's planned response into motion of its soft, tendon-driven elephant trunk.
Trunk affordances: it bends toward any side, curls (the tip curls most), retracts by co-contraction, extends by
relaxing, and can touch the user gently. Limits: light contact only (<= 15 N), slow near the user, 5-second motions,
no grasping of heavy objects, no motion that is not in the list below.

Supported intents (choose exactly one):
{tuples}

Intensity levels (choose exactly one):
{levels}

Examples:
{shots}

Reply with a JSON object only, matching this schema: {json.dumps(SCHEMA)}"""


def _post(cfg: Config, messages: list[dict]) -> str:
    if not cfg.url:
        raise ConnectionError("no MLLM endpoint configured (set JGROUNDING_MLLM_URL or pass url=...)")
    body = json.dumps({"model": cfg.model, "messages": messages, "temperature": 0.0}).encode()
    req = urllib.request.Request(
        cfg.url.rstrip("/") + "/chat/completions",
        data=body,
        method="POST",
        headers={
            "Content-Type": "application/json",
            **({"Authorization": f"Bearer {cfg.api_key}"} if cfg.api_key else {}),
        },
    )
    with urllib.request.urlopen(req, timeout=cfg.timeout_s) as resp:
        doc = json.loads(resp.read().decode())
    try:
        content = doc["choices"][0]["message"]["content"]
    except (KeyError, IndexError, TypeError):
        raise ValueError(f"the server's reply is not an OpenAI chat completion: {json.dumps(doc)[:120]}")
    if not isinstance(content, str):
        raise ValueError(f"the server's reply has no text content (got {type(content).__name__})")
    return content


def parse_reply(text: str) -> tuple[str, str, float]:
    """Validate a reply against :data:`SCHEMA`; ``ValueError`` says what is wrong."""
    match = re.search(r"\{.*\}", text, flags=re.S)
    if not match:
        raise ValueError(f"reply holds no JSON object: {text[:80]!r}")
    try:
        doc = json.loads(match.group(0))
    except json.JSONDecodeError as e:
        raise ValueError(f"reply is not valid JSON ({e})")
    intent, intensity = doc.get("intent"), doc.get("intensity")
    if intent not in INTENTS:
        raise ValueError(f"intent {intent!r} is not in the vocabulary")
    if intensity not in INTENSITIES:
        raise ValueError(f"intensity {intensity!r} is not in the vocabulary")
    conf = doc.get("confidence", 0.9)
    conf = float(conf) if isinstance(conf, (int, float)) and 0 <= conf <= 1 else 0.9
    return intent, intensity, conf


def ground_mllm(
    text: str,
    *,
    url: str | None = None,
    model: str | None = None,
    api_key: str | None = None,
    retries: int | None = None,
    timeout_s: float | None = None,
    fallback=None,
):
    """Eq. (4) through an MLLM; falls back to the embedded reducer (reason logged and returned).

    ``fallback``: an embedded Grounding already computed for ``text`` (an escalation of low confidence);
    a reply then says so in its backend, and a failure returns ``fallback`` with the reason added.
    """
    from jgrounding.semantics.embedded import ground_embedded
    from jgrounding.semantics.types import Grounding

    cfg = Config.from_env(url=url, model=model, api_key=api_key, retries=retries, timeout_s=timeout_s)
    messages = [
        {"role": "system", "content": grounding_specification()},
        {"role": "user", "content": f'Response: "{text}"\nAnswer:'},
    ]
    problems = []
    for attempt in range(cfg.retries + 1):
        try:
            intent, intensity, conf = parse_reply(_post(cfg, messages))
            if fallback is not None:
                return Grounding(
                    intent,
                    intensity,
                    conf,
                    "mllm (escalated)",
                    True,
                    reason=f"escalated: embedded confidence {fallback.confidence:.2f} ({fallback.reason})",
                )
            return Grounding(intent, intensity, conf, "mllm", True)
        except ValueError as e:  # a reply that breaks the schema: ask again, saying what was wrong
            problems.append(str(e))
            messages = messages[:2] + [
                {
                    "role": "user",
                    "content": f"Your last answer was invalid ({e}). Reply with JSON matching the schema only.",
                }
            ]
        except (OSError, ConnectionError, KeyError, json.JSONDecodeError) as e:  # server down or odd payload
            problems.append(f"{type(e).__name__}: {e}")
            break
    reason = "MLLM fallback to embedded: " + "; ".join(problems)
    log.warning(reason)
    g = fallback if fallback is not None else ground_embedded(text)
    return dataclasses.replace(
        g, backend="embedded (mllm fallback)", reason="; ".join(filter(None, [reason, g.reason]))
    )


def reason(observation: Observation, history: list[tuple[str, str]] = (), **cfg_overrides) -> str:
    """Eq. (2): r_t = f_MLLM(o_t, H_{t-1}) -> a short response plan in natural language."""
    cfg = Config.from_env(**cfg_overrides)
    past = ", ".join(f"{m}/{z}" for m, z in history[-5:]) or "none"
    text = (
        f"Scene: {observation.visual or 'n/a'}\nUser said: {observation.transcript or 'n/a'}\n"
        f"Touch on the trunk: {', '.join(observation.tactile) or 'none'}\nRecent trunk responses: {past}\n"
        "Describe in one or two sentences how the robot should respond socially."
    )
    content: list | str = text
    if observation.image:
        data = base64.b64encode(Path(observation.image).read_bytes()).decode()
        content = [
            {"type": "text", "text": text},
            {"type": "image_url", "image_url": {"url": f"data:image/png;base64,{data}"}},
        ]
    messages = [
        {
            "role": "system",
            "content": "You are the social reasoning module of a companion robot "
            "with an elephant-like trunk. Answer with the planned response only.",
        },
        {"role": "user", "content": content},
    ]
    return _post(cfg, messages).strip()
