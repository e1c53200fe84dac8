"""Generated training corpus for the semantic head: templates written from the vocabulary, never from eval text.

``python -m tools.semantics_corpus`` writes ``assets/semantics/train/corpora/generated.jsonl`` (deterministic:
one seeded numpy generator). Each line is ``{"text", "intent", "intensity"}``; ``intent`` may be ``"none"``
for text that asks for no trunk behaviour at all (interface commands, keyboard noise, unrelated facts), which
teaches the head to say it is unsure instead of guessing a motion.

Sources of the phrases: the canonical descriptions in :mod:`jgrounding.vocabulary`, and the phrase lists of
:mod:`tools.semantics_corpus_actions` and :mod:`tools.semantics_corpus_context`, written for it by hand (actions,
situations, user states, refusals and agreements without the intent's own name, parts of the trunk). The evaluation
sets were never read while writing them.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from jgrounding import vocabulary as voc
from jgrounding.vocabulary import INTENSITIES, INTENTS
from tools import semantic_sets
from tools.semantics_corpus_actions import ACTIONS, DEGREE, EXTRA
from tools.semantics_corpus_context import BRITISH, NONE, SITUATIONS, SUBJECTS, TYPOS

ROOT = Path(__file__).resolve().parent.parent
OUT = semantic_sets.path("train/corpora", "generated.jsonl")
# The dev and test splits: a generated line that happens to be one of their texts (short commands such as "Come
# here.") is dropped, so that no training text is one the project evaluates on
# (tests/semantics/test_training_data.py). Only their texts are compared; nothing else is read from them.
EVAL_SPLITS = tuple(path for s in semantic_sets.select(reader="corpus") for path in s.files)
SEED = 0
PER_INTENT = 200  # generated examples per intent
NUM_NONE = 240


def _level_words(rng, level):
    return DEGREE[level][rng.integers(len(DEGREE[level]))]


def _apply_noise(rng, text):
    words = text.split(" ")
    if rng.random() < 0.08:
        words = [TYPOS.get(w, w) for w in words]
    if rng.random() < 0.1:
        words = [BRITISH.get(w, w) for w in words]
    text = " ".join(words)
    if rng.random() < 0.3:
        text = text.lower()
    return text


def _one(rng, intent):
    """One generated (text, level) for ``intent``."""
    level = int(rng.integers(4))
    action = ACTIONS[intent][rng.integers(len(ACTIONS[intent]))]
    sit = SITUATIONS[intent][rng.integers(len(SITUATIONS[intent]))]
    sit_level = None
    if isinstance(sit, tuple):
        sit_level, sit = sit
    style = rng.random()
    adverb = _level_words(rng, level)
    bang = "!" * (1 + int(rng.integers(2))) if level == 3 and rng.random() < 0.4 else "."
    subj = SUBJECTS[rng.integers(len(SUBJECTS))]
    act = f"{action} {adverb}".strip() if rng.random() < 0.6 else f"{adverb} {action}".strip()
    if style < 0.3:  # terse command
        text = f"{subj}{act}{bang}"
    elif style < 0.6:  # situation; response plan
        if sit_level is not None:
            level = sit_level
            adverb = _level_words(rng, level) if rng.random() < 0.5 else ""
            act = f"{action} {adverb}".strip()
        text = f"{sit[0].upper()}{sit[1:]}; {subj.lower() or ''}{act}{bang}"
    elif style < 0.75 and intent in EXTRA:  # phrasing without the intent's usual words
        text = EXTRA[intent][rng.integers(len(EXTRA[intent]))]
        if rng.random() < 0.5 and adverb:
            text = f"{text.rstrip('.!')} {adverb}{bang}"
        else:
            level = 1 if text.endswith(".") else 2
    elif style < 0.85:  # third person description of the robot
        verb, _, rest = action.partition(" ")
        verb = {"do": "does", "go": "goes", "say": "says", "be": "is", "don't": "doesn't"}.get(verb, verb + "s")
        text = " ".join(f"The robot {verb} {rest} {adverb}".split()) + bang
    elif style < 0.93:  # the description itself, with the level
        text = f"The trunk {voc.INTENT_DESCRIPTIONS[intent].split('the trunk ', 1)[-1]}, {adverb or 'normally'}."
    else:  # long plan
        text = (
            f"Observation: {sit}. The user looks at me. Plan: {act}, then return to a neutral pose"
            f" and wait for their reaction{bang}"
        )
        if sit_level is not None:
            level = sit_level
    return _apply_noise(rng, text), level


def generate(seed: int = SEED) -> list[dict]:
    """The generated corpus: ``PER_INTENT`` lines per intent plus ``NUM_NONE`` no-behaviour lines."""
    rng = np.random.default_rng(seed)
    rows = []
    for intent in INTENTS:
        seen = set()
        while sum(r["intent"] == intent for r in rows) < PER_INTENT:
            text, level = _one(rng, intent)
            if text not in seen:
                seen.add(text)
                rows.append({"text": text, "intent": intent, "intensity": INTENSITIES[level]})
    letters = np.array(list("abcdefghijklmnopqrstuvwxyz"))
    for i in range(NUM_NONE):
        if i < len(NONE):
            text = NONE[i]
        else:
            n = int(rng.integers(1, 4))
            text = " ".join("".join(rng.choice(letters, int(rng.integers(2, 9)))) for _ in range(n))
        rows.append({"text": text, "intent": "none", "intensity": "moderate"})
    return rows


def normalized(text: str) -> str:
    """Lower case, words only: the form in which two texts count as the same."""
    return " ".join(re.findall(r"[a-z0-9']+", text.lower()))


def decontaminated(rows: list[dict], splits=EVAL_SPLITS) -> list[dict]:
    """``rows`` without those whose text (:func:`normalized`) is a text of ``splits``."""
    held = {
        normalized(json.loads(line)["text"])
        for path in splits
        for line in Path(path).read_text().splitlines()
        if line.strip()
    }
    return [r for r in rows if normalized(r["text"]) not in held]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=str(OUT))
    args = p.parse_args(argv)
    from jgrounding.io import write_atomic

    rows = decontaminated(generate())
    write_atomic(Path(args.out), "".join(json.dumps(r) + "\n" for r in rows))
    print(f"wrote {len(rows)} lines to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
