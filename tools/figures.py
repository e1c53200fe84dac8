"""Figures of the docs: ``python -m tools.figures primitives|stages|all``.

- ``primitives``: the trunk under simple held tendon commands, one picture per primitive family
  (bend toward each side, curl, retract, extend, touch) in docs/trunk/<family>.png and the composite
  docs/trunk/primitives.png. Every panel is simulated by :func:`jgrounding.sim.rollout` (the numbers in
  its title) and rendered by :mod:`jgrounding.sim.render`; the thin blue rod is the rest posture.
- ``stages``: one figure per pipeline stage for docs/how_it_works.md, in docs/stages/
  (grounding, splines, sampling, trunk).
- ``cli``: runs the command line on the README's example and keeps its pictures and its GIF in docs/cli/.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from jgrounding import safety, sim
from jgrounding.apps.plotting import TENDON_COLORS, TENDON_LABELS, plt, save
from jgrounding.sim import mjcf as trunk_model
from jgrounding.sim import render

DOCS = Path(__file__).resolve().parent.parent / "docs"
T = sim.NUM_STEPS
RAMP = 40  # control steps (1.3 s) to ease into a held command
PNG_COLORS = 128  # palette size of the rendered pictures (keeps each well under 150 KB)


def ease(level, start: int = 0, ramp: int = RAMP, num_steps: int = T) -> np.ndarray:
    """Tendon commands ``(T, 4)`` that ease (cosine) from slack to ``level`` (4 pulls) and hold it."""
    s = np.clip((np.arange(num_steps) - start) / ramp, 0.0, 1.0)
    return (0.5 - 0.5 * np.cos(np.pi * s))[:, None] * np.asarray(level, dtype=np.float64)[None]


def primitive_commands() -> dict[str, np.ndarray]:
    """The held commands behind the primitive figures, name -> actuation ``(150, 4)`` in [0, 1].

    Tendons: 0 faces the user (+x), 1 the robot's left (+y), 2 away (-x), 3 right (-y).
    """
    bend = 0.6  # a moderate one-sided pull: the trunk bends
    retract_then_release = ease([1, 1, 1, 1]) - ease([1, 1, 1, 1], start=75)
    u = {
        "bend_toward_user": ease([bend, 0, 0, 0]),
        "bend_left": ease([0, bend, 0, 0]),
        "bend_away": ease([0, 0, bend, 0]),
        "bend_right": ease([0, 0, 0, bend]),
        "curl_away": ease([0, 0, 1, 0]),  # the strongest one-sided pull: the compliant tip curls
        "curl_left": ease([0, 1, 0, 0]),
        "retract": ease([1, 1, 1, 1]),  # co-contraction: bending cancels, the axial slides compress
        "extend": retract_then_release,  # retracted, then all tendons slack: full length again
        "touch": ease([1, 0, 0, 0], ramp=T - 1),  # a slow 5 s reach toward the user until the tip touches
    }
    return {k: safety.emit(v) for k, v in u.items()}


def _measure(r: sim.Rollout, t: int) -> dict[str, float]:
    rest_tip = sim.BASE_POSITION - np.array([0.0, 0.0, trunk_model.TRUNK_LENGTH])
    b = r.backbone[0, t]
    return {
        "dx": b[-1, 0] - rest_tip[0],
        "dy": b[-1, 1] - rest_tip[1],
        "tip_z": b[-1, 2],
        "length": float(np.linalg.norm(np.diff(b, axis=0), axis=1).sum()),
        "turn": float(np.degrees(sim.turning_angle(b[None])[0])),
        "user": float(r.user_distance[0, t]),
        "force": float(r.contact_force[0, t]),
        "touches": "touches" if r.contact_force[0, t] > 1e-3 else "no contact",
    }


# (family, [(command, control step, view, what the title says)]); the title's numbers come from the rollout.
FAMILIES = {
    "bend": [
        ("bend_toward_user", T - 1, render.SIDE_VIEW, "toward the user: tendon 0 at 0.6\ntip {dx:+.2f} m in x"),
        ("bend_away", T - 1, render.SIDE_VIEW, "away: tendon 2 at 0.6\ntip {dx:+.2f} m in x"),
        ("bend_left", T - 1, render.REAR_VIEW, "robot's left: tendon 1 at 0.6\ntip {dy:+.2f} m in y"),
        ("bend_right", T - 1, render.REAR_VIEW, "robot's right: tendon 3 at 0.6\ntip {dy:+.2f} m in y"),
    ],
    "curl": [
        ("curl_away", T - 1, render.SIDE_VIEW, "tendon 2 at 1.0 (away)\nbackbone turns {turn:.0f}°"),
        ("curl_left", T - 1, render.REAR_VIEW, "tendon 1 at 1.0 (left)\nbackbone turns {turn:.0f}°"),
    ],
    "retract": [
        ("retract", 0, render.SIDE_VIEW, "all slack (t = 0)\nlength {length:.2f} m"),
        ("retract", T - 1, render.SIDE_VIEW, "all four at 1.0 (co-contraction)\nlength {length:.2f} m"),
    ],
    "extend": [
        ("extend", 74, render.SIDE_VIEW, "retracted (t = 2.5 s)\nlength {length:.2f} m"),
        ("extend", T - 1, render.SIDE_VIEW, "all released to slack (t = 5 s)\nlength {length:.2f} m"),
    ],
    "touch": [
        ("touch", 75, render.SIDE_VIEW, "slow reach, tendon 0 at 0.5 (t = 2.5 s)\n{user:.3f} m from the user"),
        (
            "touch",
            T - 1,
            render.SIDE_VIEW,
            "tendon 0 at 1.0 (t = 5 s): {touches}\n{user:.3f} m from the user, {force:.2f} N",
        ),
    ],
}
COMPOSITE = [("bend", 0), ("bend", 2), ("curl", 0), ("retract", 1), ("extend", 1), ("touch", 1)]


def _panels(family_panels, commands, rollouts):
    """Render and caption panels -> [(image, caption)]."""
    out = []
    for name, step, view, caption in family_panels:
        (img,), _ = render.frames(commands[name], [step], view, labels=True, ghost=True)
        out.append((img, caption.format(**_measure(rollouts[name], step))))
    return out


def _grid(panels, path, ncols: int, title: str = "", heading=None):
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, 3.5 * nrows), squeeze=False, layout="constrained")
    for k, ax in enumerate(axes.flat):
        ax.set_axis_off()
        if k < len(panels):
            img, caption = panels[k]
            ax.imshow(img)
            ax.set_title((f"{heading[k]}\n" if heading else "") + caption, fontsize=8.5)
    if title:
        fig.suptitle(title, fontsize=10)
    return save(fig, path, dpi=100, colors=PNG_COLORS)


def primitives(out: Path = DOCS / "trunk") -> list[str]:
    """docs/trunk/<family>.png for every family and the labelled composite docs/trunk/primitives.png."""
    commands = primitive_commands()
    names = list(commands)
    r = sim.rollout(np.stack([commands[n] for n in names]))
    if not (r.stable.all() and sim.feasible(r).all()):
        raise RuntimeError("a primitive command is unstable or infeasible on the trunk")
    rollouts = {
        n: sim.Rollout(**{f: getattr(r, f)[i : i + 1] for f in sim.Rollout.__dataclass_fields__})
        for i, n in enumerate(names)
    }
    written = []
    for family, family_panels in FAMILIES.items():
        panels = _panels(family_panels, commands, rollouts)
        written.append(
            _grid(
                panels,
                out / f"{family}.png",
                ncols=len(panels),
                title=f"{family} (thin blue rod: the trunk at rest, all tendons slack)",
            )
        )
    picks = [FAMILIES[f][k] for f, k in COMPOSITE]
    written.append(
        _grid(
            _panels(picks, commands, rollouts),
            out / "primitives.png",
            ncols=3,
            heading=[f.upper() for f, _ in COMPOSITE],
            title="Elephant primitives on the simulated trunk (held tendon commands; thin blue rod: rest posture)",
        )
    )
    return written


GROUNDING_TEXTS = (
    "User seems sad; respond calmly with a gentle touch",
    "The kids are cheering, we won! Celebrate wildly!",
    "The user looks uneasy and steps back; give them a little space.",
)
STAGE_TUPLE = ("comforting", "pronounced")  # the tuple the splines / sampling / trunk figures follow
TRUNK_STEPS = (0, 37, 74, 111, 149)


def grounding_figure(path, texts=GROUNDING_TEXTS, top: int = 5):
    """Stage 1: text -> (intent, intensity) with the top intent scores of :func:`jgrounding.ground`."""
    import textwrap

    import jgrounding as jg

    fig, axes = plt.subplots(1, len(texts), figsize=(4.2 * len(texts), 3.0), layout="constrained")
    for ax, text in zip(axes, texts):
        g = jg.ground(text)
        scores = np.asarray(g.scores)
        order = np.argsort(scores)[-top:]
        colors = ["tab:green" if jg.INTENTS[i] == g.intent else "tab:gray" for i in order]
        ax.barh([jg.INTENTS[i] for i in order], scores[order], color=colors)
        ax.set_xlim(0, max(1.0, scores.max() + 0.05))
        ax.set_xlabel("intent score (similarity to spec C)", fontsize=8)
        ax.tick_params(labelsize=8)
        ax.set_title(
            "\n".join(textwrap.wrap(f'"{text}"', 42))
            + f"\n→ ({g.intent}, {g.intensity}), confidence {g.confidence:.2f}",
            fontsize=8.5,
        )
    return save(fig, path)


def splines_figure(path, intent: str = STAGE_TUPLE[0], intensity: str = STAGE_TUPLE[1]):
    """Stage 2: P = 4 Catmull-Rom controls per tendon -> the 150-step actuation (basis and one record)."""
    import jgrounding as jg

    lib = jg.load_library()
    tr = lib.train
    k = int(np.flatnonzero((tr.intent == jg.intent_index(intent)) & (tr.intensity == jg.intensity_index(intensity)))[0])
    c = tr.controls[k]  # (4, P)
    num_controls = c.shape[-1]
    u = np.asarray(jg.splines.reconstruct(c))
    tau = np.linspace(0.0, 1.0, u.shape[0])
    knots = np.arange(num_controls) / (num_controls - 1)
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.3), layout="constrained", width_ratios=(1, 1.5))
    basis = np.asarray(jg.splines.basis(u.shape[0], num_controls))
    for p in range(num_controls):
        a.plot(tau, basis[:, p], lw=1.6, label=f"B_{p}(τ)")
    a.axhline(0, color="k", lw=0.5)
    a.set_ylim(-0.32, 1.08)
    a.set_title(f"Catmull–Rom basis B (150 × {num_controls}): R(c; τ) = c · B(τ)", fontsize=9)
    a.set_xlabel("execution time τ")
    a.legend(fontsize=7, loc="lower center", ncol=num_controls)
    for j in range(u.shape[1]):
        b.plot(tau, u[:, j], color=TENDON_COLORS[j], lw=1.6, label=TENDON_LABELS[j])
        b.plot(knots, c[j], "o", color=TENDON_COLORS[j], ms=7, mec="k")
    b.set_ylim(-0.03, 1.03)
    b.set_xlabel("execution time τ")
    b.set_ylabel("tendon pull u")
    b.legend(fontsize=7, loc="upper left", ncol=2)
    b.set_title(
        f"{intent} / {intensity} (library record): 4 × {num_controls} controls (dots) → {u.shape[0]} × 4 actuation",
        fontsize=9,
    )
    return save(fig, path)


def sampling_figure(path, intent: str = STAGE_TUPLE[0], intensity: str = STAGE_TUPLE[1], num_samples: int = 30):
    """Stage 3: ``num_samples`` rectified-flow samples of :func:`jgrounding.sample` for one tuple."""
    import jax

    import jgrounding as jg
    from jgrounding.evaluation import metrics

    U = jg.sample(jax.random.key(0), intent, intensity, num_samples=num_samples)
    lib = jg.load_library()
    tr = lib.train
    demos = tr.u[(tr.intent == jg.intent_index(intent)) & (tr.intensity == jg.intensity_index(intensity))]
    tau = np.linspace(0.0, 1.0, U.shape[1])
    fig, axes = plt.subplots(1, 4, figsize=(12, 2.9), sharey=True, layout="constrained")
    for j, ax in enumerate(axes):
        ax.plot(tau, U[:, :, j].T, color=TENDON_COLORS[j], lw=0.7, alpha=0.45)
        ax.plot(tau, demos[:, :, j].T, color="k", lw=1.0, ls="--")
        ax.set_title(TENDON_LABELS[j], fontsize=9)
        ax.set_xlabel("execution time τ")
        ax.set_ylim(-0.03, 1.03)
    axes[0].set_ylabel("tendon pull u")
    div = float(metrics.pairwise_diversity(U))
    fig.suptitle(
        f"jg.sample(key, {intent!r}, {intensity!r}, num_samples={num_samples}): {num_samples} samples "
        f"(colour) and the {len(demos)} training demonstrations (black dashed); diversity {div:.3f}",
        fontsize=9,
    )
    return save(fig, path, colors=256)


def trunk_figure(path, intent: str = STAGE_TUPLE[0], intensity: str = STAGE_TUPLE[1], steps=TRUNK_STEPS):
    """Stage 4: the simulated whole-body motion of one sample: postures over time from both views."""
    import jax

    import jgrounding as jg

    u = jg.sample(jax.random.key(0), intent, intensity, num_samples=30)[0]
    r = sim.rollout(u)
    fig, axes = plt.subplots(2, len(steps), figsize=(2.9 * len(steps), 5.0), layout="constrained")
    for row, view in enumerate(render.BOTH_VIEWS):
        imgs, _ = render.frames(u, list(steps), view, labels=True, ghost=True)
        for ax, img, t in zip(axes[row], imgs, steps):
            ax.imshow(img)
            ax.set_axis_off()
            if row == 0:
                pulls = " ".join(f"{x:.2f}" for x in u[t])
                ax.set_title(
                    f"t = {t * sim.CONTROL_DT:.1f} s   u = [{pulls}]\n{r.user_distance[0, t]:.2f} m from the user",
                    fontsize=8,
                )
    fig.suptitle(
        f"{intent} / {intensity}, sample 0 on the trunk (top: side view, user on the right; bottom: rear "
        "view, robot's left on the left; thin blue rod: rest posture)",
        fontsize=9,
    )
    return save(fig, path, dpi=100, colors=PNG_COLORS)


def stages(out: Path = DOCS / "stages") -> list[str]:
    """One figure per pipeline stage (SPEC §1) for docs/how_it_works.md."""
    return [
        grounding_figure(out / "grounding.png"),
        splines_figure(out / "splines.png"),
        sampling_figure(out / "sampling.png"),
        trunk_figure(out / "sim.png"),
    ]


CLI_TEXT = "User seems sad; respond calmly with a gentle touch"


def cli_pictures(out: Path = DOCS / "cli", text: str = CLI_TEXT) -> list[str]:
    """``python -m jgrounding TEXT --samples 8`` into a scratch folder; its PNGs are copied to ``out``."""
    import contextlib
    import io
    import shutil
    import tempfile

    from jgrounding.apps import cli

    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(io.StringIO()):
        if cli.main([text, "--samples", "8", "--quiet", "--out", tmp]) != 0:
            raise RuntimeError("the command line failed")
        return [
            str(shutil.copyfile(Path(tmp) / name, out / name))
            for name in ("tendons.png", "keyframes.png", "posture.png", "motion.gif")
        ]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("which", choices=("primitives", "stages", "cli", "all"))
    args = p.parse_args(argv)
    written = []
    if args.which in ("primitives", "all"):
        written += primitives()
    if args.which in ("stages", "all"):
        written += stages()
    if args.which in ("cli", "all"):
        written += cli_pictures()
    for w in written:
        print(f"wrote {w} ({Path(w).stat().st_size // 1024} KB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
