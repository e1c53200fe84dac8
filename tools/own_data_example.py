"""The worked example of docs/own_data.md, run end to end: ``python -m tools.own_data_example``.

Runs the page's commands on ``assets/examples/trunk_recordings`` (made by
``python -m tools.make_example_recordings``) into ``runs/own_data/``: import, a short training run,
sampling through ``jg.sample(..., checkpoint=...)`` and the CLI's command stream; then draws each
output into ``docs/own_data/*.png`` and prints the numbers the page quotes. ``--steps`` sets the
training length (default 2000, about a minute on two CPU cores).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
FOLDER = "assets/examples/trunk_recordings"
WORK = Path("runs/own_data")
FIGURES = ROOT / "docs" / "own_data"
SHOWN = ("nodding", "emphatic")  # the tuple sampled and streamed


def run(*args: str) -> str:
    """One documented command, echoed and run from the repository root; its output is returned."""
    print("$", " ".join(args), flush=True)
    out = subprocess.run([sys.executable, *args], cwd=ROOT, capture_output=True, text=True)
    print(out.stdout[-3000:], end="", flush=True)
    if out.returncode:
        raise SystemExit(f"command failed ({out.returncode}):\n{out.stderr[-3000:]}")
    return out.stdout


def recording_figure(path: Path) -> str:
    import matplotlib.pyplot as plt

    from jgrounding.apps import plotting

    data = np.genfromtxt(ROOT / FOLDER / "nodding_emphatic_01.csv", delimiter=",", names=True)
    fig, ax = plt.subplots(figsize=(6.4, 3.2))
    for j, name in enumerate(data.dtype.names[1:]):
        ax.plot(data["time"], data[name], lw=0.8, color=plotting.TENDON_COLORS[j], label=name)
    ax.set_xlabel("time (s), 100 Hz clock")
    ax.set_ylabel("cable pull (mm)")
    ax.set_title("nodding_emphatic_01.csv as recorded (lab units, sensor noise)", fontsize=9)
    ax.legend(fontsize=7, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    return plotting.save(fig, path)


def library_figure(lib, path: Path, samples: dict | None = None) -> str:
    """One panel per tuple: the library's realizations (train solid, held-out dashed), or ``samples``."""
    import matplotlib.pyplot as plt

    from jgrounding.apps import plotting
    from jgrounding.vocabulary import INTENSITIES, INTENTS

    tuples = sorted({(int(m), int(z)) for m, z in zip(lib.train.intent, lib.train.intensity)})
    fig, axes = plt.subplots(1, len(tuples), figsize=(3.2 * len(tuples), 2.8), sharey=True)
    for ax, (m, z) in zip(np.atleast_1d(axes), tuples):
        held = lib.heldout.u[(lib.heldout.intent == m) & (lib.heldout.intensity == z)][0]
        if samples is None:
            train = lib.train.u[(lib.train.intent == m) & (lib.train.intensity == z)]
            plotting.plot_tendons(ax, train, alpha=0.8, legend=False, lw=1.0, reference=held)
        else:
            plotting.plot_tendons(ax, samples[(m, z)], alpha=0.35, legend=False, lw=0.8, reference=held)
        ax.set_title(f"{INTENTS[m]} / {INTENSITIES[z]}", fontsize=9)
    fig.suptitle(
        "imported library: train realizations (solid), held-out (dashed)"
        if samples is None
        else "samples of the trained checkpoint (8 per tuple) and the held-out realization (dashed)",
        fontsize=9,
    )
    fig.tight_layout()
    return plotting.save(fig, path)


def commands_figure(csv_path: Path, path: Path) -> str:
    import matplotlib.pyplot as plt

    from jgrounding.apps import export, plotting

    header, u = export.read_command_stream_csv(csv_path)
    t = np.arange(len(u)) * header["control_dt_s"]
    fig, ax = plt.subplots(figsize=(6.4, 3.2))
    for j in range(u.shape[1]):
        ax.step(t, u[:, j], where="post", lw=0.9, color=plotting.TENDON_COLORS[j], label=header["channels"][j])
    ax.set_xlabel(f"time (s), {header['control_rate_hz']:.0f} Hz control rate")
    ax.set_ylabel("normalized pull")
    ax.set_title(
        f"commands.csv: ({header['intent']}, {header['intensity']}), bounds {header['bounds']}, "
        f"slew <= {header['max_slew_per_step']}/step",
        fontsize=9,
    )
    ax.legend(fontsize=7, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    return plotting.save(fig, path)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--steps", type=int, default=2000)
    args = p.parse_args(argv)
    lib_path, ckpt, cli_out = WORK / "my_library.npz", WORK / "mine", WORK / "cli"
    run("-m", "jgrounding.library", "import", FOLDER, "--out", str(lib_path), "--controls", "4", "--simulate")
    run(
        "-m",
        "experiments.train",
        "--library",
        str(lib_path),
        "--out",
        str(ckpt),
        "--steps",
        str(args.steps),
        "--chunk",
        str(min(500, args.steps)),
    )
    run(
        "-m",
        "jgrounding",
        "--intent",
        SHOWN[0],
        "--intensity",
        SHOWN[1],
        "--checkpoint",
        str(ckpt),
        "--out",
        str(cli_out),
        "--no-render",
    )

    import jax

    import jgrounding as jg
    from jgrounding.evaluation import metrics
    from jgrounding.vocabulary import INTENSITIES, INTENTS

    lib = jg.load_library(ROOT / lib_path)
    card = json.loads((ROOT / lib_path).with_suffix(".json").read_text())
    print("card: counts", card["counts_per_tuple"], "rejected", card["rejected"], "dropped", card["dropped"])
    samples = {}
    for k, (m, z) in enumerate(sorted({(int(m), int(z)) for m, z in zip(lib.train.intent, lib.train.intensity)})):
        u = jg.sample(jax.random.key(k), INTENTS[m], INTENSITIES[z], num_samples=8, checkpoint=str(ROOT / ckpt))
        samples[(m, z)] = u
        held = lib.heldout.u[(lib.heldout.intent == m) & (lib.heldout.intensity == z)][0]
        r = np.asarray(metrics.rms(u, held[None]))
        print(
            f"{INTENTS[m]}/{INTENSITIES[z]}: RMS of 8 samples to the held-out realization: mean {r.mean():.3f}, "
            f"within tau = {metrics.TAU_RMS}: {int((r <= metrics.TAU_RMS).sum())}/8"
        )
    for path in (
        recording_figure(FIGURES / "recording.png"),
        library_figure(lib, FIGURES / "imported.png"),
        library_figure(lib, FIGURES / "samples.png", samples),
        commands_figure(ROOT / cli_out / "commands.csv", FIGURES / "commands.png"),
    ):
        print("wrote", path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
