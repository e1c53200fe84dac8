"""Which rod library makes the physical reference, measured: ``python -m experiments.trunk_reference_engines``.

Both candidates simulate one command trajectory (150 x 4 at 30 Hz: tendon 0 at full pull from 0.33 s to
2.67 s, tendon 1 at 0.7 from 2 s to 4.67 s, tendon 3 at 0.4 from 3 s) on the reference's geometry and
material (:mod:`jgrounding.sim.reference`), from rest under gravity:

- PyElastica 1.0.0 (``CosseratRod``, position Verlet, numba), at 20, 30, 40, 60 and 80 elements: the time per
  trajectory and the backbone / tip RMS of each against 80 elements (the discretisation error);
- soromox 0.5.0 (JAX, piecewise-constant strain, its tendon actuator ``ThreadlikeActuator.tendons``), 10
  constant-strain sections with the radius of their middle and the routing radius tapering linearly (its
  routing is linear in s), Kelvin-Voigt material damping (``--soromox-viscosity`` Pa s; it has no
  velocity damper like PyElastica's), RK4 at fixed steps ``--soromox-dt`` inside one ``jax.jit``.

It prints the times and the tip path of each and writes ``results/trunk_reference_engines.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from jgrounding.io import write_atomic
from jgrounding.sim import reference

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "results" / "trunk_reference_engines.md"
ELEMENTS = (20, 30, 40, 60, 80)


def trajectory() -> np.ndarray:
    u = np.zeros((150, 4))
    u[10:80, 0] = 1.0
    u[60:140, 1] = 0.7
    u[90:, 3] = 0.4
    return u


def pyelastica(u: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """(markers (T, M, 3) without noise, seconds for the trajectory after the rest is settled)."""
    reference.rest_state(u[0], n)
    t0 = time.perf_counter()
    nodes = reference.simulate(u, n_elements=n)
    return reference.markers(nodes[:-1], noise=0.0), time.perf_counter() - t0


def soromox(u: np.ndarray, sections: int, dt: float, viscosity: float) -> tuple[np.ndarray | None, float, float]:
    """(markers (T, M, 3) or None when it blew up, seconds of the 5 s trajectory, seconds to compile and settle)."""
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    from soromox.actuation import ThreadlikeActuator, ThreadlikeRouting
    from soromox.systems import PCS, LinkSpec

    p = reference.PARAMETERS
    mids = (np.arange(sections) + 0.5) * p.length / sections
    links = [
        LinkSpec.circular(
            length=p.length / sections,
            radius=float(r),
            density=p.density,
            young_modulus=p.youngs_modulus,
            shear_modulus=p.shear_modulus,
            material_damping_coefficient=viscosity,
            reference_strain=[0, 0, 0, 1, 0, 0],
        )
        for r in p.radius(mids)
    ]
    th = np.deg2rad(p.tendon_angles_deg)
    # The base pose turns the material x axis (the backbone) to world -z; material y = world y, z = world x.
    dirs = np.stack([0 * th, np.sin(th), np.cos(th)], 1)
    routing = ThreadlikeRouting.linear(
        intercept=jnp.asarray(p.base_radius * dirs),
        slope=jnp.asarray((p.tip_radius - p.base_radius) / p.length * dirs),
        start_segment_index=0,
        end_segment_index=(sections - 1,) * len(th),
    )
    pose = jnp.array([0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0, 0.0, p.base_height])
    robot = PCS.from_links(
        links,
        gravity=jnp.array([0.0, 0.0, -p.gravity]),
        base_pose=pose,
        actuators=ThreadlikeActuator.tendons(routing),
        backend="jax",
    )
    nq = int(robot.num_active_strains)
    sub = max(1, int(round((1.0 / reference.RECORD_HZ) / dt)))
    h = (1.0 / reference.RECORD_HZ) / sub

    def f(y, a):
        return robot.forward_dynamics(0.0, y, (a, jnp.zeros(nq)))

    def rk4(y, a):
        k1 = f(y, a)
        k2 = f(y + h / 2 * k1, a)
        k3 = f(y + h / 2 * k2, a)
        k4 = f(y + h * k3, a)
        return y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    def sample(y, a):
        y, _ = jax.lax.scan(lambda yy, _: (rk4(yy, a), None), y, None, length=sub)
        return y, y

    run = jax.jit(lambda y0, seq: jax.lax.scan(sample, y0, seq))
    t0 = time.perf_counter()
    y1, _ = run(jnp.zeros(2 * nq), jnp.zeros((int(reference.SETTLE_S * reference.RECORD_HZ), len(th))))
    y1.block_until_ready()
    setup = time.perf_counter() - t0
    per = int(round(reference.RECORD_HZ / 30))
    seq = jnp.asarray(np.repeat(u, per, axis=0) * p.max_tendon_force)
    t0 = time.perf_counter()
    y_prev = jnp.concatenate([y1[None], run(y1, seq)[1][:-1]])
    y_prev.block_until_ready()
    seconds = time.perf_counter() - t0
    q = np.asarray(y_prev[:, :nq])
    if not np.all(np.isfinite(q)):
        return None, seconds, setup
    fk = jax.jit(jax.vmap(lambda qq, s: robot.forward_kinematics(qq, s=s)[:3, 3], in_axes=(None, 0)))
    s = jnp.asarray(reference.MARKER_S)
    return np.stack([np.asarray(fk(jnp.asarray(qq), s)) for qq in q]), seconds, setup


def _rms(a, b) -> tuple[float, float]:
    d2 = ((a - b) ** 2).sum(-1)
    return float(np.sqrt(d2.mean())), float(np.sqrt(d2[:, -1].mean()))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--soromox-dt", type=float, nargs="+", default=[2e-4, 1e-3], help="RK4 steps to try (s)")
    ap.add_argument("--soromox-viscosity", type=float, default=300.0, help="Kelvin-Voigt viscosity (Pa s)")
    ap.add_argument("--sections", type=int, default=10, help="soromox constant-strain sections")
    ap.add_argument("--no-write", action="store_true", help="print only")
    args = ap.parse_args(argv)
    u = trajectory()
    rows, paths = [], {}
    for n in ELEMENTS:
        paths[n], sec = pyelastica(u, n)
        rows.append((f"PyElastica, {n} elements", sec))
        print(f"PyElastica {n} elements: {sec:.2f} s per trajectory", flush=True)
    ref = paths[ELEMENTS[-1]]
    conv = [(n, *_rms(paths[n], ref)) for n in ELEMENTS[:-1]]
    for n, bb, tip in conv:
        print(f"  {n} vs {ELEMENTS[-1]} elements: backbone RMS {1e3 * bb:.1f} mm, tip RMS {1e3 * tip:.1f} mm")
    sx, tips = [], {f"PyElastica {reference.N_ELEMENTS} elements": paths[reference.N_ELEMENTS][:, -1]}
    for dt in args.soromox_dt:
        m, sec, setup = soromox(u, args.sections, dt, args.soromox_viscosity)
        diff = _rms(m, paths[reference.N_ELEMENTS]) if m is not None else None
        sx.append((dt, sec, setup, diff))
        if m is not None:
            tips[f"soromox, RK4 dt {dt:g} s"] = m[:, -1]
        what = (
            f"backbone RMS {1e3 * diff[0]:.1f} mm, tip RMS {1e3 * diff[1]:.1f} mm from PyElastica"
            if diff
            else "blew up (NaN)"
        )
        print(
            f"soromox {args.sections} sections, RK4 dt {dt:g} s: {sec:.1f} s per trajectory ({setup:.0f} s to compile "
            f"and settle); {what}",
            flush=True,
        )
    lines = [
        "# The physical reference: PyElastica or soromox, measured",
        "",
        "Written by `python -m experiments.trunk_reference_engines` (one trajectory: "
        "tendon 0 at 1 from 0.33 to 2.67 s, tendon 1 at 0.7 from 2 to 4.67 s, tendon 3 at 0.4 from 3 s; "
        "the reference's geometry and material).",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, 1-min load average "
        f"{os.getloadavg()[0]:.1f} at the end (a shared machine: times are upper bounds).",
        "",
        "| engine | seconds per 5 s trajectory |",
        "|---|---|",
        *[f"| {name} | {sec:.2f} |" for name, sec in rows],
        *[
            f"| soromox {args.sections} sections, RK4 dt {dt:g} s | {sec:.1f}"
            + ("" if d else " (blew up: NaN)")
            + f" (+{setup:.0f} s to compile and settle) |"
            for dt, sec, setup, d in sx
        ],
        "",
        f"PyElastica's discretisation error, against {ELEMENTS[-1]} elements:",
        "",
        "| elements | backbone RMS (mm) | tip RMS (mm) |",
        "|---|---|---|",
        *[f"| {n} | {1e3 * bb:.1f} | {1e3 * tip:.1f} |" for n, bb, tip in conv],
        "",
        f"soromox against PyElastica at {reference.N_ELEMENTS} elements (its damping is a material viscosity of "
        f"{args.soromox_viscosity:g} Pa s, PyElastica's a velocity damper, so the paths differ in their swing too):",
        "",
        "| soromox | backbone RMS (mm) | tip RMS (mm) |",
        "|---|---|---|",
        *[
            f"| RK4 dt {dt:g} s | " + (f"{1e3 * d[0]:.1f} | {1e3 * d[1]:.1f} |" if d else "NaN | NaN |")
            for dt, _, _, d in sx
        ],
        "",
        "Tip at 1, 2, 3, 4 and 5 s (m):",
        "",
        "| engine | " + " | ".join(f"{k} s" for k in range(1, 6)) + " |",
        "|---|" + "---|" * 5,
        *[
            f"| {name} | "
            + " | ".join(" ".join(f"{x:+.3f}" for x in tip[min(120 * k, len(tip) - 1)]) for k in range(1, 6))
            + " |"
            for name, tip in tips.items()
        ],
    ]
    if not args.no_write:
        write_atomic(RESULTS, "\n".join(lines) + "\n")
        print(f"wrote {RESULTS.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
