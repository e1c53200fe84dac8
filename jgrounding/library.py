"""The expert demonstration library (Sec. III-C.1, SPEC §3): 64 tuples x 4 realizations = 256 pairs.

Built by :func:`build` (``python -m experiments.build_library``): for every (intent, intensity) tuple,
candidates from :mod:`jgrounding.primitives` are reduced to Catmull-Rom controls by Eq. (ci)
(``splines.fit``), reconstructed and passed through the safety gate (the expert trajectory is
``u = make_safe(R(c))``, exactly what the generators' outputs become), screened by
:mod:`jgrounding.screening`, and the first four that pass are kept. One realization per tuple, drawn
from the seed, is held out: 192 train / 64 held-out.

File format (``FORMAT_VERSION`` 1): ``assets/library.npz`` with arrays ``u (256,150,4) f32``,
``controls (256,4,P) f32``, ``intent``, ``intensity``, ``realization``, ``heldout`` (bool),
``texts (256, n_texts) str``; and ``assets/library.json``, the card (seed, config, acceptance rates,
sha256 of the npz). Both are byte-identical for the same seed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
from pathlib import Path

import numpy as np

from jgrounding import primitives, responses, safety, screening, splines
from jgrounding.vocabulary import INTENSITIES, INTENTS, NUM_INTENSITIES, NUM_INTENTS

FORMAT_VERSION = 1
ASSETS = Path(__file__).resolve().parent.parent / "assets"
DEFAULT_PATH = ASSETS / "library.npz"
REGENERATE = "python -m experiments.build_library"


@dataclasses.dataclass(frozen=True)
class BuildConfig:
    seed: int = 0
    realizations: int = 4
    num_controls: int = 4
    candidates_per_round: int = 8
    max_rounds: int = 12
    texts_per_record: int = 3


@dataclasses.dataclass(frozen=True)
class Split:
    """Records of one split; arrays share the leading axis N."""

    u: np.ndarray  # (N, 150, 4) float32, expert actuation R(c) through the safety gate
    controls: np.ndarray  # (N, 4, P) float32, Catmull-Rom controls c* of Eq. (ci)
    intent: np.ndarray  # (N,) int32
    intensity: np.ndarray  # (N,) int32
    realization: np.ndarray  # (N,) int32
    texts: tuple[tuple[str, ...], ...]  # response texts each record was reduced from

    def __len__(self) -> int:
        return len(self.intent)


@dataclasses.dataclass(frozen=True)
class Library:
    train: Split
    heldout: Split
    meta: dict
    path: str


def _reduce(candidates: np.ndarray, num_controls: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (ci) and R(c) on the spline basis, in float64 NumPy, then rounded once to float32.

    The same least squares as :func:`splines.fit` / :func:`splines.reconstruct`, but not through XLA's
    float32 einsum, whose accumulation order depends on the CPU's vector units: that made the library
    differ in the last bits between machines, and regeneration must be byte-identical everywhere.
    """
    steps = candidates.shape[-2]
    pinv, basis = splines._pinv_np(steps, num_controls), splines._basis_np(steps, num_controls)
    controls = np.einsum("pt,btj->bjp", pinv, candidates.astype(np.float64)).astype(np.float32)
    raw = np.einsum("tp,bjp->btj", basis, controls.astype(np.float64)).astype(np.float32)
    return controls, raw, np.asarray(safety.make_safe(raw))


def build(config: BuildConfig = BuildConfig(), progress: bool = True) -> tuple[dict, dict]:
    """Generate, reduce and screen; returns (arrays, card). Deterministic in ``config.seed``."""
    from tqdm import tqdm

    keep = {k: [] for k in ("u", "controls", "intent", "intensity", "realization", "texts")}
    tried = np.zeros((NUM_INTENTS, NUM_INTENSITIES), int)
    accepted = np.zeros((NUM_INTENTS, NUM_INTENSITIES), int)
    per_check = {c: 0 for c in screening.CHECKS}
    need = {(m, z): config.realizations for m in range(NUM_INTENTS) for z in range(NUM_INTENSITIES)}
    rngs = {key: np.random.default_rng([config.seed, *key]) for key in need}
    found = {key: [] for key in need}
    bar = tqdm(total=config.max_rounds, desc="screening rounds", disable=not progress)
    for _ in range(config.max_rounds):
        todo = [k for k in need if len(found[k]) < need[k]]
        if not todo:
            break
        cand = np.stack([primitives.candidate(rngs[k], *k) for k in todo for _ in range(config.candidates_per_round)])
        tuples = np.repeat(np.array(todo), config.candidates_per_round, axis=0)
        controls, raw, u = _reduce(cand, config.num_controls)
        checks = screening.screen(raw, u, tuples[:, 0])
        for c in screening.CHECKS:
            per_check[c] += int(checks[c].sum())
        for i, (m, z) in enumerate(map(tuple, tuples)):
            tried[m, z] += 1
            if checks["accepted"][i]:
                accepted[m, z] += 1
                if len(found[(m, z)]) < need[(m, z)]:
                    found[(m, z)].append((controls[i], u[i]))
        bar.update(1)
    bar.close()
    short = {f"{INTENTS[m]}/{INTENSITIES[z]}": len(v) for (m, z), v in found.items() if len(v) < need[(m, z)]}
    if short:
        raise RuntimeError(f"screening kept too few realizations for {short}; raise BuildConfig.max_rounds")
    split_rng = np.random.default_rng([config.seed, 999])
    heldout = []
    for m in range(NUM_INTENTS):
        for z in range(NUM_INTENSITIES):
            text_rng = np.random.default_rng([config.seed, m, z, 7])
            held = int(split_rng.integers(config.realizations))
            for r, (c, u) in enumerate(found[(m, z)]):
                keep["controls"].append(c)
                keep["u"].append(u)
                keep["intent"].append(m)
                keep["intensity"].append(z)
                keep["realization"].append(r)
                keep["texts"].append(responses.response_texts(m, z, config.texts_per_record, text_rng))
                heldout.append(r == held)
    arrays = {
        "u": np.asarray(keep["u"], np.float32),
        "controls": np.asarray(keep["controls"], np.float32),
        "intent": np.asarray(keep["intent"], np.int32),
        "intensity": np.asarray(keep["intensity"], np.int32),
        "realization": np.asarray(keep["realization"], np.int32),
        "heldout": np.asarray(heldout, bool),
        "texts": np.asarray(keep["texts"], dtype=np.str_),
    }
    card = {
        "format_version": FORMAT_VERSION,
        "config": dataclasses.asdict(config),
        "num_records": int(len(arrays["u"])),
        "num_train": int((~arrays["heldout"]).sum()),
        "num_heldout": int(arrays["heldout"].sum()),
        "candidates_tried": int(tried.sum()),
        "candidates_accepted": int(accepted.sum()),
        "passed_per_check": per_check,
        "acceptance_rate": {f"{INTENTS[m]}/{INTENSITIES[z]}": round(float(accepted[m, z] / tried[m, z]), 4)
                            for m in range(NUM_INTENTS) for z in range(NUM_INTENSITIES)},
        "regenerate": REGENERATE,
    }
    return arrays, card


def to_bytes(arrays: dict) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # zip entries carry a fixed date: same arrays, same bytes
    return buf.getvalue()


def save(arrays: dict, card: dict, path: str | Path = DEFAULT_PATH) -> Path:
    """Write ``path`` (.npz) and its card (.json) atomically; the card records the npz's sha256."""
    from jgrounding.export import write_atomic

    data = to_bytes(arrays)
    card = {**card, "sha256": hashlib.sha256(data).hexdigest()}
    path = Path(path)
    write_atomic(path, data)
    write_atomic(path.with_suffix(".json"), json.dumps(card, indent=1, sort_keys=True) + "\n")
    return path


def file_hash(path: str | Path = DEFAULT_PATH) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _split(arrays, mask) -> Split:
    return Split(u=arrays["u"][mask], controls=arrays["controls"][mask], intent=arrays["intent"][mask],
                 intensity=arrays["intensity"][mask], realization=arrays["realization"][mask],
                 texts=tuple(tuple(str(t) for t in row) for row in arrays["texts"][mask]))


def load_library(path: str | Path | None = None) -> Library:
    """Load the demonstration library (``assets/library.npz`` by default) -> :class:`Library`."""
    if path is not None and not isinstance(path, (str, Path)):
        raise TypeError(f"path must be a str or pathlib.Path to a library .npz, got {type(path).__name__}")
    path = Path(path or DEFAULT_PATH)
    if not path.exists():
        raise FileNotFoundError(f"library file {path} not found; regenerate it with `{REGENERATE}`")
    card_path = path.with_suffix(".json")
    try:
        card = json.loads(card_path.read_text())
    except (OSError, ValueError) as e:
        raise ValueError(f"library card {card_path} is missing or unreadable ({e}); regenerate with `{REGENERATE}`")
    if card.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"library {path} has format_version {card.get('format_version')!r}, expected "
                         f"{FORMAT_VERSION}; regenerate with `{REGENERATE}`")
    raw = path.read_bytes()
    if card.get("sha256") and hashlib.sha256(raw).hexdigest() != card["sha256"]:
        raise ValueError(f"library {path} does not match the sha256 in {card_path} (corrupt or edited); "
                         f"regenerate with `{REGENERATE}`")
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
    except Exception as e:  # zipfile / format errors of every kind
        raise ValueError(f"library {path} is not a readable npz ({e}); regenerate with `{REGENERATE}`")
    missing = {"u", "controls", "intent", "intensity", "realization", "heldout", "texts"} - set(arrays)
    if missing:
        raise ValueError(f"library {path} lacks arrays {sorted(missing)}; regenerate with `{REGENERATE}`")
    held = arrays["heldout"].astype(bool)
    return Library(train=_split(arrays, ~held), heldout=_split(arrays, held), meta=card, path=str(path))


if __name__ == "__main__":  # python -m jgrounding.library import DIR --out my_library.npz
    from jgrounding import importer

    raise SystemExit(importer.main())
