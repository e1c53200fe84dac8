"""Figures of the ablation (like the paper's Fig. 4), written by ``python -m experiments.ablation``.

- ``results/fig4_tendons.png``: for two held-out tuples, each method's tendon commands (seed 0, first
  sample) against the dashed library reference, with the RMS, and the simulated final posture of every
  method beside the reference's (side view x-z and front view y-z).
- ``results/diversity.png``: 30 samples of one tuple overlaid for RF, DDPM and the spline CNN.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jgrounding import sim
from jgrounding.apps.plotting import TENDON_COLORS, plot_tendons, plt, save
from jgrounding.evaluation import metrics
from jgrounding.generators import methods
from jgrounding.sim import mjcf as sim_model
from jgrounding.vocabulary import INTENSITIES, INTENTS, intensity_index, intent_index

FIG4_TUPLES = (("embracing", "emphatic"), ("withdrawal", "moderate"))
DIVERSITY_TUPLE = ("embracing", "emphatic")
METHOD_COLORS = ("tab:gray", "tab:brown", "tab:purple", "tab:cyan", "tab:red")


def heldout_index(lib, intent: str, intensity: str) -> int:
    m, z = intent_index(intent), intensity_index(intensity)
    return int(np.flatnonzero((lib.heldout.intent == m) & (lib.heldout.intensity == z))[0])


def _posture(ax, backbone, plane: tuple[int, int], **kw):
    ax.plot(backbone[:, plane[0]], backbone[:, plane[1]], marker="o", ms=2, **kw)


def fig4(samples: dict[str, np.ndarray], lib, path: Path) -> str:
    """``samples[method]``: ``(64, K, 150, 4)`` of seed 0."""
    names = [m for m in methods.METHODS if m in samples]
    fig, axes = plt.subplots(
        len(FIG4_TUPLES), len(names) + 2, figsize=(3.0 * (len(names) + 2), 2.9 * len(FIG4_TUPLES)), squeeze=False
    )
    for row, (intent, intensity) in enumerate(FIG4_TUPLES):
        j = heldout_index(lib, intent, intensity)
        ref = lib.heldout.u[j]
        u = np.stack([samples[m][j, 0] for m in names])
        for col, m in enumerate(names):
            ax = axes[row, col]
            plot_tendons(ax, u[col], reference=ref, legend=(row == 0 and col == 0), lw=1.3)
            ax.set_title(f"{methods.DISPLAY[m]}\nRMS {float(metrics.rms(u[col], ref)):.3f}", fontsize=8)
            if col:
                ax.set_ylabel("")
        axes[row, 0].set_ylabel(f"{intent} / {intensity}\ntendon pull u", fontsize=8)
        final = sim.rollout(np.concatenate([ref[None], u])).backbone[:, -1]  # final postures (1 + M, 11, 3)
        for k, (plane, label) in enumerate(
            (((0, 2), "side view: x (toward user) [m]"), ((1, 2), "front view: y (left) [m]"))
        ):
            ax = axes[row, len(names) + k]
            _posture(ax, final[0], plane, color="k", ls="--", lw=2, label="library reference")
            for i, m in enumerate(names):
                _posture(ax, final[i + 1], plane, color=METHOD_COLORS[i], lw=1.2, label=methods.DISPLAY[m])
            if plane == (0, 2):
                ax.axvspan(sim_model.USER_TORSO_X - sim_model.USER_TORSO_RADIUS, 0.7, color="tab:orange", alpha=0.12)
                ax.text(0.30, 0.45, "user", fontsize=7, color="tab:orange")
            ax.set_xlim(-0.55, 0.6)
            ax.set_ylim(0.35, 1.15)
            ax.set_aspect("equal")
            ax.set_xlabel(label, fontsize=7)
            ax.set_title("final posture (simulated)", fontsize=8)
        if row == 0:
            axes[row, -1].legend(fontsize=6, loc="lower right")
    fig.suptitle("Held-out tuples: generated tendon commands (solid) vs the library reference (dashed)", fontsize=10)
    fig.tight_layout()
    return save(fig, path)


def diversity(samples: dict[str, np.ndarray], lib, path: Path) -> str:
    names = [m for m in ("tuple_spline_cnn", "tuple_spline_ddpm", "tuple_spline_rf") if m in samples]
    j = heldout_index(lib, *DIVERSITY_TUPLE)
    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 3.2), squeeze=False)
    for ax, m in zip(axes[0], names):
        u = samples[m][j]
        plot_tendons(ax, u, alpha=0.25, legend=False, lw=0.8)
        d = float(metrics.pairwise_diversity(u))
        ax.set_title(f"{methods.DISPLAY[m]}: {u.shape[0]} samples, diversity {d:.3f}", fontsize=8)
    for jj, c in enumerate(TENDON_COLORS):
        axes[0, 0].plot([], [], color=c, label=f"tendon {jj}")
    axes[0, 0].legend(fontsize=6, loc="upper right")
    fig.suptitle(f"{DIVERSITY_TUPLE[0]} / {DIVERSITY_TUPLE[1]}", fontsize=10)
    fig.tight_layout()
    return save(fig, path)


def write(samples: dict[str, np.ndarray], lib, out: str | Path) -> list[str]:
    out = Path(out)
    return [fig4(samples, lib, out / "fig4_tendons.png"), diversity(samples, lib, out / "diversity.png")]


assert all(t[0] in INTENTS and t[1] in INTENSITIES for t in FIG4_TUPLES + (DIVERSITY_TUPLE,))
