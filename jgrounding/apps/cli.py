"""Command line: ``python -m jgrounding "User seems sad; respond calmly" [options]``.

Grounds the text to an (intent, intensity) tuple, samples K trajectories, and writes
- ``tendons.png``: the tendon commands (sample 0 bold, the others faint),
- ``motion.gif``, ``keyframes.png`` and ``posture.png``: the simulated trunk (MuJoCo renderer, matplotlib
  fallback) from the side (user on the right) and from behind (robot's left on the left): the whole motion,
  the postures at t = 0, 1, 2, 3, 4, 5 s, and the final posture, each under the text and its tuple with a time
  stamp,
- ``commands.csv`` / ``commands.json``: the command stream of sample 0 at the control rate, with units
  and bounds in a header, ready for a motor controller; ``samples.npy``: all K trajectories.

``--intent/--intensity`` skip the text and sample a tuple directly. ``--current`` is the command the robot
holds now (default ``rest``): the trajectories blend in from it within the slew bound. ``--screen``
simulates the candidates on the trunk and keeps only feasible ones (stable, contact force and tip speed
near the user within bounds), reporting how many were rejected. ``--jsonl`` prints one JSON object per
event for scripts; ``--quiet`` prints only the output folder. The files go to ``--out`` (default
``grounding_out/`` in the current folder). The decision is the one every front end makes
(:class:`jgrounding.policy.respond.Responder`): with ``--checkpoint``, grounding chooses among the checkpoint's
tuples; a text the act/hold decision holds (:mod:`jgrounding.semantics.decision`: it calls for no motion, or its
grounding is below its kind of text's threshold) does not drive the trunk: the command stream holds still at
``--current`` and the screen says why first ("holding still: <reason>"), the tuple only after it as "nearest";
``--force`` drives the grounded tuple anyway.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

from jgrounding.vocabulary import INTENSITIES, INTENTS

MAX_SAMPLES = 256
MAX_TEXT_CHARS = 4000


def _positive_samples(text: str) -> int:
    try:
        k = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--samples must be an integer in 1..{MAX_SAMPLES}, got {text!r}")
    if not 1 <= k <= MAX_SAMPLES:
        raise argparse.ArgumentTypeError(f"--samples must be in 1..{MAX_SAMPLES}, got {k}")
    return k


def _seed(text: str) -> int:
    try:
        s = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seed must be a non-negative integer, got {text!r}")
    if not 0 <= s < 2**32:
        raise argparse.ArgumentTypeError(f"--seed must be in 0..2**32-1, got {s}")
    return s


def _current(text: str):
    """``rest`` or one comma-separated pull in [0, 1] per tendon (the robot's current command)."""
    if text.strip().lower() == "rest":
        return "rest"
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if not values or not all(0.0 <= v <= 1.0 for v in values):
        raise argparse.ArgumentTypeError(
            f"--current must be 'rest' or comma-separated pulls in [0, 1], one per "
            f"tendon (4 for the built-in trunk, e.g. 0.2,0,0.1,0), got {text!r}"
        )
    return values


def picture_title(text: str | None, intent: str, intensity: str, hold: bool = False, width: int = 60) -> str:
    """The title of the pictures: the text (cut to ``width`` characters) and the tuple it grounded to, or the
    tuple alone when it was given; a held (not confident) grounding says so."""
    tuple_ = f"({intent}, {intensity})"
    if hold:
        tuple_ = f"holding still (nearest {tuple_}, not acted on)"
    if not text:
        return tuple_
    text = " ".join(text.split())
    text = text if len(text) <= width else text[: width - 1].rstrip() + "…"
    return f'"{text}" -> {tuple_}'


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m jgrounding",
        description="Ground an open-vocabulary social response into soft-trunk tendon actuation.",
    )
    p.add_argument("text", nargs="?", help="the response to ground, e.g. 'User seems sad; respond calmly'")
    p.add_argument("--intent", choices=INTENTS, help="sample this intent directly (skips grounding)")
    p.add_argument("--intensity", choices=INTENSITIES, help="intensity to use with --intent")
    p.add_argument(
        "--samples",
        type=_positive_samples,
        default=8,
        metavar="K",
        help=f"number of trajectories to sample (1..{MAX_SAMPLES}, default 8)",
    )
    p.add_argument(
        "--out",
        default="grounding_out",
        metavar="DIR",
        help="output folder for the pictures, command streams and samples, made if missing (default "
        "grounding_out/ in the current folder, with or without --jsonl)",
    )
    p.add_argument(
        "--backend",
        choices=("embedded", "cues", "mllm"),
        default="embedded",
        help="semantic reduction backend (default embedded, which escalates low confidence to the MLLM "
        "when JGROUNDING_MLLM_URL is set; cues: the first cue-list reducer; mllm needs the URL)",
    )
    p.add_argument("--seed", type=_seed, default=0, help="random seed (default 0)")
    p.add_argument("--sampler", choices=("euler", "midpoint", "rk4"), default="euler")
    p.add_argument(
        "--steps",
        type=int,
        default=50,
        choices=(1, 2, 4, 8, 16, 25, 50, 100),
        help="flow integration steps S (default 50)",
    )
    p.add_argument(
        "--current",
        type=_current,
        default="rest",
        metavar="rest|A,B,C,D",
        help="the robot's current command, blended from within the slew bound (default rest)",
    )
    p.add_argument(
        "--screen",
        action="store_true",
        help="simulate candidates on the trunk and keep only feasible ones (reports the rejected)",
    )
    p.add_argument(
        "--trunk",
        default=None,
        help="the trunk MJCF to screen on and render (a fitted one, python -m jgrounding.sim calibrate; "
        "default: the shipped trunk)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="drive the grounded tuple even when the text is held (no motion called for, or unsure which motion)",
    )
    p.add_argument("--no-render", action="store_true", help="skip the simulated motion (faster)")
    p.add_argument(
        "--checkpoint",
        metavar="DIR",
        help="sample from this checkpoint (e.g. one trained on your own "
        "library with experiments.train --library; default: the shipped one); grounding then chooses "
        "among the checkpoint's tuples",
    )
    p.add_argument(
        "--units",
        choices=("normalized", "lab"),
        default="normalized",
        help="units of commands.csv/json: normalized pull in [0, 1] (default) or, for a checkpoint trained "
        "on an imported library, the lab's own units from the import's limits",
    )
    p.add_argument(
        "--allow-library-mismatch",
        action="store_true",
        help="use a --checkpoint trained on another version of its library (refused otherwise)",
    )
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--quiet", action="store_true", help="print only the output folder")
    mode.add_argument(
        "--jsonl",
        action="store_true",
        help="print JSON lines (one per event) instead of text; the files still go to --out (default grounding_out/)",
    )
    return p


class _Printer:
    def __init__(self, quiet: bool, jsonl: bool):
        self.quiet, self.jsonl = quiet, jsonl

    def __call__(self, event: str, text: str, **data):
        if self.jsonl:
            print(json.dumps({"event": event, **data}), flush=True)
        elif not self.quiet:
            print(text, flush=True)


def run(args: argparse.Namespace) -> int:
    import jax
    import numpy as np

    from jgrounding import vocabulary
    from jgrounding.apps import export, own, plotting
    from jgrounding.io import write_atomic
    from jgrounding.policy.respond import Responder

    say = _Printer(args.quiet, args.jsonl)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    info = own.import_info(args.checkpoint)
    if args.units == "lab" and info is None:
        raise ValueError(
            f"--units lab needs a checkpoint trained on an imported library (its card holds the limits); "
            f"--checkpoint {args.checkpoint} has none"
        )
    responder = Responder(
        args.checkpoint, allow_library_mismatch=args.allow_library_mismatch, backend=args.backend, trunk=args.trunk
    )
    t0 = time.perf_counter()
    decision = responder.decide(
        args.text if args.intent is None else None, intent=args.intent, intensity=args.intensity, force=args.force
    )
    intent, intensity, g = decision.intent, decision.intensity, decision.grounding
    if g is None:
        given = "[given]" if args.intensity else "[intent given; intensity not given: the default 'moderate']"
        say("tuple", f"tuple: ({intent}, {intensity}) {given}", intent=intent, intensity=intensity)
        confidence = None
    else:
        ms = 1e3 * (time.perf_counter() - t0)
        confidence = float(g.confidence)
        if decision.hold:  # what a held text shows first: the reason; the tuple only as "nearest", after it
            say(
                "holding",
                f"{decision.message(args.current)} (use --force to drive the tuple)",
                reason=decision.reason,
                hold_still=True,
            )
        if decision.note:
            say("restricted", f"note: {decision.note}", note=decision.note)
        say(
            "tuple",
            f"  {decision.nearest}  backend {g.backend}  [{ms:.0f} ms]"
            if decision.hold
            else f"grounded: ({intent}, {intensity})  confidence {confidence:.2f}  backend {g.backend}  [{ms:.0f} ms]",
            intent=intent,
            intensity=intensity,
            confidence=confidence,
            backend=g.backend,
            confident=g.confident,
            nearest=decision.hold,
        )
        if decision.forced:
            say(
                "warning",
                f"warning: {decision.reason}; driving it anyway (--force)",
                reason=decision.reason,
                hold_still=False,
            )
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:  # e.g. screening on another trunk than the library's
        warnings.simplefilter("always")
        outcome = responder.act(
            jax.random.key(args.seed),
            decision,
            args.samples,
            current=args.current,
            screen=args.screen,
            sampler=args.sampler,
            steps=args.steps,
        )
    for w in caught:
        if "screened on" in str(w.message):  # jgrounding.sim.trunk_mismatch: said like the CLI's other warnings
            say("warning", f"warning: {w.message}", reason=str(w.message), hold_still=False)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    hold = decision.hold
    u = np.asarray(outcome.u).reshape((-1,) + np.shape(outcome.u)[-2:])
    if hold:  # the neutral behaviour: the current command, held, in the shape the generator would give
        say(
            "hold",
            f"hold still: {u.shape[0]} constant command streams of shape {u.shape[1:]}",
            num_samples=int(u.shape[0]),
            hold_still=True,
        )
    else:
        res = outcome.screened
        if res is not None:
            say(
                "screen",
                f"screened on the trunk ({res.engine}): {res.candidates} candidates simulated, "
                f"{res.rejected} rejected as infeasible, {args.samples} kept "
                f"[{1e3 * res.seconds:.0f} ms of simulation]",
                candidates=res.candidates,
                rejected=res.rejected,
                engine=res.engine,
            )
        say(
            "sample",
            f"sampled {u.shape[0]} trajectories of shape {u.shape[1:]}, blended in from "
            f"{'rest' if args.current == 'rest' else args.current} "
            f"[{1e3 * (time.perf_counter() - t0):.0f} ms incl. load/compile]",
            num_samples=int(u.shape[0]),
        )

    from jgrounding.sim import CONTROL_DT

    meta = export.tuple_meta(
        vocabulary.intent_index(intent),
        vocabulary.intensity_index(intensity),
        text=args.text,
        seed=args.seed,
        sample=0,
        confidence=confidence,
        **({"hold_still": True} if hold else {}),
    )
    title = picture_title(args.text, intent, intensity, hold)
    own_stream = {
        "channels": info["channels"] if info else None,
        "limits": info["limits"] if info and args.units == "lab" else None,
    }
    files = {
        "tendons": plotting.tendon_figure(u, out / "tendons.png", title=title, labels=own_stream["channels"]),
        "csv": str(
            write_atomic(
                out / "commands.csv", export.command_stream_csv(u[0], control_dt=CONTROL_DT, meta=meta, **own_stream)
            )
        ),
        "json": str(
            write_atomic(
                out / "commands.json", export.command_stream_json(u[0], control_dt=CONTROL_DT, meta=meta, **own_stream)
            )
        ),
    }
    buf = __import__("io").BytesIO()
    np.save(buf, u)
    files["samples"] = str(write_atomic(out / "samples.npy", buf.getvalue()))
    if not args.no_render and u.shape[-1] != 4:
        say(
            "render",
            f"render skipped: the built-in simulator is the 4-tendon trunk, this checkpoint has "
            f"N_u = {u.shape[-1]} tendons",
        )
    elif not args.no_render:
        from jgrounding.sim import render

        t0 = time.perf_counter()
        files["posture"] = str(
            render.render_posture(u[0], out / "posture.png", title=f"{title}, sample 0", trunk=args.trunk)
        )
        files["keyframes"] = str(
            render.render_keyframes(u[0], out / "keyframes.png", title=f"{title}, sample 0", trunk=args.trunk)
        )
        files["motion"] = str(
            render.render_motion(u[0], out / "motion.gif", title=f"{title}, sample 0", trunk=args.trunk)
        )
        say("render", f"rendered motion [{time.perf_counter() - t0:.1f} s]")
    for name, path in files.items():
        say("file", f"  {name:9s} {path}", kind=name, path=path)
    if args.quiet:
        print(out)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.intent is None and args.intensity is not None:
        parser.error("--intensity needs --intent (or give a text to ground)")
    if args.intent is None:
        if args.text is None or not args.text.strip():
            parser.error(f"give a response text to ground, or --intent NAME (valid intents: {', '.join(INTENTS)})")
        if len(args.text) > MAX_TEXT_CHARS:
            parser.error(f"text is {len(args.text)} characters; at most {MAX_TEXT_CHARS} are accepted")
        try:
            args.text.encode("utf-8")
        except UnicodeEncodeError:  # undecodable bytes on the command line arrive as lone surrogates
            parser.error("text is not valid UTF-8; give the response as UTF-8 text")
    if not args.out.strip():
        parser.error("--out needs a folder name, e.g. --out grounding_out")
    try:
        Path(args.out).mkdir(parents=True, exist_ok=True)
    except (OSError, ValueError) as e:  # a file in the way, no permission, a NUL in the name, ...
        parser.error(f"--out {args.out!r} cannot be used as the output folder ({e})")
    if args.trunk is not None:
        from jgrounding import sim

        try:
            args.trunk = sim.resolve_trunk(args.trunk)
        except FileNotFoundError as e:
            parser.error(f"--trunk: {e}")
    try:
        return run(args)
    except (ValueError, TypeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
