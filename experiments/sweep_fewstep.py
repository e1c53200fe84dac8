"""Few steps that keep the distribution: ``python -m experiments.sweep fewstep [--steps N]``.

Four generators of Tuple + Spline, each trained over the same seeds (vmapped) with the same options
(``OPTIONS``: EMA of the parameters) on the library's training pairs: RF sampled with Euler, its
2-rectified flow (64 teacher pairs per training example, Euler S = 50 of each seed's own RF), MeanFlow
(logit-normal flow times, as shipped) and the shortcut model. Each is sampled with S in ``STEP_COUNTS`` (K samples of each held-out tuple, through
the gate as ``jg.sample`` with ``current=None``) and scored on the evaluation set with
:func:`jgrounding.evaluation.distribution.score`: mean ± std (ddof = 1) over seeds. Writes
results/sweep_fewstep.{md,json} (via ``experiments.sweep``) and results/sweep_fewstep.png (Prec@r,
ModeCov, multimodality ratio and intensity retrieval against S, one line per generator).
"""

from __future__ import annotations

import time

import jax

from jgrounding import load_library, semantics
from jgrounding.apps.plotting import plt, save
from jgrounding.config import SampleConfig
from jgrounding.evaluation import distribution, generate
from jgrounding.training import TrainConfig, trainer

RF = "tuple_spline_rf"
GENERATORS = (  # (label, method, options beyond OPTIONS); the reflow row is trained from the RF row's seeds
    ("RF (Euler)", RF, {}),
    ("2-rectified flow", "reflow", {}),
    ("MeanFlow", "tuple_spline_meanflow", {"time_sampler": "logit_normal"}),  # as shipped (experiments/ship.py)
    ("Shortcut", "tuple_spline_shortcut", {}),
)
STEP_COUNTS = (1, 2, 4, 8, 50)
OPTIONS = {"ema_decay": 0.999}
METRICS = ("prec_r", "mode_cov", "mm_ratio", "intensity_ret", "prec_tau", "between", "mode_bal", "intent_ret")
PLOTTED = ("prec_r", "mode_cov", "mm_ratio", "intensity_ret")
DEFAULT_STEPS = 20_000


def scores(trained, lib, cond, key, k: int, steps: int) -> dict[str, list[float]]:
    """Per-seed distribution summaries ``{metric: [value per seed]}`` of ``trained`` at ``steps``."""
    ho = lib.heldout
    u = generate.generate(
        trained, cond, ho.intensity, key, num_samples=k, config=SampleConfig(steps=steps)
    )  # (seeds, N, K, T, C)
    per_seed = [
        distribution.score(u[i], ho.intent, ho.intensity, lib.evaluation, with_frechet=False).summary()
        for i in range(len(u))
    ]
    return {m: [s[m] for s in per_seed] for m in METRICS}


def train_all(lib, seeds, steps: int, reflow_pairs: int) -> tuple[dict, dict]:
    """({label: Trained}, {label: training seconds})."""
    trained, seconds = {}, {}
    for label, method, extra in GENERATORS:
        config = TrainConfig(steps=steps, **OPTIONS, **extra)
        t0 = time.perf_counter()
        if method == "reflow":
            trained[label] = trainer.reflow(trained["RF (Euler)"], lib, config, pairs_per_example=reflow_pairs)
        else:
            trained[label] = trainer.fit(method, lib, seeds, config)
        seconds[label] = time.perf_counter() - t0
        print(f"trained {label}: {seconds[label]:.0f} s", flush=True)
    return trained, seconds


def _cell(ms) -> str:
    return f"{ms[0]:.3f} ± {ms[1]:.3f}"


def markdown(table: dict, seeds, steps: int, k: int, seconds: dict, r: float, n_tuples: int) -> str:
    labels = [distribution.LABELS[m] for m in METRICS]
    lines = ["| Generator | S | " + " | ".join(labels) + " |", "|---" * (len(METRICS) + 2) + "|"]
    for label, rows in table.items():
        for s, row in rows.items():
            lines.append(f"| {label} | {s} | " + " | ".join(_cell(row[m]) for m in METRICS) + " |")
    ref = table["RF (Euler)"]["50"]
    lines += [
        "",
        f"Tuple + Spline, {len(seeds)} seeds (mean ± std, ddof = 1), {steps:,} training steps each (EMA 0.999, "
        f"batch 8, Table I sizes; MeanFlow with logit-normal flow times, as shipped; the 2-rectified flow: "
        f"{steps:,} more steps on its RF's own pairs), K = {k} "
        f"samples of each of the {n_tuples} held-out tuples, scored against the "
        f"evaluation set (r = {r:.3f}). One network call per step for every generator. Training time: "
        + ", ".join(f"{lab} {sec:.0f} s" for lab, sec in seconds.items())
        + ".",
        "",
        f"Goal at a few-step S: within 0.02 of RF S = 50 on Prec@r ({ref['prec_r'][0]:.3f}) and ModeCov "
        f"({ref['mode_cov'][0]:.3f}), multimodality ratio 0.8-1.2, intensity retrieval >= 0.95.",
    ]
    for label, rows in table.items():
        met = [
            s
            for s, row in rows.items()
            if s != "50"
            and row["prec_r"][0] >= ref["prec_r"][0] - 0.02
            and row["mode_cov"][0] >= ref["mode_cov"][0] - 0.02
            and 0.8 <= row["mm_ratio"][0] <= 1.2
            and row["intensity_ret"][0] >= 0.95
        ]
        lines.append(f"- {label}: goal met at S = {', '.join(met)}" if met else f"- {label}: goal met at no S < 50")
    return "\n".join(lines)


def figure(table: dict, path) -> None:
    fig, axes = plt.subplots(1, len(PLOTTED), figsize=(13, 3.2))
    for ax, m in zip(axes, PLOTTED):
        for label, rows in table.items():
            s = [int(x) for x in rows]
            ax.errorbar(
                s, [rows[x][m][0] for x in rows], [rows[x][m][1] for x in rows], marker="o", capsize=3, label=label
            )
        if m == "mm_ratio":
            ax.axhspan(0.8, 1.2, color="k", alpha=0.06)
        ax.set_xscale("log", base=2)
        ax.set_xticks(list(STEP_COUNTS), [str(x) for x in STEP_COUNTS])
        ax.set_xlabel("steps S (network calls)")
        ax.set_title(distribution.LABELS[m])
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    save(fig, path)


def run(args) -> dict:
    """The ``fewstep`` sweep of ``experiments.sweep`` (``args``: seeds, steps, k_div, reflow_pairs, out)."""
    t_start = time.perf_counter()
    lib = load_library()
    seeds = tuple(range(args.seeds))
    cond = semantics.intent_embeddings()[lib.heldout.intent]
    trained, seconds = train_all(lib, seeds, args.steps, args.reflow_pairs)
    table = {}
    for label, tr in trained.items():
        table[label] = {}
        for s in STEP_COUNTS:
            per_seed = scores(tr, lib, cond, jax.random.key(100 + s), args.k_div, s)
            table[label][str(s)] = {m: distribution.mean_std(v) for m, v in per_seed.items()}
            row = table[label][str(s)]
            print(f"{label:18s} S={s:2d} " + ", ".join(f"{m} {_cell(row[m])}" for m in PLOTTED), flush=True)
    figure(table, args.out / "sweep_fewstep.png")
    r = distribution.radius(lib.evaluation)
    return {
        "table": table,
        "seeds": list(seeds),
        "steps": args.steps,
        "k": args.k_div,
        "options": OPTIONS,
        "generator_options": {label: extra for label, _, extra in GENERATORS},
        "r": r,
        "train_seconds": seconds,
        "seconds": time.perf_counter() - t_start,
        "markdown": markdown(table, seeds, args.steps, args.k_div, seconds, r, len(lib.heldout)),
    }
