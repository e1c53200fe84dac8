"""The blind writers' training texts (#34): well formed, and disjoint from every text the project evaluates on."""

import re
from pathlib import Path

import pytest

from experiments import bench_semantics
from jgrounding.vocabulary import INTENSITIES, INTENTS
from tools import semantic_sets, semantics_data, semantics_system_dev, train_semantics
from tools.semantics_corpus import EVAL_SPLITS
from tools.semantics_corpus import normalized as _norm
from tools.train_semantics import read_jsonl as _rows

# The brief's words that a situation-only text may not use (docs/semantics_blind_brief.md, "How to write").
MOTION_WORDS = re.compile(
    r"\b(wave|hug|nod|shake|point|beckon|celebrate|comfort|listen|curl|coil|swing|rest|offer|greet|bow|reach|lean"
    r"|retract|say hello|say goodbye)\b",
    re.IGNORECASE,
)
KEYS = {"id", "text", "intent", "intensity", "style"}


def _evaluated() -> dict[str, Path]:
    """Every file whose texts the project evaluates or selects on: the frozen benches (those the bench reads and any
    parked for a later change's judgement), the dev and test splits (the ones the corpus generator keeps its lines
    out of) and the blind situation hold-outs of the ship rule and the calibration."""
    files = dict(bench_semantics.BENCH_V3)
    for s in semantic_sets.select(role="bench"):
        # a set parked for a later change has no bench.jsonl yet: its writer's raw files are all frozen
        folder = s.folder
        frozen = [folder / "bench.jsonl"] if (folder / "bench.jsonl").exists() else sorted(folder.glob("*_raw.jsonl"))
        files |= {f"{s.name}/{path.name}": path for path in frozen}
    files |= {f"{path.parent.name}/{path.name}": path for path in EVAL_SPLITS}
    files |= {f"situation dev {path.name}": path for path in train_semantics.SITUATION_DEVS}
    # the whole system's dev sets (tools.semantics_system_dev: the unfitted hold-outs and the no-motion dev set too)
    files |= {f"system dev {path.name}": path for paths in semantics_system_dev.SETS.values() for path in paths}
    return files


BLIND_FILES = train_semantics.BLIND_TRAIN + semantics_data.UNSHIPPED_TRAIN  # what the head and the detector read


@pytest.mark.parametrize("path", BLIND_FILES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_each_blind_training_file_is_well_formed(path):
    rows = _rows(path)
    assert rows, path
    for r in rows:
        assert KEYS <= set(r), r
        assert r["intent"] in (*INTENTS, "none"), r
        assert r["intensity"] in INTENSITIES or r["intent"] == "none", r
    assert len({r["id"] for r in rows}) == len(rows)
    assert len({_norm(r["text"]) for r in rows}) == len(rows)


@pytest.mark.parametrize(
    "path",
    # every situation writer's training file, those read and those not (s24, s25)
    [p for s in semantic_sets.select(role="train") for p in s.files if re.fullmatch(r"situations_s\d+\.jsonl", p.name)],
    ids=lambda p: p.name,
)
def test_the_situation_writers_files_follow_their_brief(path):
    """s5-s9, s12, s13, s15-s20: 20 texts per intent, 5 per intensity (s24, s25, which nothing shipped reads: 16 and 4),
    situation style, none naming a motion."""
    rows = _rows(path)
    assert {r["style"] for r in rows} == {"situation"}
    counts = {}
    for r in rows:
        counts[r["intent"], r["intensity"]] = counts.get((r["intent"], r["intensity"]), 0) + 1
    per_cell = 4 if path.stem in ("situations_s24", "situations_s25") else 5
    assert counts == {(i, z): per_cell for i in INTENTS for z in INTENSITIES}
    named = [r["text"] for r in rows if MOTION_WORDS.search(r["text"])]
    assert not named, named[:5]


def test_no_training_text_is_one_the_project_evaluates_on():
    """The training corpora and the blind writers' training files share no text (case and punctuation aside)
    with the frozen benches, the dev and test splits or the ship rule's situation hold-out."""
    train = {}
    files = {name: path for name, (path, _) in train_semantics.train_files().items()}
    files |= {f"{p.parent.name}/{p.name}": p for p in semantics_data.UNSHIPPED_TRAIN}  # the detector reads them
    for name, path in files.items():
        for r in _rows(path):
            train.setdefault(_norm(r["text"]), name)
    for name, path in _evaluated().items():
        shared = [(train[t], r["text"]) for r in _rows(path) if (t := _norm(r["text"])) in train]
        assert not shared, f"{name} shares {len(shared)} texts with training: {shared[:3]}"


def test_the_second_reader_labelled_every_hold_out_text_and_agreement_counts_by_hand():
    from tools import label_agreement as la

    writer, second = la.read_labels(la.WRITER), la.read_labels(la.SECOND)
    assert set(writer) == set(second) and len(second) == 256
    assert all(i in INTENTS and z in INTENSITIES for i, z in second.values())
    a = {"x": ("nodding", "subtle"), "y": ("greeting", "emphatic"), "z": ("resting", "moderate")}
    b = {"x": ("nodding", "moderate"), "y": ("farewell", "emphatic"), "z": ("resting", "moderate")}
    r = la.agreement(a, b)
    assert (r["intent"], r["intensity_exact"], r["within_one"], r["both"]) == (2 / 3, 2 / 3, 1.0, 1 / 3)
    with pytest.raises(ValueError, match="different ids"):
        la.agreement(a, {"x": b["x"]})


def test_the_detector_only_texts_are_well_formed_unseen_by_the_head_and_never_evaluated_on():
    """assets/semantics/train/nomotion_detector/*/train.jsonl (tools.train_nomotion.DETECTOR_ONLY): the converted raw files
    of their writers (nine no-motion kinds and contrast texts), read by the detector's trainer only, sharing no text
    with any evaluated file; a text that a file the head trains on holds too (w8 wrote a log line w4 wrote) is
    left out of the detector's rows, so no text is learned twice."""
    from tools import train_nomotion

    assert train_nomotion.DETECTOR_ONLY, "no detector-only files"
    head_reads = {_norm(r["text"]) for path, _ in train_semantics.train_files().values() for r in _rows(path)}
    evaluated = {_norm(r["text"]) for path in _evaluated().values() for r in _rows(path)}
    for path in train_nomotion.DETECTOR_ONLY:
        rows = _rows(path)
        raw = sum(len(_rows(path.parent / f"{kind}_raw.jsonl")) for kind in ("nomotion", "contrast"))
        assert len(rows) == raw and len({r["id"] for r in rows}) == len(rows)
        for r in rows:
            assert KEYS <= set(r), r
            if r["intent"] == "none":
                assert r["intensity"] is None and r["style"] != "contrast", r
            else:
                assert r["style"] == "contrast" and r["intent"] in INTENTS and r["intensity"] in INTENSITIES, r
                assert r["rejected"] in INTENTS and r["rejected"] != r["intent"], r
        texts = {_norm(r["text"]) for r in rows}
        assert not texts & evaluated, path
        assert len(texts & head_reads) <= 2, path
    trained = train_nomotion.training_rows()
    sources = {r["source"] for r in trained}
    assert train_nomotion.EXTRA_NO_MOTION in sources and train_nomotion.CONTRAST in sources
    without = train_nomotion.training_rows(detector_only=())
    n_blind = sum(
        len(_rows(path)) for path in train_nomotion.DETECTOR_BLIND
    )  # then the detector-only rows, the corpora
    n_extra = len(trained) - len(without)
    assert trained[:n_blind] == without[:n_blind] and trained[n_blind + n_extra :] == without[n_blind:]
    written = [r for path in train_nomotion.DETECTOR_ONLY for r in _rows(path)]
    repeated = {_norm(r["text"]) for r in written} & {_norm(r["text"]) for r in without[:n_blind]}
    assert n_extra == sum(_norm(r["text"]) not in repeated for r in written)  # a text the head's files hold is left out
