"""Participants without people: ratings drawn from known per-condition distributions, with a participant
trait, order effects and dropouts, to validate the study end to end (the server, the database and the
browser: tests/study/test_study_browser.py) and the analysis in pure numpy (:func:`validate`,
``python -m experiments.study_validation``).

A participant ``i`` has a trait ``t_i ~ N(0, 1)``; the latent response to condition ``c``, dimension ``d`` is
``z = sqrt(rho) t_i + sqrt(1 - rho) e + shift_p`` (``e ~ N(0, 1)``, ``shift_p`` the order effect of block
position ``p``), and the rating is the category of ``Phi(z)`` in the cumulative distribution of ``c``, ``d``:
without an order effect every rating has exactly its condition's distribution, and a participant's ratings
correlate through the trait. After each block a participant drops out with probability ``dropout``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import stats

from jgrounding.study.design import DIMENSIONS, POSITIVE_FROM
from jgrounding.study.latin import williams

# The paper's positive-rating ratios (Sec. IV-B, Fig. 6): AV-only, AV with the grounded trunk.
PAPER_RATIOS = {
    "av_only": (0.36, 0.50, 0.27, 0.86, 0.30, 0.46),
    "trunk": (0.80, 0.80, 0.89, 0.83, 0.79, 0.82),
}


def likert(positive: float, scale: int = 5) -> np.ndarray:
    """A distribution over ``1..scale`` with ``P(rating >= 4) = positive``: the positive mass split 55/45
    over 4 and 5, the rest 50/30/20 over 3, 2, 1 (5-point scale)."""
    if scale != 5:
        raise ValueError("likert() builds 5-point distributions")
    q = 1.0 - positive
    return np.array([0.2 * q, 0.3 * q, 0.5 * q, 0.55 * positive, 0.45 * positive])


@dataclasses.dataclass(frozen=True)
class TrueRatings:
    """What simulated participants answer: ``probabilities (C, D, scale)`` over ratings ``1..scale``."""

    conditions: tuple[str, ...]
    dimensions: tuple[str, ...]
    probabilities: np.ndarray  # (C, D, scale), rows sum to 1
    correlation: float = 0.3  # rho: share of the latent variance that is the participant's trait
    order_shift: float = 0.0  # latent shift per block position, centred (positions -> (p - (C-1)/2) * shift)
    dropout: float = 0.0  # probability of leaving after each block

    def shifts(self) -> np.ndarray:
        c = len(self.conditions)
        return self.order_shift * (np.arange(c) - (c - 1) / 2)

    def positive_at(self) -> np.ndarray:
        """``(C, D, positions)``: P(rating >= 4) of each condition and dimension at each block position."""
        below = self.probabilities[..., : POSITIVE_FROM - 1].sum(-1)  # P(rating <= 3)
        threshold = stats.norm.ppf(np.clip(below, 1e-12, 1 - 1e-12))
        return 1.0 - stats.norm.cdf(threshold[..., None] - self.shifts())


def paper_model(**kwargs) -> TrueRatings:
    """The paper's two conditions and six dimensions at its reported positive ratios."""
    probs = np.stack([np.stack([likert(p) for p in PAPER_RATIOS[c]]) for c in ("av_only", "trunk")])
    return TrueRatings(("av_only", "trunk"), DIMENSIONS, probs, **kwargs)


def null_model(model: TrueRatings) -> TrueRatings:
    """No effect: every condition rated like the first one."""
    probs = np.broadcast_to(model.probabilities[:1], model.probabilities.shape).copy()
    return dataclasses.replace(model, probabilities=probs)


def _category(model: TrueRatings, c: int, u: np.ndarray) -> np.ndarray:
    """Ratings ``1..scale`` of uniforms ``u (..., D)`` through condition ``c``'s cumulative distributions."""
    cdf = np.cumsum(model.probabilities[c], -1)  # (D, scale)
    return 1 + np.sum(u[..., :, None] > cdf[:, :-1], -1)


def simulate_study(rng: np.random.Generator, model: TrueRatings, participants: int):
    """One study: ``ratings (P, C, D)`` (NaN after a dropout) and ``positions (P, C)`` from Williams rows in
    enrolment order."""
    rows = np.asarray(williams(len(model.conditions)))
    order = rows[np.arange(participants) % len(rows)]  # (P, C): condition at each position
    positions = np.argsort(order, axis=1)  # (P, C): position of each condition
    n_c, n_d = len(model.conditions), len(model.dimensions)
    trait = rng.standard_normal((participants, 1, 1))
    noise = rng.standard_normal((participants, n_c, n_d))
    z = np.sqrt(model.correlation) * trait + np.sqrt(1 - model.correlation) * noise
    z = z + model.shifts()[positions][..., None]
    u = stats.norm.cdf(z)
    ratings = np.stack([_category(model, c, u[:, c]) for c in range(n_c)], axis=1).astype(np.float64)
    stays = rng.random((participants, n_c)) >= model.dropout  # leaves after block p with prob dropout
    reached = np.cumprod(np.concatenate([np.ones((participants, 1), bool), stays[:, :-1]], 1), 1).astype(bool)
    seen = np.take_along_axis(reached, positions, 1)  # (P, C): the condition's block was reached
    ratings[~seen] = np.nan
    return ratings, np.where(seen, positions, -1)


def true_ratios(model: TrueRatings, participants: int) -> np.ndarray:
    """``(C, D)``: what the pooled positive ratio of a condition estimates in such a study: the positive
    probability at each position, weighted by the expected number of ratings there (Williams rows in
    enrolment order, fewer at later positions by the dropout)."""
    rows = np.asarray(williams(len(model.conditions)))
    positions = np.argsort(rows[np.arange(participants) % len(rows)], axis=1)  # (P, C)
    weight = (1 - model.dropout) ** positions  # P(block reached)
    at = model.positive_at()  # (C, D, positions)
    out = np.empty(at.shape[:2])
    for c in range(len(model.conditions)):
        w = np.bincount(positions[:, c], weight[:, c], minlength=at.shape[2])
        out[c] = at[c] @ w / w.sum()
    return out


@dataclasses.dataclass
class SimulatedParticipant:
    """One simulated participant answering through the pages (tests/study/test_study_browser.py)."""

    model: TrueRatings
    rng: np.random.Generator

    def __post_init__(self):
        self.trait = self.rng.standard_normal()

    def rate(self, condition: str, position: int) -> dict[str, int]:
        c = self.model.conditions.index(condition)
        noise = self.rng.standard_normal(len(self.model.dimensions))
        z = np.sqrt(self.model.correlation) * self.trait + np.sqrt(1 - self.model.correlation) * noise
        u = stats.norm.cdf(z + self.model.shifts()[position])
        return dict(zip(self.model.dimensions, (int(v) for v in _category(self.model, c, u))))

    def drops_out(self) -> bool:
        return bool(self.rng.random() < self.model.dropout)


def validate(rng: np.random.Generator, model: TrueRatings, studies: int, participants: int) -> dict:
    """Run ``studies`` simulated studies of ``participants`` each through the analysis: the 95% Wilson
    intervals' coverage of :func:`true_ratios`, the estimates' error, and the paired tests' false-positive
    rate under :func:`null_model` (per test at 0.05, and family-wise after Holm over the dimensions), and
    the Wilcoxon test's exact level given each null test's ranks (:func:`jgrounding.study.analysis.wilcoxon_level`:
    its false-positive rate under symmetric differences, free of the sign draws' Monte Carlo noise)."""
    from jgrounding.study import analysis

    truth = true_ratios(model, participants)
    null = null_model(model)
    covered, errors, n_cells = 0, [], 0
    fp = {"wilcoxon": 0, "mcnemar": 0}
    fw = {"wilcoxon": 0, "mcnemar": 0}
    power = {"wilcoxon": 0, "mcnemar": 0}
    tests, levels = 0, []
    for _ in range(studies):
        ratings, positions = simulate_study(rng, model, participants)
        desc = analysis.describe(ratings, model.conditions, model.dimensions)
        for r in desc:
            t = truth[model.conditions.index(r["condition"]), model.dimensions.index(r["dimension"])]
            covered += int(r["lo"] <= t <= r["hi"])
            errors.append(r["ratio"] - t)
            n_cells += 1
        comp = analysis.compare(ratings, positions, 0, 1, model.dimensions)
        ratings0, positions0 = simulate_study(rng, null, participants)
        comp0 = analysis.compare(ratings0, positions0, 0, 1, model.dimensions)
        for test in fp:
            fp[test] += sum(r[f"{test}_p"] < analysis.ALPHA for r in comp0)
            fw[test] += int(any(r[f"{test}_p_holm"] < analysis.ALPHA for r in comp0))
            power[test] += sum(r[f"{test}_p_holm"] < analysis.ALPHA for r in comp)
        tests += len(comp0)
        for d in range(len(model.dimensions)):
            x, y = ratings0[:, 0, d], ratings0[:, 1, d]
            ok = ~np.isnan(x) & ~np.isnan(y)
            levels.append(analysis.wilcoxon_level(x[ok], y[ok]))
    errors = np.asarray(errors)
    return {
        "studies": studies,
        "participants": participants,
        "coverage": covered / n_cells,
        "intervals": n_cells,
        "mean_error": float(errors.mean()),
        "rmse": float(np.sqrt(np.mean(errors**2))),
        "false_positive": {k: v / tests for k, v in fp.items()},
        "familywise_false_positive": {k: v / studies for k, v in fw.items()},
        "wilcoxon_level": {"mean": float(np.mean(levels)), "max": float(np.max(levels))},
        "power": {k: v / tests for k, v in power.items()},
    }
