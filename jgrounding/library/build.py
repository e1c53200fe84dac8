"""The expert demonstration library (Sec. III-C.1, SPEC §3): 64 tuples x 4 realizations = 256 pairs.

Built by :func:`build` (``python -m tools.build_library``): for every (intent, intensity) tuple,
candidates from :mod:`jgrounding.library.primitives` are reduced to Catmull-Rom controls by Eq. (ci)
(``splines.fit``), reconstructed and passed through the safety gate (the expert trajectory is
``u = make_safe(R(c))``, exactly what the generators' outputs become), screened by
:mod:`jgrounding.library.screening`, and the first four that pass are kept. One realization per tuple, drawn
from the seed, is held out: 192 train / 64 held-out.

File format (``FORMAT_VERSION`` 1): ``jgrounding/assets/library.npz`` with arrays ``u (256,150,4) f32``,
``controls (256,4,P) f32``, ``intent``, ``intensity``, ``realization``, ``variant``, ``heldout`` (bool),
``texts (256, n_texts) str``, and the evaluation set ``eval_u (E,150,4)``, ``eval_controls``,
``eval_intent``, ``eval_intensity``, ``eval_variant`` (E = 64 x ``eval_realizations``, never trained on); and ``jgrounding/assets/library.json``, the card (seed, config, acceptance rates,
sha256 of the npz). Both are byte-identical for the same seed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
from pathlib import Path

import numpy as np

from jgrounding import safety, sim
from jgrounding.actuation import splines
from jgrounding.config import NUM_CONTROLS
from jgrounding.io import asset  # the one resolver of the package's run-time files
from jgrounding.library import designs, primitives, responses, screening
from jgrounding.vocabulary import INTENSITIES, INTENTS, NUM_INTENSITIES, NUM_INTENTS

FORMAT_VERSION = 1
# The shipped library's content version (jgrounding.library.designs; bump it there when a design changes).
# Checkpoints record it with the library's sha256 and are refused on another library (training.checkpoints.restore_trained).
LIBRARY_VERSION = designs.LIBRARY_VERSIONS[designs.DEFAULT_VERSION]

ASSETS = asset()  # jgrounding/assets
DEFAULT_PATH = ASSETS / "library.npz"
REGENERATE = "python -m tools.build_library"


@dataclasses.dataclass(frozen=True)
class BuildConfig:
    seed: int = 0
    realizations: int = 4
    num_controls: int = NUM_CONTROLS
    candidates_per_round: int = 8
    max_rounds: int = 12
    texts_per_record: int = 3
    # The evaluation set (SPEC §3, §6): fresh realizations per tuple, balanced across its variants, drawn
    # with another seed, never trained on; the distribution metrics score samples against it.
    eval_realizations: int = 16
    eval_seed_offset: int = 1000
    # The design (jgrounding.library.designs): 5, the shipped library, or 3 / 4 (python -m tools.build_library --version N).
    version: int = designs.DEFAULT_VERSION


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
class EvalSet:
    """The evaluation set: ``eval_realizations`` fresh realizations of every tuple, tuple-major."""

    u: np.ndarray  # (E, 150, 4) float32
    controls: np.ndarray  # (E, 4, P) float32
    intent: np.ndarray  # (E,) int32
    intensity: np.ndarray  # (E,) int32
    variant: np.ndarray  # (E,) int32: which valid variant of the intent (0 or 1)

    def __len__(self) -> int:
        return len(self.intent)


@dataclasses.dataclass(frozen=True)
class Library:
    train: Split
    heldout: Split
    meta: dict
    path: str
    evaluation: EvalSet | None = None  # None for a library file without one (an imported library)


def reduce_candidates(
    candidates: np.ndarray, num_controls: int, returns: np.ndarray | None = None, pin_start: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (ci) and R(c) on the spline basis, in float64 NumPy, then rounded once to float32.

    A demonstration starts from the rest command, so the first control is pinned to rest and the others
    are the least-squares fit of what remains; the gestures that return (``returns (B,)`` bool) also pin
    the last control to rest. ``pin_start=False`` (a lab's imported recordings) pins nothing: exactly
    :func:`splines.fit`. It is the same least
    squares as :func:`splines.fit` / :func:`splines.reconstruct`, but not through XLA's float32 einsum,
    whose accumulation order depends on the CPU's vector units: that made the library differ in the last
    bits between machines, and regeneration must be byte-identical everywhere.
    """
    steps = candidates.shape[-2]
    basis = splines.basis_np(steps, num_controls)
    rest = primitives.REST if pin_start else 0.0
    x = candidates.astype(np.float64) - rest
    returns = np.zeros(len(x), bool) if returns is None else np.asarray(returns, bool)
    controls = np.zeros((len(x), x.shape[-1], num_controls))
    for ret in (False, True):
        sel = returns == ret
        if not sel.any():
            continue
        free = slice(1 if pin_start else 0, num_controls - 1 if ret else num_controls)
        b = basis[:, free]
        pinv = np.linalg.solve(b.T @ b, b.T)
        controls[sel, :, free] = np.einsum("pt,btj->bjp", pinv, x[sel])
    controls = (controls + rest).astype(np.float32)
    raw = np.einsum("tp,bjp->btj", basis, controls.astype(np.float64)).astype(np.float32)
    return controls, raw, np.asarray(safety.make_safe(raw))


def _search(plan: dict, seed: list, config: BuildConfig, desc: str, progress: bool, trunk: str | None = None):
    """Screen candidates until every (intent, intensity, variant) has its planned count.

    ``plan``: ``(m, z) -> variants`` of the realizations wanted. Returns ``(found, tried, accepted,
    per_check)`` with ``found[(m, z, v)]`` a list of ``(controls, u)`` in acceptance order. Simulated on ``trunk``
    (None: the shipped trunk).
    """
    from tqdm import tqdm

    design = designs.get(config.version)  # v3's design plays primitives' own code: the same candidates
    tried = np.zeros((NUM_INTENTS, NUM_INTENSITIES), int)
    accepted = np.zeros((NUM_INTENTS, NUM_INTENSITIES), int)
    per_check = {c: 0 for c in screening.CHECKS}
    need = {(m, z, int(v)): int((vs == v).sum()) for (m, z), vs in plan.items() for v in np.unique(vs)}
    rngs = {key: np.random.default_rng([*seed, *key]) for key in need}
    found = {key: [] for key in need}
    need_max = max(need.values())
    per_round = max(config.candidates_per_round, need_max + need_max // 4 + 1)
    bar = tqdm(total=config.max_rounds, desc=desc, disable=not progress)
    for _ in range(config.max_rounds):
        todo = [k for k in need if len(found[k]) < need[k]]
        if not todo:
            break
        cand = np.stack(
            [
                primitives.candidate(rngs[k], k[0], k[1], k[2], design.variation, design=design)
                for k in todo
                for _ in range(per_round)
            ]
        )
        keys = np.repeat(np.array(todo), per_round, axis=0)
        controls, raw, u = reduce_candidates(cand, config.num_controls, primitives.RETURNS_MASK[keys[:, 0]])
        checks = screening.screen(raw, u, keys[:, 0], intensity=keys[:, 1], trunk=trunk)
        for c in screening.CHECKS:
            per_check[c] += int(checks[c].sum())
        for i, key in enumerate(map(tuple, keys)):
            tried[key[0], key[1]] += 1
            if checks["accepted"][i]:
                accepted[key[0], key[1]] += 1
                if len(found[key]) < need[key]:
                    found[key].append((controls[i], u[i]))
        bar.update(1)
    bar.close()
    short = {
        f"{INTENTS[m]}/{INTENSITIES[z]}/variant {v}": len(f)
        for (m, z, v), f in found.items()
        if len(f) < need[(m, z, v)]
    }
    if short:
        raise RuntimeError(f"screening kept too few realizations for {short}; raise BuildConfig.max_rounds")
    return found, tried, accepted, per_check


def fresh_realizations(
    plan: dict, seed: int, config: BuildConfig = BuildConfig(), progress: bool = False
) -> dict[tuple[int, int], np.ndarray]:
    """New screened realizations, drawn exactly as the library's: ``plan`` maps ``(intent, intensity)`` to
    the variant of each realization wanted; returns ``(intent, intensity) -> u (len(variants), T, N_u)``
    in the plan's order. The reference rows of the benchmark replay these (a perfect generator)."""
    plan = {k: np.asarray(v, int) for k, v in plan.items()}
    found, *_ = _search(plan, [seed, 77], config, "fresh realizations", progress)
    out = {}
    for key, vs in plan.items():
        taken = {int(v): iter(found[(*key, int(v))]) for v in np.unique(vs)}
        out[key] = np.stack([next(taken[int(v)])[1] for v in vs])
    return out


def build(config: BuildConfig = BuildConfig(), progress: bool = True, trunk: str | None = None) -> tuple[dict, dict]:
    """Generate, reduce and screen on ``trunk`` (None: the shipped trunk); returns (arrays, card). Deterministic in
    ``config.seed``. The card records a trunk of its own (path and sha256) under ``trunk``."""
    keep = {k: [] for k in ("u", "controls", "intent", "intensity", "realization", "variant", "texts")}
    design = designs.get(config.version)
    # One-to-many: how a tuple's realizations divide among its variants (designs.Design.train_variants).
    plan = {
        (m, z): design.train_variants(m, z, config.realizations)
        for m in range(NUM_INTENTS)
        for z in range(NUM_INTENSITIES)
    }
    found, tried, accepted, per_check = _search(plan, [config.seed], config, "screening rounds", progress, trunk)
    split_rng = np.random.default_rng([config.seed, 999])
    heldout = []
    for m in range(NUM_INTENTS):
        for z in range(NUM_INTENSITIES):
            text_rng = np.random.default_rng([config.seed, m, z, 7])
            if config.version == 3:
                held = int(split_rng.integers(config.realizations))
            else:  # v4, v5: a three-variant tuple holds out one of its doubled variant's realizations
                held = int(split_rng.choice(design.holdable(m, plan[(m, z)])))
            taken = {int(v): iter(found[(m, z, int(v))]) for v in np.unique(plan[(m, z)])}
            for r, v in enumerate(plan[(m, z)]):
                c, u = next(taken[int(v)])
                keep["controls"].append(c)
                keep["u"].append(u)
                keep["intent"].append(m)
                keep["intensity"].append(z)
                keep["realization"].append(r)
                keep["variant"].append(int(v))
                keep["texts"].append(
                    responses.response_texts(m, z, config.texts_per_record, text_rng, heldout=r == held)
                )
                heldout.append(r == held)
    # The evaluation set: the same generator and screening, another seed, balanced across variants.
    eval_plan = {
        (m, z): design.eval_variants(m, config.eval_realizations)
        for m in range(NUM_INTENTS)
        for z in range(NUM_INTENSITIES)
    }
    eval_found, *_ = _search(
        eval_plan, [config.seed + config.eval_seed_offset], config, "screening the evaluation set", progress, trunk
    )
    ev = {k: [] for k in ("u", "controls", "intent", "intensity", "variant")}
    for (m, z), vs in eval_plan.items():
        taken = {int(v): iter(eval_found[(m, z, int(v))]) for v in np.unique(vs)}
        for v in vs:
            c, u = next(taken[int(v)])
            for k, x in zip(ev, (u, c, m, z, int(v))):
                ev[k].append(x)
    arrays = {
        "u": np.asarray(keep["u"], np.float32),
        "controls": np.asarray(keep["controls"], np.float32),
        "intent": np.asarray(keep["intent"], np.int32),
        "intensity": np.asarray(keep["intensity"], np.int32),
        "realization": np.asarray(keep["realization"], np.int32),
        "variant": np.asarray(keep["variant"], np.int32),
        "heldout": np.asarray(heldout, bool),
        "texts": np.asarray(keep["texts"], dtype=np.str_),
        "eval_u": np.asarray(ev["u"], np.float32),
        "eval_controls": np.asarray(ev["controls"], np.float32),
        "eval_intent": np.asarray(ev["intent"], np.int32),
        "eval_intensity": np.asarray(ev["intensity"], np.int32),
        "eval_variant": np.asarray(ev["variant"], np.int32),
    }
    arrays["library_version"] = np.asarray(design.library_version)
    arrays["content_sha256"] = np.asarray(content_hash(arrays))
    card = {
        "format_version": FORMAT_VERSION,
        "library_version": design.library_version,
        "content_sha256": str(arrays["content_sha256"]),
        "config": dataclasses.asdict(config),
        "num_records": int(len(arrays["u"])),
        "num_train": int((~arrays["heldout"]).sum()),
        "num_heldout": int(arrays["heldout"].sum()),
        "num_eval": int(len(arrays["eval_u"])),
        "candidates_tried": int(tried.sum()),
        "candidates_accepted": int(accepted.sum()),
        "passed_per_check": per_check,
        "acceptance_rate": {
            f"{INTENTS[m]}/{INTENSITIES[z]}": round(float(accepted[m, z] / tried[m, z]), 4)
            for m in range(NUM_INTENTS)
            for z in range(NUM_INTENSITIES)
        },
        "regenerate": REGENERATE,
    }
    if sim.resolve_trunk(trunk) is not None:  # the shipped card stays as it was: no key = the shipped trunk
        card["trunk"] = sim.trunk_identity(trunk)
    return arrays, card


def content_hash(arrays: dict) -> str:
    """sha256 over the name, dtype, shape and bytes of every record array (not the hash itself)."""
    h = hashlib.sha256()
    for name in sorted(k for k in arrays if k != "content_sha256"):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def to_bytes(arrays: dict) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # zip entries carry a fixed date: same arrays, same bytes
    return buf.getvalue()


def save(arrays: dict, card: dict, path: str | Path = DEFAULT_PATH) -> Path:
    """Write ``path`` (.npz) and its card (.json) atomically; the card records the npz's sha256."""
    from jgrounding.io import write_atomic

    data = to_bytes(arrays)
    card = {**card, "sha256": hashlib.sha256(data).hexdigest()}
    path = Path(path)
    write_atomic(path, data)
    write_atomic(path.with_suffix(".json"), json.dumps(card, indent=1, sort_keys=True) + "\n")
    return path


def file_hash(path: str | Path = DEFAULT_PATH) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _split(arrays, mask) -> Split:
    return Split(
        u=arrays["u"][mask],
        controls=arrays["controls"][mask],
        intent=arrays["intent"][mask],
        intensity=arrays["intensity"][mask],
        realization=arrays["realization"][mask],
        texts=tuple(tuple(str(t) for t in row) for row in arrays["texts"][mask]),
    )


def load_library(path: str | Path | None = None) -> Library:
    """Load the demonstration library (``jgrounding/assets/library.npz`` by default) -> :class:`Library`."""
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
        raise ValueError(
            f"library {path} has format_version {card.get('format_version')!r}, expected "
            f"{FORMAT_VERSION}; regenerate with `{REGENERATE}`"
        )
    raw = path.read_bytes()
    if card.get("sha256") and hashlib.sha256(raw).hexdigest() != card["sha256"]:
        raise ValueError(
            f"library {path} does not match the sha256 in {card_path} (corrupt or edited); "
            f"regenerate with `{REGENERATE}`"
        )
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
    except Exception as e:  # zipfile / format errors of every kind
        raise ValueError(f"library {path} is not a readable npz ({e}); regenerate with `{REGENERATE}`")
    missing = {"u", "controls", "intent", "intensity", "realization", "heldout", "texts"} - set(arrays)
    if missing:
        raise ValueError(f"library {path} lacks arrays {sorted(missing)}; regenerate with `{REGENERATE}`")
    held = arrays["heldout"].astype(bool)
    evaluation = None
    if "eval_u" in arrays:
        evaluation = EvalSet(**{k: arrays[f"eval_{k}"] for k in ("u", "controls", "intent", "intensity", "variant")})
    return Library(
        train=_split(arrays, ~held), heldout=_split(arrays, held), meta=card, path=str(path), evaluation=evaluation
    )


# Brackets of the success metric (SPEC §3): expected values over the library, exact (every training
# record of a reference's pool replayed against each held-out target, no sampling noise).
BRACKET_RANGES = {  # at tau = 0.35: (low, high); the tuple mean is judged against the oracle
    "oracle": (0.45, 0.92),
    "wrong_intent": (0.0, 0.10),
    "far_intensity": (0.0, 0.30),
    "adjacent_intensity": (0.0, 0.80),
    "heldout_4gram_overlap": (0.0, 0.30),
}
TUPLE_MEAN_GAP = 0.10  # the tuple mean is at least this far below the oracle


def _bracket_pools(lib) -> dict:
    tr, ho = lib.train, lib.heldout
    same = tr.intent[None] == ho.intent[:, None]
    dz = np.abs(tr.intensity[None] - ho.intensity[:, None])
    return {
        "oracle": same & (dz == 0),
        "wrong_intent": ~same & (dz == 0),
        "far_intensity": same & (dz >= 2),
        "adjacent_intensity": same & (dz == 1),
    }


def bracket_distances(lib) -> dict[str, list[np.ndarray]]:
    """Per held-out target, the RMS of every replay of each bracket (the tuple mean: one value)."""
    from jgrounding.actuation import rms

    d = np.asarray(rms(lib.train.u[None], lib.heldout.u[:, None]))  # (64, 192)
    out = {name: [d[j, pool[j]] for j in range(len(d))] for name, pool in _bracket_pools(lib).items()}
    oracle = _bracket_pools(lib)["oracle"]
    means = np.stack([lib.train.u[oracle[j]].mean(0) for j in range(len(d))])
    out["tuple_mean"] = [np.atleast_1d(x) for x in np.asarray(rms(means, lib.heldout.u))]
    return out


def _ngrams(text: str, n: int = 4) -> set:
    words = "".join(c.lower() if c.isalnum() or c == "'" else " " for c in text).split()
    return {tuple(words[i : i + n]) for i in range(len(words) - n + 1)}


def heldout_overlap(lib, n: int = 4) -> float:
    """Share of the held-out responses' word n-grams that occur in training responses of the same intent."""
    shared = total = 0
    for m in np.unique(lib.heldout.intent):
        seen = set().union(*(_ngrams(t, n) for row, i in zip(lib.train.texts, lib.train.intent) if i == m for t in row))
        grams = [
            g for row, i in zip(lib.heldout.texts, lib.heldout.intent) if i == m for t in row for g in _ngrams(t, n)
        ]
        shared += sum(g in seen for g in grams)
        total += len(grams)
    return shared / max(total, 1)


def brackets(lib, taus=(0.25, 0.30, 0.35, 0.40, 0.45)) -> dict:
    """``{name: {tau: expected success}}`` for oracle, tuple mean, wrong intent, far and adjacent
    intensity, plus ``heldout_4gram_overlap`` (a share, independent of tau)."""
    dist = bracket_distances(lib)
    order = ("oracle", "tuple_mean", "wrong_intent", "far_intensity", "adjacent_intensity")
    out = {k: {float(t): float(np.mean([np.mean(x <= t) for x in dist[k]])) for t in taus} for k in order}
    out["heldout_4gram_overlap"] = heldout_overlap(lib)
    return out


def bracket_violations(b: dict, tau: float = 0.35) -> list[str]:
    """The bracket ranges of SPEC §3 that ``b`` (from :func:`brackets`) misses at ``tau``; empty if none."""
    bad = []
    for name, (lo, hi) in BRACKET_RANGES.items():
        v = b[name] if name == "heldout_4gram_overlap" else b[name][tau]
        if not lo <= v <= hi:
            bad.append(f"{name} {v:.3f} outside [{lo}, {hi}]")
    if b["tuple_mean"][tau] > b["oracle"][tau] - TUPLE_MEAN_GAP:
        bad.append(f"tuple mean {b['tuple_mean'][tau]:.3f} is not {TUPLE_MEAN_GAP} below oracle {b['oracle'][tau]:.3f}")
    return bad


def fold(lib: Library, k: int) -> Library:
    """The library re-split for cross-validation fold ``k``: realization ``k`` of every tuple held out,
    the other realizations trained on (``k`` in 0..realizations-1; fold of the shipped split: none)."""
    both = {f.name: (getattr(lib.train, f.name), getattr(lib.heldout, f.name)) for f in dataclasses.fields(Split)}
    arrays = {name: (a + b if name == "texts" else np.concatenate([a, b])) for name, (a, b) in both.items()}
    num = int(arrays["realization"].max()) + 1
    if not 0 <= k < num:
        raise ValueError(f"fold must be in 0..{num - 1}, got {k}")
    held = arrays["realization"] == k

    def part(mask):
        return Split(
            **{
                name: (tuple(t for t, keep in zip(v, mask) if keep) if name == "texts" else v[mask])
                for name, v in arrays.items()
            }
        )

    return dataclasses.replace(lib, train=part(~held), heldout=part(held), meta={**lib.meta, "fold": k})


def with_all_pairs(lib: Library) -> Library:
    """The library with every pair (train and held out) in ``train``: what the shipped model learns from.
    ``heldout`` stays as it is, so code that reads it still runs; the evaluation set is untouched."""
    tr, ho = lib.train, lib.heldout
    merged = Split(
        **{
            f.name: (getattr(tr, f.name) + getattr(ho, f.name))
            if f.name == "texts"
            else np.concatenate([getattr(tr, f.name), getattr(ho, f.name)])
            for f in dataclasses.fields(Split)
        }
    )
    return dataclasses.replace(lib, train=merged, meta={**lib.meta, "data": "all"})


def variant_midpoint(lib, taus=(0.25, 0.30, 0.35, 0.40, 0.45)) -> dict | None:
    """Success of a *hedge* on the one-to-many tuples: the midpoint of the means of the two variants'
    training realizations (weighted equally), replayed against the held-out target. ``None`` when the
    library file records no variants. Beside the brackets, not one of them: it shows how far apart the
    variants are relative to tau (a midpoint within tau of both variants succeeds whatever the target)."""
    arrays = np.load(lib.path)
    if "variant" not in arrays.files:
        return None
    u, m, z, v, held = (arrays[k] for k in ("u", "intent", "intensity", "variant", "heldout"))
    dist = []
    for j in np.flatnonzero(held):
        pool = ~held & (m == m[j]) & (z == z[j])
        if len(np.unique(v[pool])) < 2:
            continue
        mid = np.mean([u[pool & (v == k)].mean(0) for k in np.unique(v[pool])], axis=0)
        dist.append(float(np.sqrt(((mid - u[j]) ** 2).mean())))
    dist = np.asarray(dist)
    return {"tuples": len(dist), "success": {float(t): float(np.mean(dist <= t)) for t in taus}} if len(dist) else None
