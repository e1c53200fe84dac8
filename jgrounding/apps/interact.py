"""Interactive loop: ``python -m jgrounding.apps.interact``.

Type a response plan ("User seems sad; respond calmly") and see the grounded tuple, a tendon plot and,
with ``:render``, the simulated motion. ``obs: <scene> | <what the user said>`` asks the MLLM for a
response first (Eq. 2, needs JGROUNDING_MLLM_URL), with the short history of past tuples. Commands:
``:help``, ``:history``, ``:render``, ``:force`` (drive the last low-confidence grounding anyway), ``:quit``.

A text the act/hold decision holds (:mod:`jgrounding.semantics.decision`: it calls for no motion, or the
grounding is below its kind of text's threshold) does not drive the trunk: the loop holds still (no motion is
sampled or sent; :data:`jgrounding.semantics.HOLD_STILL`) and says "holding still: <reason>" first, the tuple it was
not acted on only after it as "nearest", unless started with ``--force`` or told ``:force``.

Each turn's trajectory continues from where the last one left the robot (the first from rest): the gate
blends it in within the slew bound, so the command stream never jumps between responses. The stream
sent so far (every turn's sample 0, in order) is saved as ``stream.npy`` in the output folder.
``--screen`` keeps only candidates that the simulated trunk finds feasible. ``--checkpoint DIR`` samples
from your own model (``experiments.train --library``): grounding then chooses among its tuples and says so
when a text asks for one it never learned. ``:quit``, end of input (Ctrl-D) and Ctrl-C end the loop cleanly:
the trunk is brought back to rest within the slew bound and that ramp is saved with the stream.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

PROMPT = "jg> "
HELP = """\
Type a response plan, e.g.  User seems sad; respond calmly
  -> the grounded (intent, intensity) tuple, 8 sampled trajectories and a tendon plot (turnNNN.png).
obs: <scene> | <what the user said>
  -> asks the MLLM for a response first (needs JGROUNDING_MLLM_URL), then grounds it.
Commands:
  :help      this text
  :history   the tuples driven so far
  :render    the simulated motion of the last turn (motion GIF)
  :force     drive the last grounding that was held back
  :quit      end (so do Ctrl-D and Ctrl-C); the trunk is brought back to rest
A held text ("holding still: <reason>") does not move the trunk: it holds still at its current
command, unless you type :force (or started with --force).
Each turn continues from where the last one left the trunk; the stream so far is in stream.npy."""


def main(argv=None, stdin=None, stdout=None) -> int:
    stdin, stdout = stdin or sys.stdin, stdout or sys.stdout
    p = argparse.ArgumentParser(prog="python -m jgrounding.apps.interact", description="Interactive grounding loop.")
    p.add_argument("--out", default="interact_out")
    p.add_argument("--backend", choices=("embedded", "cues", "mllm"), default="embedded")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--screen", action="store_true", help="keep only samples feasible on the simulated trunk")
    p.add_argument("--force", action="store_true", help="drive held texts' groundings too")
    p.add_argument(
        "--checkpoint",
        metavar="DIR",
        help="sample from this checkpoint (e.g. your own, from experiments.train --library); "
        "grounding then chooses among its tuples",
    )
    args = p.parse_args(argv)
    if args.checkpoint is not None and not Path(args.checkpoint, "meta.json").is_file():
        p.error(f"--checkpoint {args.checkpoint!r} is not a checkpoint directory (no meta.json in it)")

    state = {"current": "rest", "stream": []}
    try:
        return _loop(args, stdin, stdout, state)
    except KeyboardInterrupt:
        print("\n(interrupted)", file=stdout)
        return _to_rest(args, stdout, state)
    finally:
        stdout.flush()


def _save_stream(out: Path, stream) -> Path:
    import io

    import numpy as np

    from jgrounding.io import write_atomic

    buf = io.BytesIO()
    np.save(buf, np.concatenate(stream))
    return write_atomic(out / "stream.npy", buf.getvalue())


def _to_rest(args, stdout, state) -> int:
    """End of the loop: ramp from the trunk's last command back to rest within the slew bound."""
    import numpy as np

    from jgrounding import safety

    current = state["current"]
    if isinstance(current, str) or not np.any(np.asarray(current) > 0):
        print("the trunk is at rest; bye", file=stdout)
        return 0
    ramp = safety.emit(
        np.zeros((safety.BLEND_STEPS + 1, len(current)), np.float32), num_channels=len(current), current=current
    )
    state["stream"].append(ramp)
    state["current"] = "rest"
    path = _save_stream(Path(args.out), state["stream"])
    print(f"trunk brought back to rest over {len(ramp)} steps (slew-limited); stream saved to {path}; bye", file=stdout)
    return 0


def _loop(args, stdin, stdout, state) -> int:
    import jax

    from jgrounding.apps import own, plotting
    from jgrounding.policy.respond import Decision, Responder

    out = Path(args.out)
    history: list[tuple[str, str]] = []
    last = None
    stream = state["stream"]
    pending = None  # a low-confidence grounding held back, for :force
    turn = 0
    info = own.import_info(args.checkpoint)
    responder = Responder(args.checkpoint, backend=args.backend)
    labels = info["channels"] if info else None
    model = f"checkpoint {args.checkpoint}" if args.checkpoint else "the shipped model"
    print(f"jgrounding interactive ({model}): type a response, 'obs: scene | utterance', or :help", file=stdout)
    while True:
        print(PROMPT, end="", file=stdout, flush=True)
        line = stdin.readline()
        if not line:  # end of input (Ctrl-D)
            print(file=stdout)
            break
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
            elif last.shape[-1] != 4:
                print(
                    f"render skipped: the simulator is the 4-tendon trunk, this model has {last.shape[-1]}", file=stdout
                )
            else:
                from jgrounding.sim import render

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
            decision, pending = pending, None
            print(f"forcing ({decision.intent}, {decision.intensity})", file=stdout)
        else:
            try:
                decision = responder.decide(text, force=args.force)
            except (ValueError, TypeError) as e:
                print(f"error: {e}", file=stdout)
                continue
            g = decision.grounding
            if decision.hold:  # the reason first; the tuple it was not acted on only as "nearest", in small print
                pending = Decision(decision.intent, decision.intensity, g, decision.note, False, decision.reason)
                print(f"   {decision.message(state['current'])}. Type :force to drive it anyway.", file=stdout)
                if decision.note:
                    print(f"   note: {decision.note}", file=stdout)
                print(f"      ({decision.nearest})", file=stdout)
                stdout.flush()
                continue
            if decision.note:
                print(f"   note: {decision.note}", file=stdout)
            flag = f"  (forced: {decision.reason})" if decision.reason else ""
            print(f"-> ({g.intent}, {g.intensity})  confidence {g.confidence:.2f}{flag}", file=stdout)
        pending = None
        turn += 1
        history.append((decision.intent, decision.intensity))
        key = jax.random.fold_in(jax.random.key(args.seed), turn)
        try:
            outcome = responder.act(key, decision, 8, current=state["current"], screen=args.screen)
        except ValueError as e:
            print(f"error: {e}", file=stdout)
            continue
        u = outcome.u
        if outcome.screened is not None:
            res = outcome.screened
            print(f"   screened: {res.rejected} of {res.candidates} candidates rejected as infeasible", file=stdout)
        last = u[0]
        state["current"] = last[-1]  # the next response starts from where this one leaves the robot
        stream.append(last)
        _save_stream(out, stream)
        title = f"{decision.intent} / {decision.intensity}"
        print(
            f"   tendons: {plotting.tendon_figure(u, out / f'turn{turn:03d}.png', title=title, labels=labels)}",
            file=stdout,
        )
        stdout.flush()
    return _to_rest(args, stdout, state)


if __name__ == "__main__":
    raise SystemExit(main())
