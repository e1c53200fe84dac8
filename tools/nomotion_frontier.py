"""The act/hold frontier of the no-motion decision on the dev sets: how many texts that call for no motion it holds
against what its holds cost the texts that call for a motion (acted, ECE), at every threshold of the learned detector.

    python -m tools.nomotion_frontier                     # print the table, write results/nomotion_frontier.{md,png}

#34 asks for both no-motion held >= 0.95 and ECE <= 0.05 on every frozen set, and the situation-only sets hold no
text that calls for no motion: every hold there is a false one, and a held text reports a confidence near 0
(:func:`jgrounding.semantics.nomotion.apply`) while its intent is most often right. This tool measures, on the dev
sets of ``tools.semantics_system_dev`` (never a frozen bench), whether any threshold of the shipped detector meets both
at once: the no-motion dev set's held share (written blind, like the benches, and never trained or fitted on) against
the ECE of the two unfitted situation hold-outs (likewise). The decision is the one ``jg.ground`` makes
(:func:`jgrounding.semantics.nomotion.apply`, with the shipped detector at another threshold), on the grounding
``jg.ground`` computes for each text alone; the row at the shipped threshold is therefore ``jg.ground``'s own figures.
Two more rows: the rule alone (no detector) and no decision at all (the reducer's grounding as it is).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys

from experiments import bench_semantics_scores as bs
from tools import semantics_system_dev as sd

THRESHOLDS = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.98, 0.99, 0.995, 0.999)
SITUATIONS = sd.UNFITTED_BOTH  # the pooled unfitted situation hold-outs: every hold there is a false one
NO_MOTION = sd.NO_MOTION_DEV
OUT = bs.RESULTS / "nomotion_frontier"


def groundings(sets: dict[str, list[dict]]) -> dict[str, tuple[list[dict], list, list]]:
    """Each set's items (``{name: items}``), and for each text the grounding and sentence vector ``jg.ground``
    computes for it alone before the no-motion decision (``ground_embedded_vectors([text])``, as
    :func:`jgrounding.semantics.ground`)."""
    from jgrounding.semantics import embedded

    out = {}
    for name, items in sets.items():
        pairs = [embedded.ground_embedded_vectors([it["text"]]) for it in items]
        out[name] = items, [g for (g,), _ in pairs], [None if v is None else v[0] for _, v in pairs]
    return out


def decided(runs: dict, *, off: bool = False, **options) -> dict[str, dict]:
    """``bench semantics``' metrics of every set (and of :data:`tools.semantics_system_dev.POOLED`'s pools) after
    :func:`jgrounding.semantics.nomotion.apply` with ``options`` (``off``: no decision, the groundings as they are)."""
    from jgrounding.semantics import nomotion

    preds = {}
    for name, (items, gs, vectors) in runs.items():
        if off:
            preds[name] = gs
        else:
            preds[name] = [nomotion.apply(it["text"], g, vector=v, **options) for it, g, v in zip(items, gs, vectors)]
    res = {name: bs.metrics(runs[name][0], preds[name]) for name in runs}
    for name, parts in sd.POOLED.items():
        res[name] = bs.metrics(sum((runs[p][0] for p in parts), []), sum((preds[p] for p in parts), []))
    return res


def frontier(runs: dict, thresholds=THRESHOLDS) -> list[tuple[str, dict]]:
    """(label, figures) for the shipped threshold, each of ``thresholds``, the rule alone and no decision."""
    from jgrounding.semantics import nomotion

    shipped = nomotion.detector()
    if shipped is None:
        raise SystemExit("the shipped detector is off (made for another head): retrain it with tools.train_nomotion")
    rows = [(f"{shipped.threshold:.4f} (shipped)", decided(runs))]
    for t in thresholds:
        rows.append((f"{t:.4f}", decided(runs, learned_detector=dataclasses.replace(shipped, threshold=t))))
    rows.append(("rule only", decided(runs, learned=False)))
    rows.append(("no decision", decided(runs, off=True)))
    return rows


def meets(r: dict) -> bool:
    """#34's three goals that the decision trades against each other, on the dev proxies: the no-motion dev set's
    held >= 0.95 and ECE <= 0.05 (a no-motion bench's), and the unfitted situations' ECE <= 0.05 (a situation
    bench's)."""
    g = bs.GOALS_34
    nm, sit = r[NO_MOTION], r[SITUATIONS]
    return nm["none_held"] >= g["none_held"] and nm["ece"] <= g["ece"] and sit["ece"] <= g["ece"]


COLUMNS = (
    (NO_MOTION, "none_held", "no-motion dev held"),
    (NO_MOTION, "acted", "its contrast acted"),
    (NO_MOTION, "ece", "its ECE"),
    ("v2 dev", "none_held", "v2 dev held"),
    (SITUATIONS, "acted", "unfitted situations acted"),
    (SITUATIONS, "ece", "their ECE"),
    ("blind hold-outs", "ece", "blind hold-outs ECE"),
)


def table(rows) -> str:
    head = "| detector threshold | " + " | ".join(c[2] for c in COLUMNS) + " | all three goals |"
    lines = [head, "|" + "---|" * (len(COLUMNS) + 2)]
    for label, r in rows:
        cells = " | ".join(bs.fmt(r[s][k]) for s, k, _ in COLUMNS)
        lines.append(f"| {label} | {cells} | {'yes' if meets(r) else 'no'} |")
    return "\n".join(lines)


def figure(rows, path) -> None:
    """Two panels over the thresholds: no-motion held against the situations' ECE, and the two sets' ECE."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    g = bs.GOALS_34
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4))
    panels = (
        (axes[0], (NO_MOTION, "none_held"), "no-motion dev: texts that call for no motion held", g["none_held"], 1.0),
        (axes[1], (NO_MOTION, "ece"), "no-motion dev: ECE", 0.0, g["ece"]),
    )
    for ax, (name, key), xlabel, lo, hi in panels:
        pts = [(r[name][key], r[SITUATIONS]["ece"], label) for label, r in rows]
        sweep = sorted((p for p in pts if p[2][0].isdigit()), key=lambda p: float(p[2].split()[0]))
        ax.plot([p[0] for p in sweep], [p[1] for p in sweep], "o-", label="detector threshold (rule on)")
        for x, y, label in pts:
            if not label[0].isdigit():
                ax.plot([x], [y], "s", label=label)
            ax.annotate(label.split()[0] + ("*" if "shipped" in label else ""), (x, y), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")  # fmt: skip
        ax.axvline(g["none_held"] if key == "none_held" else g["ece"], color="grey", ls="--", lw=0.8)
        ax.axhline(g["ece"], color="grey", ls="--", lw=0.8)
        ax.fill_between([lo, hi], 0, g["ece"], color="green", alpha=0.08)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("unfitted situation hold-outs: ECE")
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(
        "#34's goals on dev, the no-motion decision at each detector threshold (green: met; * shipped)", fontsize=10
    )
    fig.tight_layout()
    from jgrounding.apps import plotting

    plotting.save(fig, path)  # atomic, closes the figure


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=str(OUT), help="write OUT.md, OUT.json and OUT.png")
    args = p.parse_args(argv)
    from pathlib import Path

    from jgrounding.io import write_atomic
    from jgrounding.semantics import head as sh

    head = sh.load()
    print(f"jg.ground's no-motion decision on the dev sets ({bs.machine()}): head {head.meta['params_digest']}")
    rows = frontier(groundings({name: sd.read(paths) for name, paths in sd.SETS.items()}))
    text = table(rows)
    print(text)
    met = [label for label, r in rows if meets(r)]
    verdict = (
        f"thresholds meeting all three goals on dev: {', '.join(met)}"
        if met
        else "no threshold meets all three goals on dev (no-motion dev held >= 0.95 and ECE <= 0.05, unfitted "
        "situations' ECE <= 0.05)"
    )
    print(verdict)
    out = Path(args.out)
    md = (
        "The no-motion decision's act/hold frontier on the dev sets (`python -m tools.nomotion_frontier`; "
        f"{bs.machine()}): `jg.ground`'s decision with the shipped detector at each threshold. Sets: "
        f"{NO_MOTION} ({len(sd.read(sd.SETS[NO_MOTION]))} texts, 270 call for no motion), the unfitted situation "
        "hold-outs pooled (every hold a false one), v2 dev and the blind hold-outs. Goals as #34's on the frozen "
        "sets: held >= 0.95, ECE <= 0.05.\n\n![frontier](nomotion_frontier.png)\n\n" + text + "\n\n" + verdict + "\n"
    )
    write_atomic(out.with_suffix(".md"), md)
    payload = {label: r for label, r in rows}
    write_atomic(out.with_suffix(".json"), json.dumps(payload, indent=1, sort_keys=True) + "\n")
    figure(rows, out.with_suffix(".png"))
    print(f"wrote {out.with_suffix('.md')}, .json and .png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
