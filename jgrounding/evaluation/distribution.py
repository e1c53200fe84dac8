"""Distribution metrics (SPEC §6, benchmark v3): score all K samples of a tuple against its evaluation set.

Grounding is one-to-many: a tuple has one or two valid *variants* and every realization of a variant
differs a little (onset, tempo, amplitude). One sample within tau of one held-out realization (Succ@tau)
cannot tell a generator that covers both variants from one that hedges between them or collapses onto
one. These metrics can. For samples ``x_k`` (k = 1..K) of tuple j and the tuple's evaluation
realizations ``e_i`` (library v3 and v4: 16 per tuple, balanced across variants, never trained on), with
``d_k = min_i RMS(x_k, e_i)`` and ``nn_k`` the nearest one:

- **Prec@tau** = mean_k [d_k <= tau] (tau = 0.35), **Prec@r** = mean_k [d_k <= r].
- **r** (:func:`radius`) comes from the within-variant spread: the ``RADIUS_QUANTILE`` quantile, over
  every evaluation realization, of the RMS to its nearest *other* realization of the same tuple and
  variant. A fresh realization of the tuple lands within r of the set that often; r is recorded with
  every result.
- **Between-variants share** = mean_k [r < d_k <= tau]: close enough for Succ@tau, but near no
  demonstration (the hedge between two variants lands here).
- **ModeCov@r** (split tuples): the share of a tuple's variants that receive at least
  ``COVER_SHARE`` of their fair share K / V of the samples within r (assigned to the variant of nn_k).
- **ModeBal** (split tuples): normalized entropy of how the samples within r divide among the variants,
  H(n_v / sum n) / log V (1 = even, 0 = one variant or none within r).
- **Multimodality ratio** = mean pairwise RMS of the K samples / mean pairwise RMS of the tuple's
  evaluation realizations (1 = as spread as the demonstrations; 0 = one motion).
- **Intent / intensity retrieval@1**: the nearest realization in the *whole* evaluation set (every tuple)
  has the asked intent / the asked intensity.
- **Frechet distance** (information only): between Gaussians fitted to the samples and to the evaluation
  set, on the trajectories subsampled to every 10th step (60 dimensions), pooled over tuples.

Every function takes plain arrays; :func:`score` is the one entry point the ablation, the references and
the benchmark scripts call.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding.evaluation.metrics import TAU_RMS

RADIUS_QUANTILE = 0.98
COVER_SHARE = 0.2  # a variant counts as covered with at least this share of its fair share of samples
HEADLINE = ("prec_tau", "prec_r", "between", "mode_cov", "mode_bal", "mm_ratio", "intent_ret", "intensity_ret")
LABELS = {
    "prec_tau": "Prec@τ",
    "prec_r": "Prec@r",
    "between": "Between",
    "mode_cov": "ModeCov",
    "mode_bal": "ModeBal",
    "mm_ratio": "MM ratio",
    "intent_ret": "Intent ret.",
    "intensity_ret": "Intensity ret.",
    "frechet": "Fréchet",
}


@jax.jit
def _sq_dist(a, b):
    """Mean squared difference ``(A, B)`` between flattened trajectories ``a (A, D)`` and ``b (B, D)``."""
    aa = jnp.sum(a * a, axis=1)[:, None]
    bb = jnp.sum(b * b, axis=1)[None, :]
    return jnp.maximum(aa + bb - 2.0 * a @ b.T, 0.0) / a.shape[1]


def rms_matrix(a, b, chunk: int = 4096) -> np.ndarray:
    """RMS ``(A, B)`` between trajectories ``a (A, T, C)`` and ``b (B, T, C)``, in float64-safe chunks."""
    a = np.asarray(a, np.float32).reshape(len(a), -1)
    b = jnp.asarray(np.asarray(b, np.float32).reshape(len(b), -1))
    out = [np.asarray(_sq_dist(jnp.asarray(a[i : i + chunk]), b)) for i in range(0, len(a), chunk)]
    return np.sqrt(np.concatenate(out) if out else np.zeros((0, b.shape[0]), np.float32))


def _tuples(ev) -> dict[tuple[int, int], np.ndarray]:
    key = ev.intent.astype(int) * 4 + ev.intensity.astype(int)
    return {(int(k) // 4, int(k) % 4): np.flatnonzero(key == k) for k in np.unique(key)}


def radius(ev, quantile: float = RADIUS_QUANTILE, from_step: int = 0) -> float:
    """r: the ``quantile`` of each evaluation realization's RMS to its nearest other realization of the same
    tuple and variant (the within-variant spread); ``from_step``: over steps ``from_step:`` only."""
    nn = []
    for idx in _tuples(ev).values():
        d = rms_matrix(ev.u[idx, from_step:], ev.u[idx, from_step:])
        same = ev.variant[idx][:, None] == ev.variant[idx][None]
        np.fill_diagonal(same, False)
        nn.extend(np.where(same, d, np.inf).min(axis=1))
    return float(np.quantile(np.asarray(nn), quantile))


def _pairwise_mean(x) -> float:
    if len(x) < 2:
        return 0.0
    d = rms_matrix(x, x)
    iu = np.triu_indices(len(x), 1)
    return float(d[iu].mean())


def frechet(x, y, stride: int = 10) -> float:
    """Frechet distance between Gaussians fitted to ``x (N, T, C)`` and ``y (M, T, C)`` (every ``stride``-th step)."""
    import warnings

    from scipy import linalg

    a = np.asarray(x, np.float64)[:, ::stride].reshape(len(x), -1)
    b = np.asarray(y, np.float64)[:, ::stride].reshape(len(y), -1)
    ma, mb = a.mean(0), b.mean(0)
    ca, cb = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    with warnings.catch_warnings():  # rank-deficient covariances (few samples): the estimate is still defined
        warnings.simplefilter("ignore")
        covmean = np.real(linalg.sqrtm(ca @ cb))
    return float(np.sum((ma - mb) ** 2) + np.trace(ca + cb - 2.0 * covmean))


@dataclasses.dataclass(frozen=True)
class Scores:
    """Per-tuple distribution metrics (arrays over the N scored tuples) and their means."""

    r: float
    tau: float
    per_tuple: dict  # name -> (N,) float array (NaN where undefined: mode metrics of single-variant tuples)
    split: np.ndarray  # (N,) bool: the tuple has two or more variants in the evaluation set
    frechet: float

    def mean(self, name: str, split_only: bool = False) -> float:
        """Mean over tuples (the mode metrics are defined on split tuples only); ``split_only``: over the
        tuples with two or more variants."""
        x = self.per_tuple[name][self.split] if split_only else self.per_tuple[name]
        return float(np.nanmean(x)) if np.isfinite(x).any() else float("nan")

    def summary(self) -> dict[str, float]:
        out = {k: self.mean(k) for k in HEADLINE}
        out["frechet"] = self.frechet
        out["prec_r_split"] = self.mean("prec_r", split_only=True)
        out["r"] = self.r
        return out


def score(
    samples, intent, intensity, ev, r: float | None = None, tau: float = TAU_RMS, with_frechet=True, from_step: int = 0
) -> Scores:
    """Distribution metrics of ``samples (N, K, T, C)`` drawn for tuples ``(intent[n], intensity[n])``
    against the evaluation set ``ev`` (:class:`jgrounding.library.EvalSet`); ``r`` defaults to :func:`radius`.

    ``from_step > 0`` compares only steps ``from_step:`` (samples and realizations; ``r`` from the same
    window): how a motion that starts elsewhere (mid-motion, start-conditioned) continues."""
    samples = np.asarray(samples, np.float32)
    if samples.ndim != 4:
        raise ValueError(f"samples must be (N tuples, K, T, C), got shape {samples.shape}")
    if from_step:
        samples = samples[:, :, from_step:]
        ev = dataclasses.replace(ev, u=ev.u[:, from_step:])
    n, k = samples.shape[:2]
    intent, intensity = np.asarray(intent).reshape(n), np.asarray(intensity).reshape(n)
    r = radius(ev) if r is None else float(r)
    groups = _tuples(ev)
    d_all = rms_matrix(samples.reshape(n * k, *samples.shape[2:]), ev.u).reshape(n, k, len(ev.u))
    nearest = d_all.argmin(axis=2)  # (N, K) over the whole evaluation set
    out = {name: np.full(n, np.nan) for name in (*HEADLINE, "modes_covered")}
    split = np.zeros(n, bool)
    demo_spread = {}
    for j in range(n):
        key = (int(intent[j]), int(intensity[j]))
        if key not in groups:
            raise ValueError(f"the evaluation set has no realizations of tuple {key}")
        idx = groups[key]
        d = d_all[j][:, idx]  # (K, R)
        dmin = d.min(axis=1)
        within_r = dmin <= r
        out["prec_tau"][j] = np.mean(dmin <= tau)
        out["prec_r"][j] = np.mean(within_r)
        out["between"][j] = np.mean((dmin > r) & (dmin <= tau))
        variants = np.unique(ev.variant[idx])
        if len(variants) > 1:
            split[j] = True
            assigned = ev.variant[idx][d.argmin(axis=1)][within_r]
            counts = np.array([(assigned == v).sum() for v in variants], float)
            fair = k / len(variants)
            out["mode_cov"][j] = np.mean(counts >= max(1.0, COVER_SHARE * fair))
            out["modes_covered"][j] = np.sum(counts >= max(1.0, COVER_SHARE * fair))  # how many variants
            p = counts / counts.sum() if counts.sum() else np.zeros_like(counts)
            ent = -np.sum(np.where(p > 0, p * np.log(np.where(p > 0, p, 1.0)), 0.0))
            out["mode_bal"][j] = ent / np.log(len(variants))
        if key not in demo_spread:
            demo_spread[key] = _pairwise_mean(ev.u[idx])
        out["mm_ratio"][j] = _pairwise_mean(samples[j]) / max(demo_spread[key], 1e-9)
        out["intent_ret"][j] = np.mean(ev.intent[nearest[j]] == key[0])
        out["intensity_ret"][j] = np.mean(ev.intensity[nearest[j]] == key[1])
    fd = frechet(samples.reshape(n * k, *samples.shape[2:]), ev.u) if with_frechet and n * k > 1 else float("nan")
    return Scores(r=r, tau=tau, per_tuple=out, split=split, frechet=fd)


# ---------------------------------------------------------------------------------------------------------
# Statistics over seeds (SPEC §6: std with ddof = 1; every "A beats B" with a test or an interval).


def mean_std(values) -> tuple[float, float]:
    """Mean and sample standard deviation (ddof = 1; 0 for a single value)."""
    x = np.asarray(values, float)
    return float(x.mean()), float(x.std(ddof=1)) if len(x) > 1 else 0.0


def std_error(values) -> float:
    x = np.asarray(values, float)
    return float(x.std(ddof=1) / np.sqrt(len(x))) if len(x) > 1 else float("nan")


def compare(a, b, *, draws: int = 10000, seed: int = 0) -> dict:
    """A vs B over seeds: Welch's t-test and a bootstrap 95 % interval of mean(a) - mean(b); the verdict is
    "higher" / "lower" only when the interval excludes 0 and Welch's p < 0.05, else "not resolved"."""
    from scipy import stats

    a, b = np.asarray(a, float), np.asarray(b, float)
    rng = np.random.default_rng(seed)
    boot = rng.choice(a, (draws, len(a))).mean(1) - rng.choice(b, (draws, len(b))).mean(1)
    lo, hi = np.quantile(boot, [0.025, 0.975])
    if len(a) > 1 and len(b) > 1 and (a.std() > 0 or b.std() > 0):
        t, p = stats.ttest_ind(a, b, equal_var=False)
    else:
        t, p = float("nan"), float("nan")
    diff = float(a.mean() - b.mean())
    # Both must agree: with few seeds the bootstrap interval is too narrow on its own.
    significant = np.isfinite(p) and p < 0.05 if np.isfinite(t) else lo > 0 or hi < 0
    verdict = "not resolved" if not significant else "higher" if lo > 0 else "lower" if hi < 0 else "not resolved"
    return {"diff": diff, "ci95": (float(lo), float(hi)), "t": float(t), "p": float(p), "verdict": verdict}


# ---------------------------------------------------------------------------------------------------------
# Reference rows: known answers scored by the same code. A metric is trusted only once it ranks them right.

REFERENCES = {
    "fresh_replay": "fresh replay (a perfect generator: new realizations, both variants)",
    "hedge": "variant midpoint (hedge: the mean of the two variants' means)",
    "collapse": "one variant only (collapse: fresh realizations of variant 0)",
    "tuple_mean": "tuple mean (the squared-loss regressor's answer)",
    "other_intent": "another intent (fresh realizations of the next intent, same intensity)",
    "adjacent_intensity": "same variant, adjacent intensity (fresh realizations one level away)",
}
# The brackets a test asserts before any method is ranked (benchmark v3).
BRACKETS = {  # name -> metric -> (low, high); the hedge is judged on the split tuples, where it is a hedge
    "fresh_replay": {"prec_r": (0.95, 1.0), "mode_cov": (0.95, 1.0)},
    "hedge": {"prec_r_split": (0.0, 0.10), "mode_cov": (0.0, 0.10)},
    "collapse": {"modes_covered": (0.9, 1.1)},  # one variant of two or three (mode_cov 0.5 of two; v3: 0.45-0.55)
    "other_intent": {"intent_ret": (0.0, 0.05)},
    "adjacent_intensity": {"intensity_ret": (0.0, 0.20)},
}


# What the reference rows are a function of besides the library's evaluation set: the design, screening and
# simulation code that draws fresh realizations (hashed into the cache key, so an edit there recomputes).
_REFERENCE_SOURCES = ("library", "sim", "actuation", "safety.py", "evaluation/distribution.py", "assets/trunk.xml")


def reference_key(lib, k: int, seed: int) -> str:
    """The content hash :func:`reference_samples` caches under: the evaluation set's arrays, the design version,
    ``k``, ``seed``, MuJoCo's and numpy's versions and every source file in :data:`_REFERENCE_SOURCES`."""
    import mujoco

    from jgrounding import io
    from jgrounding.library import designs

    ev = lib.evaluation
    files = []
    for name in _REFERENCE_SOURCES:
        path = io.package_file(name)
        files += sorted(path.rglob("*.py")) if path.is_dir() else [path]
    arrays = [np.ascontiguousarray(a).tobytes() for a in (ev.u, ev.intent, ev.intensity, ev.variant)]
    return io.content_key(
        "reference_samples v1",
        str(designs.of_library(lib).version),
        str(k),
        str(seed),
        mujoco.__version__,
        np.__version__,
        *arrays,
        *files,
    )


def reference_samples(lib, k: int = 30, seed: int = 2, *, cache: bool = True) -> dict[str, np.ndarray]:
    """``name -> (64, k, T, C)`` samples of every reference row for the 64 tuples in (intent, intensity) order.

    Drawing them screens every fresh realization in simulation (about a minute on 2 cores), and they are a pure
    function of the evaluation set, the design and the code that draws them: with ``cache`` they are kept in
    :func:`jgrounding.io.data_cache_dir` under a content hash of all of those (written atomically), so a
    second call (``make ablation`` then ``experiments.references``) loads them instead."""
    import io as _io

    from jgrounding.io import data_cache_dir, write_atomic

    folder = data_cache_dir() if cache and lib.evaluation is not None else None
    path = None if folder is None else folder / f"reference_samples-{reference_key(lib, k, seed)[:24]}.npz"
    if path is not None and path.exists():
        try:
            with np.load(path) as f:
                return {name: f[name] for name in f.files}
        except (OSError, ValueError):  # a damaged entry: draw again and replace it
            pass
    out = _draw_reference_samples(lib, k, seed)
    if path is not None:
        buf = _io.BytesIO()
        np.savez(buf, **out)
        try:
            write_atomic(path, buf.getvalue())
        except OSError:  # a read-only cache: the result stands, it is only not kept
            pass
    return out


def _draw_reference_samples(lib, k: int, seed: int) -> dict[str, np.ndarray]:
    import functools

    from jgrounding.library import BuildConfig, designs
    from jgrounding.library import fresh_realizations as fresh_of

    ev = lib.evaluation
    if ev is None:
        raise ValueError("this library file has no evaluation set; regenerate it with `python -m tools.build_library`")
    design = designs.of_library(lib)  # the references are drawn from the design the library was built with
    fresh_realizations = functools.partial(fresh_of, config=BuildConfig(version=design.version))
    tuples = sorted(_tuples(ev))
    both = {t: design.eval_variants(t[0], k) for t in tuples}  # every variant, balanced
    fresh = fresh_realizations(both, seed)
    collapse = fresh_realizations({t: np.zeros(k, int) for t in tuples}, seed + 1)
    groups = _tuples(ev)
    out = {"fresh_replay": np.stack([fresh[t] for t in tuples]), "collapse": np.stack([collapse[t] for t in tuples])}
    hedge, mean = [], []
    for t in tuples:
        u, v = ev.u[groups[t]], ev.variant[groups[t]]
        mean.append(np.repeat(u.mean(0)[None], k, 0))
        hedge.append(np.repeat(np.mean([u[v == w].mean(0) for w in np.unique(v)], axis=0)[None], k, 0))
    out["hedge"], out["tuple_mean"] = np.stack(hedge), np.stack(mean)
    num_intents = int(ev.intent.max()) + 1
    out["other_intent"] = np.stack([fresh[((m + 1) % num_intents, z)] for m, z in tuples])
    # the same variant one intensity level away (the next one up; emphatic's is pronounced)
    nearby = {(m, z): (m, z + 1 if z < 3 else z - 1) for m, z in tuples}
    adj = fresh_realizations({nearby[t]: both[t] for t in tuples}, seed + 2)
    out["adjacent_intensity"] = np.stack([adj[nearby[t]] for t in tuples])
    return out


def reference_scores(lib, k: int = 30, seed: int = 2, r: float | None = None) -> dict[str, Scores]:
    """Every reference row scored against the evaluation set (tuples in (intent, intensity) order)."""
    ev = lib.evaluation
    r = radius(ev) if r is None else r
    tuples = np.array(sorted(_tuples(ev)))
    return {name: score(x, tuples[:, 0], tuples[:, 1], ev, r=r) for name, x in reference_samples(lib, k, seed).items()}


def bracket_failures(scores: dict[str, Scores]) -> list[str]:
    """The reference brackets (:data:`BRACKETS`) that ``scores`` miss; mode metrics over split tuples."""
    bad = []
    for name, want in BRACKETS.items():
        for metric, (lo, hi) in want.items():
            v = scores[name].mean(metric.removesuffix("_split"), split_only=metric.endswith("_split"))
            if not lo <= v <= hi:
                bad.append(f"{name}: {metric} {v:.3f} outside [{lo}, {hi}]")
    return bad
