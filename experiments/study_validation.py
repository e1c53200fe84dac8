"""Validate the study's analysis without people: simulated studies at the paper's positive ratios
(100 participants, two conditions, six dimensions, an order effect and 5% dropout per block).

    python -m experiments.study_validation              # 1,000 studies (about a minute on 2 cores)
    python -m experiments.study_validation --studies 200

Prints: the 95% Wilson intervals' coverage of the true positive ratios (should be 95% +- 2%), the estimates'
bias and RMSE, the paired tests' false-positive rate under no effect (each test at 0.05 should be <= 5%; and
family-wise over the six dimensions after Holm; and the Wilcoxon test's exact level given each null
test's ranks, at most 5% by construction), the tests' power at the paper's effects, and the CPU.
tests/study/test_simulate.py runs 200 studies and checks the same bounds loosely.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main(argv=None) -> dict:
    from experiments.bench_sample import cpu_model
    from jgrounding.study import simulate
    from jgrounding.study.analysis import participants_needed, wilson

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--studies", type=int, default=1000)
    parser.add_argument("--participants", type=int, default=100)
    parser.add_argument("--order-shift", type=float, default=0.2, help="latent shift per block position")
    parser.add_argument("--dropout", type=float, default=0.05, help="probability of leaving after each block")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    model = simulate.paper_model(order_shift=args.order_shift, dropout=args.dropout)
    t0 = time.perf_counter()
    r = simulate.validate(np.random.default_rng(args.seed), model, args.studies, args.participants)
    r["seconds"] = round(time.perf_counter() - t0, 1)
    r["cpu"] = cpu_model()
    r["model"] = {"order_shift": args.order_shift, "dropout": args.dropout, "correlation": model.correlation}
    sd = (0.95 * 0.05 / r["intervals"]) ** 0.5
    print(f"{args.studies} simulated studies x {args.participants} participants, 2 conditions x 6 dimensions")
    print(f"  order shift {args.order_shift} (latent sd per block), dropout {args.dropout} per block")
    print(
        f"  Wilson 95% coverage of the true positive ratios: {100 * r['coverage']:.2f}% of {r['intervals']} intervals"
    )
    print(f"    (binomial sd of that figure at 95%: {100 * sd:.2f} points)  target 95% +- 2%")
    print(f"  positive-ratio estimates: bias {r['mean_error']:+.4f}, RMSE {r['rmse']:.4f}")
    fp, fw, pw = r["false_positive"], r["familywise_false_positive"], r["power"]

    def rate(v, n):  # a Monte Carlo rate with its 95% Wilson interval
        lo, hi = wilson(round(v * n), n)
        return f"{100 * v:.2f}% [{100 * float(lo):.2f}, {100 * float(hi):.2f}]"

    tests = 6 * args.studies
    print(f"  false positives under no effect, per test at 0.05 ({tests} tests; [95% Monte Carlo interval]):")
    print(f"    Wilcoxon {rate(fp['wilcoxon'], tests)}, McNemar {rate(fp['mcnemar'], tests)}")
    lv = r["wilcoxon_level"]
    print(
        f"    Wilcoxon's exact level given each null test's ranks (no sign-draw noise): "
        f"mean {100 * lv['mean']:.2f}%, at most {100 * lv['max']:.2f}%"
    )
    print(f"  family-wise after Holm over 6 dimensions ({args.studies} studies):")
    print(f"    Wilcoxon {rate(fw['wilcoxon'], args.studies)}, McNemar {rate(fw['mcnemar'], args.studies)}")
    print(
        f"  power at the paper's effects (Holm, share of the 6 tests): Wilcoxon {100 * pw['wilcoxon']:.1f}%, McNemar {100 * pw['mcnemar']:.1f}%"
    )
    print("    (5 of the 6 dimensions differ by >= 30 points, perceived safety by 3: 83.3% is all five found)")
    print(
        f"  participants for 80% power, McNemar (Connor 1987), 46% -> 82%: {participants_needed(0.46, 0.82)}; 50% -> 65%: {participants_needed(0.50, 0.65)}"
    )
    print(f"  {r['seconds']} s on {r['cpu']}")
    print(json.dumps(r))
    return r


if __name__ == "__main__":
    main()
