"""The physical reference: a Cosserat rod of the trunk's geometry in PyElastica, driven by four tendons.

It stands for a trunk we do not control. Its parameters (:data:`PARAMETERS`) are fixed here, each with its
source (:data:`SOURCES`), and are never tuned toward the MuJoCo trunk of :mod:`jgrounding.sim.model`; only the
geometry and the actuation are shared with it, because they are the robot's design, not its physics.

The rod. PyElastica's ``CosseratRod`` (Gazzola et al. 2018, R. Soc. Open Sci. 5:171628): a discretised
Cosserat rod with bending, twist, shear and axial stretch, integrated with its position-Verlet stepper. It
hangs from a clamped base at ``(0, 0, BASE_HEIGHT)`` along -z under gravity (-z), as the MuJoCo trunk does.
Its radius tapers geometrically from 45 mm at the base to 14 mm at the tip over 0.70 m.

The tendons. Four tendons at 0, 90, 180 and 270 degrees (0 toward +x, the user; 1 toward +y), each routed
along the body at the body's radius (the routing radius of the MuJoCo trunk) through a guide at every
element and anchored at the tip. Tendon j pulls with tension ``u_j * MAX_TENDON_FORCE``. The loads follow
the discrete form of the general tendon-routing model of Rucker & Webster (2011, IEEE T-RO 27(6):1033): the
tendon is straight between consecutive guides, so each guide receives the tension along both neighbouring
tendon segments (the anchor along one), applied at the guide, i.e. a force at the element's centre and the
couple of its offset; the base takes the rest. A straight rod thus feels a compressive force and the
couple ``T r`` at the tip, and a bent one also the guides' pressure.

What it records is what a lab's motion capture records: the positions of markers on the backbone at arc
lengths :data:`MARKER_S` (the tip among them) at :data:`RECORD_HZ`, with Gaussian noise of
:data:`MARKER_NOISE_M` per axis. The rod starts from its rest under gravity (settled once, heavily damped).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from jgrounding.sim import mjcf as tm
from jgrounding.sim.measures import CONTROL_DT

RECORD_HZ = 120  # samples per second of the recordings (4 per control step)
MARKER_NAMES = ("quarter", "mid", "three_quarter", "tip")
MARKER_S = (0.175, 0.35, 0.525, 0.70)  # m, arc length from the base along the undeformed backbone
MARKER_NOISE_M = 0.5e-3  # m, standard deviation per axis of the recorded marker positions
N_ELEMENTS = 40  # rod elements; the error against 80: python -m experiments.trunk_reference_engines
CFL = 0.25  # time step = CFL x element length / sqrt(E / density) (the rod's axial wave speed)
SETTLE_S = 1.5  # s of heavily damped settling under gravity before a recording starts
SETTLE_DAMPING = 30.0  # 1/s during the settling (the first bending mode overdamped)


def time_step(n_elements: int, params=None) -> tuple[float, int]:
    """(time step, steps per recorded sample): the largest step within :data:`CFL` x element length / the axial
    wave speed sqrt(E / density) that divides 1 / :data:`RECORD_HZ`."""
    p = params or PARAMETERS
    limit = CFL * (p.length / n_elements) / math.sqrt(p.youngs_modulus / p.density)
    substeps = math.ceil((1.0 / RECORD_HZ) / limit)
    return (1.0 / RECORD_HZ) / substeps, substeps


@dataclasses.dataclass(frozen=True)
class RodParameters:
    """The reference's physical parameters (SI units); :data:`SOURCES` gives each one's source."""

    length: float = tm.TRUNK_LENGTH
    base_radius: float = tm.BASE_RADIUS
    tip_radius: float = tm.TIP_RADIUS
    base_height: float = tm.BASE_HEIGHT
    tendon_angles_deg: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0)
    routing_fraction: float = 1.0  # tendon offset / body radius at each cross-section
    max_tendon_force: float = tm.MAX_TENDON_FORCE
    youngs_modulus: float = 0.593e6  # Pa
    poisson_ratio: float = 0.5
    density: float = 1080.0  # kg/m^3
    damping_ratio: float = 0.05  # of the first bending mode
    first_mode_hz: float = 1.19  # the rod's first bending mode, measured (see SOURCES)
    gravity: float = 9.81  # m/s^2

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def damping_constant(self) -> float:
        """PyElastica's uniform damping rate (1/s) that gives the first bending mode ``damping_ratio``:
        ``2 zeta omega_1``."""
        return 2.0 * self.damping_ratio * 2.0 * math.pi * self.first_mode_hz

    def radius(self, s: np.ndarray) -> np.ndarray:
        """Body radius at arc length ``s``: geometric taper from the base radius to the tip radius."""
        return self.base_radius * (self.tip_radius / self.base_radius) ** (np.asarray(s) / self.length)


PARAMETERS = RodParameters()

SOURCES = {
    "length": "the trunk's design: jgrounding.sim.mjcf.TRUNK_LENGTH",
    "base_radius": "the trunk's design: jgrounding.sim.mjcf.BASE_RADIUS",
    "tip_radius": "the trunk's design: jgrounding.sim.mjcf.TIP_RADIUS (geometric taper, as the capsules')",
    "base_height": "the trunk's design: jgrounding.sim.mjcf.BASE_HEIGHT (the base mount, the frame origin + z)",
    "tendon_angles_deg": "the trunk's design: tendons 0-3 at +x, +y, -x, -y (jgrounding.sim.mjcf)",
    "routing_fraction": "the trunk's design: the MuJoCo trunk routes each tendon at the segment's radius",
    "max_tendon_force": "the trunk's design: jgrounding.sim.mjcf.MAX_TENDON_FORCE, the pull at u = 1",
    "youngs_modulus": "Smooth-On Dragon Skin 30 technical bulletin: 100% modulus 86 psi = 0.593 MPa, taken as "
    "the Young's modulus (a platinum-cure silicone commonly cast for cable-driven soft arms)",
    "poisson_ratio": "rubber is nearly incompressible (nu = 0.5; PyElastica's default for soft rods), so G = E / 3",
    "density": "Smooth-On Dragon Skin 30 technical bulletin: specific gravity 1.08 g/cc",
    "damping_ratio": "assumed: half the loss factor tan(delta) ~ 0.1 of platinum-cure silicone rubber near 1 Hz "
    "(zeta = tan(delta) / 2); no datasheet gives it, so it is the least certain value of the set",
    "first_mode_hz": "measured on this rod: the peak of the tip's spectrum in a free decay after a small pull "
    "(python -m experiments.trunk_reference prints it again)",
    "gravity": "standard gravity",
}


def check_commands(u) -> np.ndarray:
    """``(T, 4)`` commands in [0, 1], finite, as float64 (else ``ValueError``)."""
    u = np.asarray(u, np.float64)
    n = len(PARAMETERS.tendon_angles_deg)
    if u.ndim != 2 or u.shape[1] != n or u.shape[0] < 1:
        raise ValueError(f"commands must have shape (T, {n}) (one column per tendon), got {u.shape}")
    if not np.all(np.isfinite(u)) or u.min() < 0.0 or u.max() > 1.0:
        raise ValueError("commands must be finite and inside [0, 1] (0 = slack, 1 = MAX_TENDON_FORCE)")
    return u


try:
    from numba import njit
except ImportError as e:  # pragma: no cover
    raise ImportError(
        "the physical reference needs PyElastica and numba: pip install pyelastica==1.0.0 numba==0.68.1"
    ) from e


@njit(cache=True)
def tendon_loads(x, Q, offsets, tension, forces, torques):  # pragma: no cover (compiled)
    """Add the tendons' loads to ``forces`` (3, n + 1; lab frame) and ``torques`` (3, n; material frame): node
    positions ``x`` (3, n + 1), directors ``Q`` (3, 3, n), ``offsets`` (K, n + 1, 2) of each tendon's routing
    points in the material frame (d1, d2), ``tension`` (K,) in newtons."""
    n = Q.shape[2]
    P = np.empty((3, n + 1))
    for j in range(offsets.shape[0]):
        T = tension[j]
        if T <= 0.0:
            continue
        for a in range(3):  # the tendon's exit at the base, then one guide per element (at its centre)
            P[a, 0] = x[a, 0] + Q[0, a, 0] * offsets[j, 0, 0] + Q[1, a, 0] * offsets[j, 0, 1]
        for e in range(n):
            for a in range(3):
                c = 0.5 * (x[a, e] + x[a, e + 1])
                P[a, e + 1] = c + Q[0, a, e] * offsets[j, e + 1, 0] + Q[1, a, e] * offsets[j, e + 1, 1]
        for k in range(1, n + 1):
            f0, f1, f2 = 0.0, 0.0, 0.0
            for nb in (k - 1, k + 1):
                if nb > n:
                    continue
                d0, d1, d2 = P[0, nb] - P[0, k], P[1, nb] - P[1, k], P[2, nb] - P[2, k]
                norm = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                f0 += T * d0 / norm
                f1 += T * d1 / norm
                f2 += T * d2 / norm
            e = k - 1
            forces[0, e] += 0.5 * f0
            forces[1, e] += 0.5 * f1
            forces[2, e] += 0.5 * f2
            forces[0, e + 1] += 0.5 * f0
            forces[1, e + 1] += 0.5 * f1
            forces[2, e + 1] += 0.5 * f2
            r0 = P[0, k] - 0.5 * (x[0, e] + x[0, e + 1])
            r1 = P[1, k] - 0.5 * (x[1, e] + x[1, e + 1])
            r2 = P[2, k] - 0.5 * (x[2, e] + x[2, e + 1])
            t0, t1, t2 = r1 * f2 - r2 * f1, r2 * f0 - r0 * f2, r0 * f1 - r1 * f0
            for b in range(3):  # lab-frame couple -> the element's material frame
                torques[b, e] += Q[b, 0, e] * t0 + Q[b, 1, e] * t1 + Q[b, 2, e] * t2


class Rod:
    """One PyElastica simulation of the trunk: ``Rod(n_elements).run(u)``."""

    def __init__(self, n_elements: int = N_ELEMENTS, params: RodParameters = PARAMETERS, *, damping=None):
        import elastica as ea

        if n_elements < 8:
            raise ValueError(f"n_elements must be >= 8 (a coarser rod is unstable at this time step), got {n_elements}")
        p = self.params = params
        self.n = n_elements
        ds = p.length / n_elements
        self.s_nodes = np.arange(n_elements + 1) * ds
        s_el = (np.arange(n_elements) + 0.5) * ds
        self.dt, self.substeps = time_step(n_elements, p)

        class _Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
            pass

        angles = np.deg2rad(p.tendon_angles_deg)
        # Offsets in the material frame (d1 = +x, d2 = d3 x d1 = -y for a rod along -z), per routing point:
        # the base exit (the first element's radius) and each element's centre.
        r = p.routing_fraction * np.concatenate([[p.radius(0.0)], p.radius(s_el)])
        unit = np.stack([np.cos(angles), -np.sin(angles)], axis=-1)  # (K, 2)
        offsets = np.ascontiguousarray(unit[:, None, :] * r[None, :, None])  # (K, n + 1, 2)
        self.tension = np.zeros(len(angles))
        tension = self.tension

        class _Tendons(ea.NoForces):
            def apply_torques(self, system, time=0.0):
                tendon_loads(
                    system.position_collection,
                    system.director_collection,
                    offsets,
                    tension,
                    system.external_forces,
                    system.external_torques,
                )

        self.sim = _Sim()
        self.rod = ea.CosseratRod.straight_rod(
            n_elements,
            np.array([0.0, 0.0, p.base_height]),
            np.array([0.0, 0.0, -1.0]),
            np.array([1.0, 0.0, 0.0]),
            p.length,
            p.radius(s_el),
            p.density,
            youngs_modulus=p.youngs_modulus,
            shear_modulus=p.shear_modulus,
        )
        self.sim.append(self.rod)
        self.sim.constrain(self.rod).using(
            ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
        )
        self.sim.add_forcing_to(self.rod).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -p.gravity]))
        self.sim.add_forcing_to(self.rod).using(_Tendons)
        rate = p.damping_constant if damping is None else damping
        self.sim.dampen(self.rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=rate, time_step=self.dt)
        self.sim.finalize()
        self.stepper = ea.PositionVerlet()
        self.time = 0.0

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.rod.position_collection.copy(), self.rod.director_collection.copy()

    def set_state(self, state) -> None:
        """Place the rod in ``state`` (positions, directors), at rest."""
        self.rod.position_collection[...] = state[0]
        self.rod.director_collection[...] = state[1]
        self.rod.velocity_collection[...] = 0.0
        self.rod.omega_collection[...] = 0.0

    def advance(self, tension: np.ndarray, seconds: float) -> None:
        self.tension[:] = tension
        for _ in range(int(round(seconds / self.dt))):
            self.time = self.stepper.step(self.sim, self.time, self.dt)

    def run(self, u: np.ndarray) -> np.ndarray:
        """Node positions ``(T + 1, n + 1, 3)`` at :data:`RECORD_HZ` while commands ``u`` ``(T_c, 4)`` are held one
        control step (1/30 s) each, ``T = 4 T_c``: sample k at t = k / RECORD_HZ, before the step it starts (the
        last one at the end of the last control step)."""
        per = int(round(CONTROL_DT * RECORD_HZ))
        out = np.empty((len(u) * per + 1, self.n + 1, 3))
        force = self.params.max_tendon_force
        for k in range(len(out)):
            out[k] = self.rod.position_collection.T
            if k == len(out) - 1:
                break
            self.tension[:] = force * u[k // per]
            for _ in range(self.substeps):
                self.time = self.stepper.step(self.sim, self.time, self.dt)
            if not np.all(np.isfinite(self.rod.position_collection)):
                raise FloatingPointError(
                    f"the rod became unstable at t = {k / RECORD_HZ:.3f} s ({self.n} elements, dt = {self.dt:.3g} s)"
                )
        return out


_REST: dict = {}


def rest_state(u0, n_elements: int = N_ELEMENTS, params: RodParameters = PARAMETERS):
    """The rod at rest under gravity holding commands ``u0`` (settled heavily damped; cached per case)."""
    key = (tuple(np.round(u0, 12)), n_elements, params)
    if key not in _REST:
        rod = Rod(n_elements, params, damping=SETTLE_DAMPING)
        rod.advance(params.max_tendon_force * np.asarray(u0, np.float64), SETTLE_S)
        _REST[key] = rod.state()
    return _REST[key]


def simulate(u, *, n_elements: int = N_ELEMENTS, params: RodParameters = PARAMETERS) -> np.ndarray:
    """Node positions ``(T + 1, n_elements + 1, 3)`` (metres, world frame) at :data:`RECORD_HZ` of the rod driven
    by commands ``u`` ``(T_c, 4)`` in [0, 1] at 30 Hz, from its rest under ``u[0]``; ``T = 4 T_c`` (sample k
    at k / RECORD_HZ; the last at the end of the last command)."""
    u = check_commands(u)
    rod = Rod(n_elements, params)
    rod.set_state(rest_state(u[0], n_elements, params))
    return rod.run(u)


def at_arc_length(nodes: np.ndarray, s_nodes: np.ndarray, s) -> np.ndarray:
    """Points ``(..., M, 3)`` at arc lengths ``s`` (M,) of the undeformed backbone, interpolated linearly
    between the nodes ``(..., n + 1, 3)`` at ``s_nodes``."""
    s = np.asarray(s, np.float64)
    i = np.clip(np.searchsorted(s_nodes, s, side="right") - 1, 0, len(s_nodes) - 2)
    w = ((s - s_nodes[i]) / (s_nodes[i + 1] - s_nodes[i]))[:, None]
    return nodes[..., i, :] * (1.0 - w) + nodes[..., i + 1, :] * w


def markers(
    nodes: np.ndarray, *, marker_s=MARKER_S, noise: float = MARKER_NOISE_M, rng=None, length: float | None = None
) -> np.ndarray:
    """Marker positions ``(T, M, 3)`` read from node positions ``(T, n + 1, 3)``, with Gaussian noise of ``noise``
    metres per axis drawn from ``rng`` (none when ``noise`` is 0)."""
    n = nodes.shape[-2] - 1
    s_nodes = np.linspace(0.0, length or PARAMETERS.length, n + 1)
    out = at_arc_length(nodes, s_nodes, marker_s)
    if noise > 0:
        rng = rng if rng is not None else np.random.default_rng(0)
        out = out + rng.normal(0.0, noise, out.shape)
    return out
