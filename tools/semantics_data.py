"""The semantic head's data, for its trainer and the tools beside it: the sets it trains, selects and calibrates on
(looked up in ``assets/semantics/sets.toml``, :mod:`tools.semantic_sets`), each training file's weight, the rows'
labels and the no-behaviour reasons they teach."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from jgrounding.semantics import head as sh
from jgrounding.vocabulary import INTENSITIES, INTENTS
from tools import semantic_sets

ROOT = Path(__file__).resolve().parent.parent
# The sets, named in assets/semantics/sets.toml (tools.semantic_sets): the training corpora's folder and the dev splits
# (v2 dev: the styles reasoners write, with no-behaviour texts; plain dev: plainly worded).
CORPORA = "train/corpora"
TRAIN_DIR = semantic_sets.get(CORPORA).folder
DEV = semantic_sets.path("dev/v2")
DEV_PLAIN = semantic_sets.path("dev/plain")
# The situation-only hold-outs of selection and calibration, two blind writers' (v2 dev holds 29 situations), never
# trained on: the calibration is fitted on v2 dev and them together, and their intent accuracy at an option's dev
# threshold is one term of its ship score (tools.semantics_calibration.dev_score). tools.semantics_knn reports them
# as its "blind" hold-outs.
SITUATION_DEV = semantic_sets.path("dev/situations_blind")
SITUATION_DEV2 = semantic_sets.path("dev/situations_blind2")
SITUATION_DEVS = (SITUATION_DEV, SITUATION_DEV2)
# Texts a student's distillation reads beside the training texts (labels unused: distillation matches the teacher's
# token states): the vote's situations and a second situations corpus, so that the student learns the teacher's
# reading of situations on more of them than the training corpora hold.
DISTILL_EXTRA = tuple(path for s in semantic_sets.select(reader="distillation") for path in s.files)
# Rows weigh by their file: the generated corpus less (templated), the structure corpus (the styles real
# reasoners write, and the no-behaviour kinds) more; each intent and "none" then weighs the same in total.
# (situations_blind.jsonl: the vote-only rows of assets/semantics/train/vote/, for a head retrained with them through
# --train-dir; the shipped head is not trained on them.)
FILE_WEIGHTS = {"generated.jsonl": 0.3, "structure.jsonl": 2.0, "situations.jsonl": 2.0, "situations_blind.jsonl": 2.0}
# The blind writers' training splits: every set read for training beside the corpora (no-motion and contrast texts,
# situation-only and mixed texts), each file weighing as the structure corpus; their benches stay frozen.
# tools.train_nomotion reads the same files.
BLIND_TRAIN = tuple(path for s in semantic_sets.select(reader="training") if s.name != CORPORA for path in s.files)
# Two more situation writers' files that the shipped head is not trained on (the head retrained with them did not
# ship: without a vote it lost to the shipped head with its vote on dev); the no-motion detector reads them as motion
# texts (tools.train_nomotion: BLIND_TRAIN + UNSHIPPED_TRAIN).
UNSHIPPED_TRAIN = semantic_sets.files("train/situations_detector")
BLIND_WEIGHT = 2.0

# How a no-behaviour style reads to a person (the reason head's classes; unknown styles read as their name).
REASON_TEXT = {
    "addressed_other": "words addressed to someone else",
    "quoted": "quoted words, not a request to the trunk",
    "background": "background talk (TV, radio or other people)",
    "system": "a system or log line",
    "instruction_other": "an instruction for another person",
    "not_understood": "the reasoner did not understand",
    "chitchat": "chit-chat: no behaviour requested",
    "question": "a question that moving cannot answer",
    "none": "no behaviour requested",
    # the blind writers' kinds
    "rules_out": "the text rules the motion out",
    "freeze_order": "an order to keep still",
    "observed_activity": "activity that asks nothing of the robot",
    "media_or_readaloud": "media or words read aloud",
    "system_or_meta": "a system or log line",
    "not_now_wait": "nothing to respond to yet",
    "maintenance_handling": "the trunk is being handled or serviced",
    "past_or_hypothetical": "a past or hypothetical motion, not a request",
}


def read_jsonl(path) -> list[dict]:
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def labels(rows) -> tuple[np.ndarray, np.ndarray]:
    intent = np.array([sh.NONE if r["intent"] == "none" else INTENTS.index(r["intent"]) for r in rows], np.int32)
    intensity = np.array(
        [
            -1 if r["intent"] == "none" or r.get("intensity") is None else INTENSITIES.index(r["intensity"])
            for r in rows
        ],
        np.int32,
    )
    return intent, intensity


def reason_classes(rows) -> list[str]:
    """The no-behaviour reasons the training rows name (their ``style``), "none" first for unnamed ones."""
    return ["none"] + sorted(
        {r["style"] for r in rows if r["intent"] == "none" and r.get("style") not in (None, "none")}
    )


def reason_labels(rows, classes) -> np.ndarray:
    return np.array([classes.index(r.get("style") or "none") if r["intent"] == "none" else -1 for r in rows], np.int32)


def train_files(train_dir=TRAIN_DIR, blind=BLIND_TRAIN) -> dict[str, tuple[Path, float]]:
    """The training files by name (a corpus file by its name, a blind split by its folder and name) with their
    weights (:data:`FILE_WEIGHTS`, :data:`BLIND_WEIGHT`), in reading order."""
    files = {path.name: (path, FILE_WEIGHTS.get(path.name, 1.0)) for path in sorted(Path(train_dir).glob("*.jsonl"))}
    for path in blind:
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"blind training split {path} missing (run its folder's split.py)")
        files[f"{path.parent.name}/{path.name}"] = (path, BLIND_WEIGHT)
    return files


def load_train(train_dir=TRAIN_DIR, blind=BLIND_TRAIN) -> tuple[list[dict], np.ndarray]:
    """All training rows and each one's weight before class balancing ``(N,)`` (:func:`train_files`)."""
    rows, weight = [], []
    for path, w in train_files(train_dir, blind).values():
        part = read_jsonl(path)
        rows += part
        weight += [w] * len(part)
    return rows, np.array(weight, np.float32)


def read_situations(paths=SITUATION_DEVS) -> list[dict]:
    """The rows of the situation hold-outs (:data:`SITUATION_DEVS`), in order."""
    return [r for path in paths for r in read_jsonl(path)]


def distill_texts() -> list[str]:
    """The texts of :data:`DISTILL_EXTRA` (labels unused)."""
    return [r["text"] for path in DISTILL_EXTRA for r in read_jsonl(path)]
