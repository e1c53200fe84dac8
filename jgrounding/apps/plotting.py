"""Matplotlib figures shared by the CLI and the experiments (headless, Agg backend)."""

from __future__ import annotations

import io
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

TENDON_COLORS = ("tab:red", "tab:green", "tab:blue", "tab:orange")
TENDON_LABELS = ("tendon 0 (toward user)", "tendon 1 (left)", "tendon 2 (away)", "tendon 3 (right)")


def plot_tendons(
    ax, u, *, reference=None, alpha: float = 1.0, legend: bool = True, lw: float = 1.6, labels=None, dt=None
):
    """Draw tendon commands ``(T, N_u)`` or samples ``(K, T, N_u)`` on ``ax`` against time in seconds (step k
    at k * ``dt``; ``dt`` defaults to the control period, 1/30 s, so 150 steps span 5 s); reference dashed.

    ``labels``: one legend name per tendon (default: the built-in trunk's layout for 4 tendons, else
    ``tendon j``; pass an imported library's channel names for a lab's own trunk)."""
    if dt is None:
        from jgrounding.sim import CONTROL_DT as dt
    u = np.asarray(u)
    samples = u[None] if u.ndim == 2 else u
    tau = np.arange(samples.shape[-2]) * float(dt)
    colors = TENDON_COLORS if samples.shape[-1] == 4 else [f"C{j}" for j in range(samples.shape[-1])]
    if labels is None:
        labels = TENDON_LABELS if samples.shape[-1] == 4 else [f"tendon {j}" for j in range(samples.shape[-1])]
    for k, s in enumerate(samples):
        for j in range(s.shape[-1]):
            ax.plot(tau, s[:, j], color=colors[j], alpha=alpha, lw=lw, label=labels[j] if (legend and k == 0) else None)
    if reference is not None:
        ref = np.asarray(reference)
        for j in range(ref.shape[-1]):
            ax.plot(tau, ref[:, j], color=colors[j], ls="--", lw=1.2)
    ax.set_ylim(-0.03, 1.03)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tendon pull u")
    if legend:
        ax.legend(fontsize=7, loc="upper right")
    return ax


def save(fig, path: str | os.PathLike, dpi: int = 110, colors: int | None = None) -> str:
    """Save a figure atomically as PNG and close it; ``colors`` (e.g. 128) stores it with a palette of
    that many colours, which keeps rendered pictures small enough for the docs."""
    from jgrounding.io import write_atomic

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    data = buf.getvalue()
    if colors is not None:
        from PIL import Image

        img = Image.open(io.BytesIO(data)).convert("RGB").quantize(colors, dither=Image.Dither.NONE)
        buf = io.BytesIO()
        img.save(buf, format="PNG", optimize=True)
        data = buf.getvalue()
    write_atomic(path, data)
    return str(path)


def tendon_figure(u, path, *, title: str = "", reference=None, labels=None):
    """One-panel PNG of tendon commands (samples overlaid faintly when ``u`` is ``(K, T, 4)``); ``labels``:
    as :func:`plot_tendons`."""
    u = np.asarray(u)
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    if u.ndim == 3 and u.shape[0] > 1:
        plot_tendons(ax, u[1:], alpha=0.18, legend=False, lw=0.8)
        plot_tendons(ax, u[0], reference=reference, labels=labels)
        title = f"{title}: sample 0 (bold) and {u.shape[0] - 1} more (faint)" if title else title
    else:
        plot_tendons(ax, u.reshape(-1, *u.shape[-2:])[0], reference=reference, labels=labels)
    # Below the axes, so that it never hides a curve.
    ax.legend(fontsize=7, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.17), frameon=False)
    ax.set_title(title, fontsize=9)
    return save(fig, path)
