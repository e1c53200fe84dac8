"""``python -m jgrounding.sim calibrate RECORDINGS --out my_trunk.xml``: fit the simulated trunk to a lab's recordings.

RECORDINGS is a recordings folder (tendon commands and motion-capture markers, :mod:`jgrounding.sim.recordings`).
The fit uses MuJoCo's system identification (``mujoco.sysid``); see docs/trunk.md.
"""

from __future__ import annotations

import argparse
import sys

from jgrounding.sim import calibration


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m jgrounding.sim", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser(
        "calibrate",
        help="fit the trunk's parameters to recordings with markers",
        description="Fit the trunk's parameters to a recordings folder with mujoco.sysid; writes the fitted MJCF, "
        "a sidecar JSON with its provenance and a report folder beside it.",
        epilog="Fittable parameters and default bounds: "
        + "; ".join(f"{n} [{lo:g}, {hi:g}]" for n, (lo, hi) in calibration.DEFAULT_BOUNDS.items()),
    )
    c.add_argument("recordings", help="recordings folder (manifest.json with markers, one CSV per recording)")
    c.add_argument("--out", required=True, help="the fitted trunk's MJCF (e.g. my_trunk.xml)")
    c.add_argument("--config", help="TOML description of the starting trunk (python -m jgrounding.sim.model)")
    c.add_argument("--settings", help="TOML: parameters = [...], [bounds] name = [low, high], validation, ...")
    c.add_argument("--fit", help="comma-separated parameters to fit (default: " + ",".join(calibration.FIT_PARAMETERS))
    c.add_argument("--bound", action="append", default=[], metavar="NAME=LOW,HIGH", help="a bound (repeatable)")
    c.add_argument("--validation", type=float, help="fraction of recordings held out (default 0.25)")
    c.add_argument("--seed", type=int, help="seed of the fit / validation split (default 0)")
    c.add_argument("--max-iters", type=int, help="iteration budget of the optimizer (default 40)")
    c.add_argument("--no-html", action="store_true", help="skip sysid's HTML report")
    return p


def calibrate_main(args) -> int:
    from jgrounding.sim import calibration_report
    from jgrounding.sim import mjcf as tm
    from jgrounding.sim.recordings import load_recordings

    try:
        overrides = {
            "parameters": tuple(s.strip() for s in args.fit.split(",") if s.strip()) if args.fit else None,
            "bounds": tuple(calibration.parse_bound(b) for b in args.bound),
            "validation": args.validation,
            "seed": args.seed,
            "max_iters": args.max_iters,
        }
        if args.settings:
            settings = calibration.load_settings(args.settings, **overrides)
        else:
            settings = calibration.Settings(**{k: v for k, v in overrides.items() if v is not None})
        base = tm.load_config(args.config) if args.config else tm.TrunkParams()
        recordings = load_recordings(args.recordings)
        result = calibration.calibrate(recordings, base, settings)
        calibration_report.write(result, args.out, recordings, args.recordings, html=not args.no_html)
    except (ValueError, FileNotFoundError) as e:  # CalibrationError, RecordingsError, bad TOML: nothing written
        print(f"error: {e}", file=sys.stderr)
        return 2
    for name, d in result.rms.items():
        (b0, t0), (b1, t1) = d["before"], d["after"]
        print(
            f"{name}: backbone RMS {1000 * b0:.2f} -> {1000 * b1:.2f} mm, tip RMS {1000 * t0:.2f} -> {1000 * t1:.2f} mm"
        )
    print(f"use it: --trunk {args.out} (or --set physics.trunk={args.out})")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    return calibrate_main(args)


if __name__ == "__main__":
    raise SystemExit(main())
