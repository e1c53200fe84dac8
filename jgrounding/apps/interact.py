"""Interactive loop: ``python -m jgrounding.apps.interact``.

Type a response plan ("User seems sad; respond calmly") and see the grounded tuple, a tendon plot and,
with ``:render``, the simulated motion. ``obs: <scene> | <what the user said>`` asks the MLLM for a
response first (Eq. 2, needs JGROUNDING_MLLM_URL), with the short history of past tuples. Commands:
``:help``, ``:history``, ``:render``, ``:force`` (drive the last low-confidence grounding anyway), ``:quit``.

A grounding below the calibrated confidence threshold does not drive the trunk: the loop holds still
(no motion is sampled or sent; :data:`jgrounding.semantics.HOLD_STILL`) and says so, unless started with
``--force`` or told ``:force``.

Each turn's trajectory continues from where the last one left the robot (the first from rest): the gate
blends it in within the slew bound, so the command stream never jumps between responses. The stream
sent so far (every turn's sample 0, in order) is saved as ``stream.npy`` in the output folder.
``--screen`` keeps only candidates that the simulated trunk finds feasible.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = __doc__.split("\n\n", 1)[1]


def main(argv=None, stdin=None, stdout=None) -> int:
    stdin, stdout = stdin or sys.stdin, stdout or sys.stdout
    p = argparse.ArgumentParser(prog="python -m jgrounding.apps.interact", description="Interactive grounding loop.")
    p.add_argument("--out", default="interact_out")
    p.add_argument("--backend", choices=("embedded", "cues", "mllm"), default="embedded")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--screen", action="store_true", help="keep only samples feasible on the simulated trunk")
    p.add_argument("--force", action="store_true", help="drive groundings below the confidence threshold too")
    args = p.parse_args(argv)

    import jax
    import numpy as np

    from jgrounding.apps import plotting
    from jgrounding.generators import sampling
    from jgrounding.io import write_atomic
    from jgrounding.semantics import HOLD_STILL, ground
    from jgrounding.sim import render

    out = Path(args.out)
    history: list[tuple[str, str]] = []
    last = None
    current = "rest"  # the robot's command when the session starts
    stream = []
    pending = None  # a low-confidence grounding held back, for :force
    turn = 0
    print("jgrounding interactive: type a response, 'obs: scene | utterance', or :help", file=stdout)
    for line in stdin:
        line = line.strip()
        if not line:
            continue
        if line in (":quit", ":q", "exit", "quit"):
            break
        if line == ":help":
            print(HELP, file=stdout)
            continue
        if line == ":history":
            print(", ".join(f"{m}/{z}" for m, z in history) or "(empty)", file=stdout)
            continue
        if line == ":render":
            if last is None:
                print("nothing to render yet", file=stdout)
            else:
                print(f"motion: {render.render_motion(last, out / f'turn{turn:03d}.gif')}", file=stdout)
            continue
        if line.startswith(":") and line != ":force":
            print(f"unknown command {line!r}; commands: :help, :history, :render, :force, :quit", file=stdout)
            continue
        text = line
        if line.startswith("obs:"):
            from jgrounding.semantics import mllm

            scene, _, said = line[4:].partition("|")
            try:
                text = mllm.reason(mllm.Observation(visual=scene.strip(), transcript=said.strip()), history)
                print(f"response: {text}", file=stdout)
            except OSError as e:
                print(f"MLLM unavailable ({e}); grounding the observation text directly", file=stdout)
                text = f"{scene.strip()} {said.strip()}"
        if line == ":force":
            if pending is None:
                print("nothing held back to force", file=stdout)
                continue
            g, pending = pending, None
            print(f"forcing ({g.intent}, {g.intensity})", file=stdout)
        else:
            try:
                g = ground(text, backend=args.backend)
            except (ValueError, TypeError) as e:
                print(f"error: {e}", file=stdout)
                continue
            flag = "" if g.confident else f"  (not acting: {g.reason or 'low confidence'})"
            print(f"-> ({g.intent}, {g.intensity})  confidence {g.confidence:.2f}{flag}", file=stdout)
            if not g.confident and not args.force:
                pending = g
                why = g.reason or "low confidence"
                print(f"   holding still ({why}): {HOLD_STILL}. Type :force to drive it anyway.", file=stdout)
                stdout.flush()
                continue
        pending = None
        turn += 1
        history.append((g.intent, g.intensity))
        key = jax.random.fold_in(jax.random.key(args.seed), turn)
        if args.screen:
            res = sampling.screened(key, g.intent, g.intensity, num_samples=8, current=current)
            u = res.u
            print(f"   screened: {res.rejected} of {res.candidates} candidates rejected as infeasible", file=stdout)
        else:
            u = sampling.sample(key, g.intent, g.intensity, num_samples=8, current=current)
        last = u[0]
        current = last[-1]  # the next response starts from where this one leaves the robot
        stream.append(last)
        buf = __import__("io").BytesIO()
        np.save(buf, np.concatenate(stream))
        write_atomic(out / "stream.npy", buf.getvalue())
        print(
            f"   tendons: {plotting.tendon_figure(u, out / f'turn{turn:03d}.png', title=f'{g.intent} / {g.intensity}')}",
            file=stdout,
        )
        stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
