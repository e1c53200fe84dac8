"""What a calibration leaves behind: the fitted trunk (MJCF with its provenance), a sidecar JSON, and a report
folder (Markdown, sysid's HTML report, a figure of the marker paths recorded against simulated).

Nothing is half-written: the report folder is built beside its place and moved in whole, the JSON and the MJCF
are written atomically, the MJCF last (a fitted trunk on disk always has its report and provenance).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from jgrounding.io import write_atomic
from jgrounding.sim import calibration
from jgrounding.sim import mjcf as tm


def recordings_hash(recordings) -> str:
    """Content hash of the recordings' names, clocks, commands and markers (the fitted trunk's provenance)."""
    from jgrounding import io

    parts = []
    for r in sorted(recordings, key=lambda r: r.name):
        parts += [r.name, *r.marker_names, np.ascontiguousarray(r.marker_s, np.float64).tobytes()]
        parts += [np.ascontiguousarray(a, np.float64).tobytes() for a in (r.t, r.u, r.markers)]
    return io.content_key("trunk recordings v1", *parts)


def provenance(result: calibration.Result, recordings, folder: str) -> dict:
    """Everything the fitted trunk came from: recordings (folder, content hash, split), parameters with bounds and
    uncertainty, RMS before / after, MuJoCo's version."""
    import mujoco

    params = {}
    for name in result.settings.parameters:
        lo, hi = result.settings.bound(name)
        params[name] = {
            "start": getattr(result.start, name),
            "value": getattr(result.fitted, name),
            "interval95": result.interval[name] if np.isfinite(result.interval[name]) else None,
            "bounds": [lo, hi],
            "at_bound": result.at_bound[name] or None,
        }
    return {
        "fitted_by": "python -m jgrounding.sim calibrate (mujoco.sysid)",
        "mujoco": mujoco.__version__,
        "recordings": {
            "folder": str(folder),
            "sha256": recordings_hash(recordings),
            "fit": result.fit_names,
            "validation": result.validation_names,
        },
        "parameters": params,
        "trunk": tm.to_mapping(result.fitted),
        "rms_m": {k: {w: list(v) for w, v in d.items()} for k, d in result.rms.items()},
        "iterations": result.iterations,
        "status": result.status,
        "seconds": round(result.seconds, 1),
    }


def fitted_xml(result: calibration.Result, prov: dict) -> str:
    """The fitted trunk's MJCF (full precision) with its provenance as a comment under the header."""
    values = ", ".join(f"{n}={getattr(result.fitted, n):.6g}" for n in result.settings.parameters)
    comment = (
        f"  <!-- Fitted by python -m jgrounding.sim calibrate (mujoco.sysid, MuJoCo {prov['mujoco']}) to recordings "
        f"sha256 {prov['recordings']['sha256']} ({prov['recordings']['folder']}): {values} -->"
    )
    lines = tm.build_xml(params=result.fitted, exact=True).split("\n")
    return "\n".join([*lines[:2], comment, *lines[2:]])


def _mm(x: float) -> str:
    return f"{1000 * x:.2f}"


def markdown(result: calibration.Result, prov: dict) -> str:
    rec = prov["recordings"]
    lines = [
        "# Trunk calibration",
        "",
        f"Recordings: `{rec['folder']}` (sha256 `{rec['sha256'][:16]}`), {len(rec['fit'])} fitted, "
        f"{len(rec['validation'])} held out for validation. MuJoCo {prov['mujoco']}, `mujoco.sysid` Gauss-Newton: "
        f"{result.iterations} iterations, {result.status}, {result.seconds:.1f} s.",
        "",
        "| parameter | start | fitted | ± 95 % | bounds | at a bound |",
        "|---|---|---|---|---|---|",
    ]
    for name, p in prov["parameters"].items():
        ci = "not determined" if p["interval95"] is None else f"{p['interval95']:.3g}"
        lines.append(
            f"| {name} | {p['start']:.4g} | {p['value']:.4g} | {ci} | [{p['bounds'][0]:g}, {p['bounds'][1]:g}] | "
            f"{p['at_bound'] or ''} |"
        )
    lines += [
        "",
        "| set | backbone RMS before (mm) | after (mm) | tip RMS before (mm) | after (mm) |",
        "|---|---|---|---|---|",
    ]
    for name, d in result.rms.items():
        (b0, t0), (b1, t1) = d["before"], d["after"]
        lines.append(f"| {name} | {_mm(b0)} | {_mm(b1)} | {_mm(t0)} | {_mm(t1)} |")
    lines += [
        "",
        "![marker paths](paths.png)",
        "",
        "Before: the starting trunk; after: the fitted one. Backbone RMS is over every marker, sample and recording; "
        "tip RMS over the marker farthest along the trunk. A parameter at a bound was stopped by it: widen that "
        "bound if it is physical. A 95 % interval 'not determined' means the recordings do not constrain that "
        "parameter (add recordings that excite it). `report.html` is sysid's report: signals, parameter "
        "distribution, covariance and the optimization trace.",
    ]
    return "\n".join(lines) + "\n"


def figure(result: calibration.Result, recordings, path: Path) -> None:
    """Marker paths of up to two recordings (held-out ones first), recorded vs simulated before and after; side view
    (x, z) and rear view (y, z)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    settings = result.settings
    by_name = {r.name: r for r in recordings}
    recs = [by_name[n] for n in (result.validation_names + result.fit_names)[:2]]
    sub = calibration.problem(recs, result.start, settings)
    before, after = calibration.paths(sub, result.start), calibration.paths(sub, result.fitted)
    fig, axes = plt.subplots(len(recs), 2, figsize=(9, 4.2 * len(recs)), squeeze=False)
    for row, (b, a) in enumerate(zip(before, after)):
        name, _, recorded, sim0 = b
        sim1 = a[3]
        for col, (k, label) in enumerate(((0, "x (m), toward the user"), (1, "y (m), robot's left"))):
            ax = axes[row, col]
            for m in range(recorded.shape[1]):
                ax.plot(
                    recorded[:, m, k], recorded[:, m, 2], color=f"C{m}", lw=2.0, label="recorded" if m == 0 else None
                )
                ax.plot(sim0[:, m, k], sim0[:, m, 2], color=f"C{m}", ls=":", lw=1.2, label="before" if m == 0 else None)
                ax.plot(sim1[:, m, k], sim1[:, m, 2], color=f"C{m}", ls="--", lw=1.2, label="after" if m == 0 else None)
            ax.set_xlabel(label)
            ax.set_ylabel("z (m)")
            ax.set_title(f"{name}: {'side' if col == 0 else 'rear'} view", fontsize=9)
            ax.set_aspect("equal", adjustable="datalim")
            ax.legend(fontsize=7)
    fig.tight_layout()
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    write_atomic(path, buf.getvalue())


def write(result: calibration.Result, out: str | Path, recordings, folder: str, *, html: bool = True, log=print):
    """Write the report folder ``<out stem>.report/``, the sidecar ``<out stem>.json`` and the fitted MJCF ``out``
    (in that order, each whole). Returns the paths written."""
    from mujoco import sysid

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    prov = provenance(result, recordings, folder)
    report_dir = out.with_name(out.stem + ".report")
    tmp = Path(tempfile.mkdtemp(prefix=f".{report_dir.name}.", dir=out.parent))
    try:
        write_atomic(tmp / "report.md", markdown(result, prov))
        figure(result, recordings, tmp / "paths.png")
        if html:
            prob = result.problem
            sysid.default_report(
                models_sequences=prob.sequences,
                initial_params=result.initial_params,
                opt_params=result.opt_params,
                residual_fn=prob.residual,
                opt_result=result.opt_result,
                title="Trunk calibration",
                save_path=tmp,
                build_model=prob.build_model,
                generate_videos=False,
            )
        os.chmod(tmp, 0o755)
        if report_dir.exists():
            shutil.rmtree(report_dir)
        os.replace(tmp, report_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    sidecar = out.with_suffix(".json")
    write_atomic(sidecar, json.dumps(prov, indent=1) + "\n")
    write_atomic(out, fitted_xml(result, prov))
    for p in (report_dir / "report.md", report_dir / "report.html", report_dir / "paths.png", sidecar, out):
        if p.exists():
            log(f"wrote {p}")
    return {"trunk": out, "sidecar": sidecar, "report": report_dir}
