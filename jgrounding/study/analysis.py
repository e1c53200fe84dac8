"""The study's analysis (``python -m jgrounding.study analyze DB``), as Sec. IV-B reports it and beyond.

Per dimension and condition: the positive-rating ratio (ratings >= 4) with its 95% Wilson interval, and the
median with its IQR. Between two conditions, on the participants who rated both (complete pairs): the
Wilcoxon signed-rank test on the ratings (zero differences dropped, mid-ranks for ties; the p-value from the
exact sign-flip distribution of the rank sum given the observed ranks, ties included, up to ``EXACT_UP_TO``
non-zero differences, the normal approximation with the tie and continuity corrections beyond) and the exact
McNemar test on positive-or-not (two-sided binomial on the discordant pairs), each Holm-corrected over the
questionnaire's dimensions; effect sizes: the matched-pairs rank-biserial correlation and the difference in
positive ratio (with a paired Wald interval). Order: each condition's positive ratio by block position, a
Kruskal-Wallis test of its ratings across positions, and a Mann-Whitney test of the paired differences between
the participants who saw one condition first and those who saw the other first (condition x order).
Power: participants needed to detect a difference in paired positive ratios with McNemar's test (Connor 1987).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import stats

from jgrounding.study.design import POSITIVE_FROM

ALPHA = 0.05


def wilson(k, n, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval of a binomial proportion ``k / n`` (elementwise; ``n = 0`` gives ``(0, 1)``)."""
    k, n = np.asarray(k, np.float64), np.asarray(n, np.float64)
    z = stats.norm.ppf(0.5 + confidence / 2)
    safe = np.maximum(n, 1)
    p = k / safe
    centre = (p + z * z / (2 * safe)) / (1 + z * z / safe)
    half = z * np.sqrt(p * (1 - p) / safe + z * z / (4 * safe * safe)) / (1 + z * z / safe)
    lo, hi = np.clip(centre - half, 0, 1), np.clip(centre + half, 0, 1)
    return np.where(n > 0, lo, 0.0), np.where(n > 0, hi, 1.0)


def median_iqr(values) -> tuple[float, float, float]:
    """(median, first quartile, third quartile), linear interpolation (numpy's default)."""
    v = np.asarray(values, np.float64)
    if not len(v):
        return math.nan, math.nan, math.nan
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return float(med), float(q1), float(q3)


def mcnemar_exact(a_positive, b_positive) -> tuple[int, int, float]:
    """``(b, c, p)``: pairs positive only under A, only under B, and the exact two-sided McNemar p-value
    ``min(1, 2 P(X <= min(b, c)))`` with ``X ~ Binomial(b + c, 1/2)``."""
    a, b_ = np.asarray(a_positive, bool), np.asarray(b_positive, bool)
    only_a, only_b = int(np.sum(a & ~b_)), int(np.sum(~a & b_))
    n = only_a + only_b
    p = 1.0 if n == 0 else min(1.0, 2.0 * float(stats.binom.cdf(min(only_a, only_b), n, 0.5)))
    return only_a, only_b, p


EXACT_UP_TO = 400  # non-zero differences: the exact sign-flip distribution up to here, the normal one beyond


def signed_rank_null(ranks) -> np.ndarray:
    """The exact null distribution of the signed-rank statistic ``T+`` (the sum of the ranks of the positive
    differences) given the ranks of the non-zero |differences|, mid-ranks of ties included: every one of the
    ``2^n`` sign patterns equally likely (the sign-flip permutation distribution). Entry ``j`` is
    ``P(2 T+ = j)`` (doubled ranks are integers), ``j = 0 .. 2 sum(ranks)``; computed by convolving, per
    distinct rank ``r`` held by ``m`` differences, ``r`` times a Binomial(``m``, 1/2)."""
    doubled = np.rint(2 * np.asarray(ranks, np.float64)).astype(np.int64)
    dist = np.zeros(int(doubled.sum()) + 1)
    dist[0], top = 1.0, 0
    for value, m in zip(*np.unique(doubled, return_counts=True)):
        pmf = stats.binom.pmf(np.arange(m + 1), m, 0.5)
        new = np.zeros_like(dist)
        for k in range(m + 1):  # k of the m differences of this rank positive
            new[k * value : k * value + top + 1] += pmf[k] * dist[: top + 1]
        dist, top = new, top + int(m * value)
    return dist


def _two_sided(dist: np.ndarray) -> np.ndarray:
    """The exact two-sided p-value at every value of a null distribution: ``min(1, 2 min(cdf, sf))``."""
    return np.minimum(1.0, 2.0 * np.minimum(np.cumsum(dist), np.cumsum(dist[::-1])[::-1]))


def wilcoxon_level(x, y, alpha: float = ALPHA) -> float:
    """The actual level of :func:`wilcoxon` at ``alpha`` for data with these |differences|: the probability,
    over the ``2^n`` equally likely sign patterns of the non-zero differences, of a p-value below ``alpha``.
    At most ``alpha`` by construction (the exact p-value), below it where ties make the statistic coarse;
    what a test at 0.05 rejects under a true null of symmetric differences. NaN beyond ``EXACT_UP_TO``."""
    d = np.asarray(y, np.float64) - np.asarray(x, np.float64)
    d = d[d != 0]
    if len(d) > EXACT_UP_TO:
        return math.nan
    dist = signed_rank_null(stats.rankdata(np.abs(d))) if len(d) else np.ones(1)
    return float(dist[_two_sided(dist) < alpha].sum())


def wilcoxon(x, y, exact_up_to: int = EXACT_UP_TO) -> tuple[float, float]:
    """``(W, p)`` of the Wilcoxon signed-rank test of ``y - x`` (two-sided; ``W`` = the smaller rank sum).

    Zero differences are dropped (Wilcoxon's ``zero_method="wilcox"``) and ties get mid-ranks. Up to
    ``exact_up_to`` non-zero differences the p-value is exact: ``min(1, 2 min(P(T+ <= t), P(T+ >= t)))``
    under :func:`signed_rank_null`, the distribution given the observed ranks (without ties it is the
    classical exact distribution), so the test never rejects a true null of symmetric differences more often
    than its level, ties and zeros or not (a Likert scale has many of both). Beyond, the normal
    approximation with the tie correction and the continuity correction (as ``scipy.stats.wilcoxon(d,
    zero_method="wilcox", correction=True, method="asymptotic")``): mean ``n (n + 1) / 4``, variance
    ``n (n + 1) (2n + 1) / 24 - sum(t^3 - t) / 48`` over tie groups of size ``t``,
    ``z = max(|T+ - mean| - 1/2, 0) / sd``. No non-zero difference: ``(0, 1)``."""
    d = np.asarray(y, np.float64) - np.asarray(x, np.float64)
    d = d[d != 0]
    if not len(d):
        return 0.0, 1.0
    ranks = stats.rankdata(np.abs(d))
    plus, minus = float(ranks[d > 0].sum()), float(ranks[d < 0].sum())
    n = len(d)
    if n <= exact_up_to:
        p = float(_two_sided(signed_rank_null(ranks))[round(2 * plus)])
    else:
        _, ties = np.unique(np.abs(d), return_counts=True)
        sd = math.sqrt(n * (n + 1) * (2 * n + 1) / 24 - float(np.sum(ties**3 - ties)) / 48)
        z = max(abs(plus - n * (n + 1) / 4) - 0.5, 0.0) / sd
        p = 2.0 * float(stats.norm.sf(z))
    return min(plus, minus), min(1.0, p)


def rank_biserial(x, y) -> float:
    """Matched-pairs rank-biserial correlation of ``y - x``: ``(T+ - T-) / (T+ + T-)`` over the ranks of the
    non-zero |differences| (in [-1, 1]; positive: ``y`` rated higher)."""
    d = np.asarray(y, np.float64) - np.asarray(x, np.float64)
    d = d[d != 0]
    if not len(d):
        return 0.0
    ranks = stats.rankdata(np.abs(d))
    plus, minus = ranks[d > 0].sum(), ranks[d < 0].sum()
    return float((plus - minus) / (plus + minus))


def holm(pvalues: Sequence[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values (family-wise error control), in the order given."""
    p = np.asarray(pvalues, np.float64)
    m = len(p)
    order = np.argsort(p)
    adjusted = np.maximum.accumulate((m - np.arange(m)) * p[order])
    out = np.empty(m)
    out[order] = np.minimum(adjusted, 1.0)
    return out


def paired_difference(a_positive, b_positive, confidence: float = 0.95) -> tuple[float, float, float]:
    """``(p_B - p_A, lo, hi)``: the difference in positive ratio of paired ratings with its Wald interval
    (standard error ``sqrt((b + c) - (c - b)^2 / n) / n`` over discordant counts ``b``, ``c``)."""
    a, b_ = np.asarray(a_positive, bool), np.asarray(b_positive, bool)
    n = len(a)
    if not n:
        return math.nan, math.nan, math.nan
    only_a, only_b = np.sum(a & ~b_), np.sum(~a & b_)
    diff = float((only_b - only_a) / n)
    se = math.sqrt(max(only_a + only_b - (only_b - only_a) ** 2 / n, 0.0)) / n
    z = stats.norm.ppf(0.5 + confidence / 2)
    return diff, max(-1.0, diff - z * se), min(1.0, diff + z * se)


def participants_needed(
    p_a: float, p_b: float, discordant: float | None = None, *, alpha: float = ALPHA, power: float = 0.8
) -> int:
    """Participants needed to detect positive ratios ``p_a`` -> ``p_b`` on paired ratings with McNemar's test
    (two-sided ``alpha``, the given ``power``), by Connor's (1987) normal approximation:

        n = (z_{1-alpha/2} sqrt(psi) + z_{power} sqrt(psi - delta^2))^2 / delta^2,  delta = p_b - p_a,

    where ``psi`` is the discordant proportion P(positive under exactly one condition). ``discordant`` None
    assumes the two ratings independent, ``psi = p_a (1 - p_b) + (1 - p_a) p_b`` (conservative when a
    participant's ratings correlate positively); ``psi`` is at least ``|delta|``."""
    delta = p_b - p_a
    if not (0 <= p_a <= 1 and 0 <= p_b <= 1) or delta == 0:
        raise ValueError(f"give two different positive ratios in [0, 1], got {p_a!r} and {p_b!r}")
    psi = p_a * (1 - p_b) + (1 - p_a) * p_b if discordant is None else discordant
    psi = max(psi, abs(delta))
    za, zb = stats.norm.ppf(1 - alpha / 2), stats.norm.ppf(power)
    return math.ceil((za * math.sqrt(psi) + zb * math.sqrt(max(psi - delta * delta, 0.0))) ** 2 / (delta * delta))


# --- from the database's long table to the report ----------------------------------------------------------


def arrays(rows: list[dict], conditions: Sequence[str], dimensions: Sequence[str]):
    """``(ratings, positions, participants)``: ``ratings (P, C, D)`` float with NaN where missing, and each
    participant's block position of each condition ``positions (P, C)`` (-1 where never seen)."""
    ids = sorted({r["participant_id"] for r in rows}, key=lambda p: (len(p), p))
    pi = {p: i for i, p in enumerate(ids)}
    ci, di = {c: i for i, c in enumerate(conditions)}, {d: i for i, d in enumerate(dimensions)}
    ratings = np.full((len(ids), len(conditions), len(dimensions)), np.nan)
    positions = np.full((len(ids), len(conditions)), -1, np.int64)
    for r in rows:
        if r["condition"] in ci and r["dimension"] in di:
            ratings[pi[r["participant_id"]], ci[r["condition"]], di[r["dimension"]]] = r["value"]
            positions[pi[r["participant_id"]], ci[r["condition"]]] = r["position"]
    return ratings, positions, ids


def describe(ratings: np.ndarray, conditions, dimensions, confidence: float = 0.95) -> list[dict]:
    """Per condition and dimension: n, positive ratio with its Wilson interval, median and IQR."""
    out = []
    for c, cond in enumerate(conditions):
        for d, dim in enumerate(dimensions):
            v = ratings[:, c, d]
            v = v[~np.isnan(v)]
            k = int(np.sum(v >= POSITIVE_FROM))
            lo, hi = wilson(k, len(v), confidence)
            med, q1, q3 = median_iqr(v)
            ratio = k / len(v) if len(v) else math.nan
            row = dict(condition=cond, dimension=dim, n=len(v), positive=k, ratio=ratio, lo=float(lo), hi=float(hi))
            out.append({**row, "median": med, "q1": q1, "q3": q3})
    return out


def compare(ratings: np.ndarray, positions: np.ndarray, a: int, b: int, dimensions) -> list[dict]:
    """Condition ``b`` against ``a`` on each dimension (complete pairs): both tests, Holm over the dimensions,
    both effect sizes, and the condition x order test of the differences."""
    out = []
    for d, dim in enumerate(dimensions):
        x, y = ratings[:, a, d], ratings[:, b, d]
        ok = ~np.isnan(x) & ~np.isnan(y)
        x, y, first = x[ok], y[ok], positions[ok, a] < positions[ok, b]
        w, p_w = wilcoxon(x, y)
        only_a, only_b, p_m = mcnemar_exact(x >= POSITIVE_FROM, y >= POSITIVE_FROM)
        diff, lo, hi = paired_difference(x >= POSITIVE_FROM, y >= POSITIVE_FROM)
        diffs = y - x
        if first.any() and (~first).any() and np.ptp(diffs) > 0:
            p_order = float(stats.mannwhitneyu(diffs[first], diffs[~first], alternative="two-sided").pvalue)
        else:
            p_order = math.nan
        out.append(
            dict(
                dimension=dim,
                pairs=int(ok.sum()),
                wilcoxon_w=w,
                wilcoxon_p=p_w,
                rank_biserial=rank_biserial(x, y),
                only_a=only_a,
                only_b=only_b,
                mcnemar_p=p_m,
                ratio_difference=diff,
                difference_lo=lo,
                difference_hi=hi,
                order_p=p_order,
            )
        )
    for test in ("wilcoxon", "mcnemar"):
        for row, adj in zip(out, holm([r[f"{test}_p"] for r in out])):
            row[f"{test}_p_holm"] = float(adj)
    return out


def order_effects(ratings: np.ndarray, positions: np.ndarray, conditions, dimensions) -> list[dict]:
    """Per condition and dimension: the positive ratio at each block position, and a Kruskal-Wallis test of
    the ratings across positions (NaN where fewer than two positions hold ratings or all ratings are equal)."""
    out = []
    for c, cond in enumerate(conditions):
        for d, dim in enumerate(dimensions):
            groups, ratio = [], {}
            for pos in range(len(conditions)):
                v = ratings[(positions[:, c] == pos) & ~np.isnan(ratings[:, c, d]), c, d]
                if len(v):
                    groups.append(v)
                    ratio[pos] = float(np.mean(v >= POSITIVE_FROM))
            allv = np.concatenate(groups) if groups else np.zeros(0)
            p = float(stats.kruskal(*groups).pvalue) if len(groups) > 1 and np.ptp(allv) > 0 else math.nan
            out.append(dict(condition=cond, dimension=dim, ratio_by_position=ratio, kruskal_p=p))
    return out


def analyze(
    rows: list[dict],
    conditions: Sequence[str],
    dimensions: Sequence[str],
    deltas=(0.1, 0.15, 0.2),
    *,
    exclude_withdrawn: bool = False,
) -> dict:
    """The whole report of a study's long table (:meth:`jgrounding.study.store.Store.long_ratings`).

    Every participant's ratings count by default, a withdrawn participant's too (intention to treat: what
    they rated before leaving). ``exclude_withdrawn`` drops the participants whose ``status`` is
    ``withdrawn`` (the operator withdrew them; one who just stopped coming stays ``active`` and counts);
    the report names them either way (``withdrawn``, ``withdrawn_excluded``)."""
    withdrawn = sorted({r["participant_id"] for r in rows if r.get("status") == "withdrawn"}, key=lambda p: (len(p), p))
    if exclude_withdrawn:
        rows = [r for r in rows if r.get("status") != "withdrawn"]
    ratings, positions, ids = arrays(rows, conditions, dimensions)
    base = 0
    comparisons = [(a, b) for a in range(len(conditions)) for b in range(a + 1, len(conditions))]
    desc = describe(ratings, conditions, dimensions)
    baseline = [r for r in desc if r["condition"] == conditions[base] and r["n"]]
    p_a = float(np.mean([r["ratio"] for r in baseline])) if baseline else 0.5
    power = [
        dict(delta=dl, baseline_ratio=round(p_a, 4), participants=participants_needed(p_a, min(p_a + dl, 1.0)))
        for dl in deltas
        if p_a + dl <= 1
    ]
    return {
        "participants": len(ids),
        "withdrawn": withdrawn,
        "withdrawn_excluded": bool(exclude_withdrawn),
        "conditions": list(conditions),
        "dimensions": list(dimensions),
        "descriptive": desc,
        "comparisons": [
            {"a": conditions[a], "b": conditions[b], "tests": compare(ratings, positions, a, b, dimensions)}
            for a, b in comparisons
        ],
        "order": order_effects(ratings, positions, conditions, dimensions),
        "power": power,
        "power_method": "McNemar, Connor (1987) normal approximation, independent ratings, alpha 0.05, power 0.8",
    }


SMALL_SAMPLE = 10  # fewer complete pairs (or ratings) than this: the report warns that its numbers say little


def small_sample_warnings(report: dict, below: int = SMALL_SAMPLE) -> list[str]:
    """One line per comparison (and per condition's ratings) resting on fewer than ``below`` participants:
    there a paired interval such as "100.0% [100.0%, 100.0%]" is an artefact of the sample size."""
    out = []
    for comp in report["comparisons"]:
        n = min((t["pairs"] for t in comp["tests"]), default=0)
        if n < below:
            out.append(
                f"small sample: {comp['b']} vs {comp['a']} rests on n = {n} complete pair{'s' * (n != 1)} "
                f"(fewer than {below}): the tests have next to no power and the intervals are degenerate or wide; "
                "read these rows as a check of the pipeline, not as evidence"
            )
    for cond in report["conditions"]:
        n = min((r["n"] for r in report["descriptive"] if r["condition"] == cond), default=0)
        if n < below:
            out.append(f"small sample: {cond} has n = {n} rating{'s' * (n != 1)} per dimension (fewer than {below})")
    return out


def markdown(report: dict) -> str:
    """The report as Markdown tables, with a warning above them where a sample is small
    (:func:`small_sample_warnings`)."""
    pct = lambda v: "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{100 * v:.1f}%"
    num = lambda v: "-" if isinstance(v, float) and math.isnan(v) else f"{v:.4g}"
    withdrawn = report.get("withdrawn", [])
    how = "excluded" if report.get("withdrawn_excluded") else "included"
    title = f"# Study analysis: {report['participants']} participants"
    out = [title + (f" ({len(withdrawn)} withdrawn, {how})" if withdrawn else ""), ""]
    warnings = small_sample_warnings(report)
    out += [f"> **Warning, {w}.**" for w in warnings] + ([""] if warnings else [])
    out += ["## Positive-rating ratio (ratings 4-5)"]
    out += ["", "| dimension | condition | n | positive | 95% Wilson | median [IQR] |", "|---|---|---|---|---|---|"]
    for r in report["descriptive"]:
        out.append(
            f"| {r['dimension']} | {r['condition']} | {r['n']} | {pct(r['ratio'])} | {pct(r['lo'])}-{pct(r['hi'])} "
            f"| {num(r['median'])} [{num(r['q1'])}, {num(r['q3'])}] |"
        )
    for comp in report["comparisons"]:
        out += ["", f"## {comp['b']} vs {comp['a']} (complete pairs; Holm over {len(comp['tests'])} dimensions)", ""]
        out += [
            "| dimension | pairs | Wilcoxon p (Holm) | rank-biserial | McNemar p (Holm) | diff. positive [95%] "
            "| order x condition p |",
            "|---|---|---|---|---|---|---|",
        ]
        for t in comp["tests"]:
            out.append(
                f"| {t['dimension']} | {t['pairs']} | {num(t['wilcoxon_p'])} ({num(t['wilcoxon_p_holm'])}) "
                f"| {t['rank_biserial']:+.3f} | {num(t['mcnemar_p'])} ({num(t['mcnemar_p_holm'])}) "
                f"| {pct(t['ratio_difference'])} [{pct(t['difference_lo'])}, {pct(t['difference_hi'])}] "
                f"| {num(t['order_p'])} |"
            )
    out += ["", "## Order: positive ratio by block position, Kruskal-Wallis across positions", ""]
    out += ["| condition | dimension | by position | p |", "|---|---|---|---|"]
    for r in report["order"]:
        by = ", ".join(f"{k}: {pct(v)}" for k, v in sorted(r["ratio_by_position"].items()))
        out.append(f"| {r['condition']} | {r['dimension']} | {by} | {num(r['kruskal_p'])} |")
    out += ["", f"## Power ({report['power_method']})", "", "| difference | from | participants |", "|---|---|---|"]
    out += [f"| +{pct(p['delta'])} | {pct(p['baseline_ratio'])} | {p['participants']} |" for p in report["power"]]
    return "\n".join(out) + "\n"


def figure(report: dict, path) -> None:
    """Fig. 6 of the paper with intervals: positive-rating ratio per dimension and condition, 95% Wilson bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dims, conds = report["dimensions"], report["conditions"]
    by = {(r["condition"], r["dimension"]): r for r in report["descriptive"]}
    fig, ax = plt.subplots(figsize=(1.3 * len(dims) + 2, 3.6))
    width = 0.8 / len(conds)
    colors = ["#9aa5b1", "#d1495b", "#00798c"]
    for c, cond in enumerate(conds):
        xs = np.arange(len(dims)) + (c - (len(conds) - 1) / 2) * width
        r = [by[(cond, d)] for d in dims]
        ratio = np.array([0.0 if math.isnan(x["ratio"]) else x["ratio"] for x in r])
        err = np.array(
            [[max(v - x["lo"], 0) for v, x in zip(ratio, r)], [max(x["hi"] - v, 0) for v, x in zip(ratio, r)]]
        )
        ax.bar(xs, 100 * ratio, width, yerr=100 * err, capsize=3, label=cond, color=colors[c % 3])
        for x, v in zip(xs, ratio):
            ax.text(x, 2, f"{100 * v:.0f}", ha="center", va="bottom", fontsize=7, color="white")
    ax.set_xticks(np.arange(len(dims)), [d.replace("_", "\n") for d in dims], fontsize=8)
    ax.set_ylabel("positive ratings (4-5), %")
    ax.set_ylim(0, 118)  # room for the legend above the bars
    ax.set_yticks(range(0, 101, 20))
    ax.set_title(f"{report['participants']} participants; bars: 95% Wilson intervals", fontsize=9)
    ax.legend(fontsize=8, loc="upper center", ncol=len(conds), frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
