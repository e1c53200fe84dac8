"""Fit the trunk to recordings with MuJoCo's system identification (``mujoco.sysid``).

What is fitted: named parameters of :class:`jgrounding.sim.mjcf.TrunkParams` (by default the hinge stiffness and
damping at root and tip, the tendon force at u = 1, the slide stiffness, the segment density and the command
delay), each inside its box bounds. How: sysid's box-constrained Gauss-Newton (``mujoco.minimize.least_squares``)
with finite-difference Jacobians, each evaluation one batched ``mujoco.rollout`` of every recording under every
perturbed parameter vector. The residual is what a motion-capture system sees: the recorded marker positions minus
the simulated ones, in metres, at the recorded times. The marker at arc length ``s`` is the point of our chain at
that arc length along the undeformed backbone (a site on the segment that holds it, read by a ``framepos``
sensor), so the objective is the backbone's squared error summed over markers and time. Parameters with a positive
lower bound move in log space (equal steps are equal relative changes); an optimizer's trial step where the chain
diverges gets a large residual, so it is rejected; and the fit restarts from the point it reached while a round
still gains more than 10 % (Gauss-Newton's damping grows along the nearly flat direction where stiffness, force,
damping and mass scale together).

The command delay is MuJoCo's actuator delay (each motor applies the command of ``delay`` seconds ago; the
history is at rest before time 0), so a fitted trunk file simulates its delay by itself.

Every candidate model is built from its :class:`TrunkParams` by :func:`jgrounding.sim.mjcf.build_xml` (full
precision), the same builder that writes the fitted file: what was fitted is what is written.
"""

from __future__ import annotations

import dataclasses
import math
import os

import mujoco
import numpy as np

from jgrounding.config import NUM_TENDONS
from jgrounding.sim import mjcf as tm
from jgrounding.sim.calibration_settings import (  # noqa: F401  (re-exported: the calibration's public surface)
    DEFAULT_BOUNDS,
    FIT_PARAMETERS,
    CalibrationError,
    Settings,
    load_settings,
    parse_bound,
)

MAX_ABS_POSITION = 3.0  # m: a simulated marker farther than this from the origin has blown up
MARKER_PREFIX = "marker_"


class UnstableError(CalibrationError):
    """The trunk diverges at some parameter values (MuJoCo reset it, or a marker left the scene)."""


UNSTABLE_RESIDUAL = 1.0  # m per residual entry for a trial step where the trunk diverges: the optimizer rejects it


def check_recordings(recordings, params: tm.TrunkParams) -> None:
    """Refuse what cannot be fitted: no recordings, no markers, a marker off the trunk, another number of tendons."""
    if not recordings:
        raise CalibrationError("no recordings to calibrate on")
    first = recordings[0]
    for r in recordings:
        if r.markers.ndim != 3 or r.markers.shape[1] == 0:
            raise CalibrationError(f"recording {r.name!r} has no motion-capture markers: calibration needs them")
        if r.u.shape[1] != NUM_TENDONS:
            raise CalibrationError(
                f"recording {r.name!r} has {r.u.shape[1]} tendon columns; this trunk has {NUM_TENDONS}"
            )
        if r.marker_names != first.marker_names:
            raise CalibrationError(f"recording {r.name!r} has other markers than {first.name!r}")
        if len(r.t) < 3 or not np.all(np.diff(r.t) > 0) or not np.all(np.isfinite(r.markers)):
            raise CalibrationError(f"recording {r.name!r}: times must increase and markers be finite")
    s = np.asarray(first.marker_s, float)
    if s.min() < 0 or s.max() > params.length + 1e-3:
        raise CalibrationError(
            f"marker arc lengths {s.round(4).tolist()} m must lie on the trunk, in [0, {params.length}] m"
        )


def split(recordings, fraction: float, seed: int) -> tuple[list, list]:
    """Fit and validation sets: a seeded permutation of the recordings (by name), ``fraction`` held out."""
    order = sorted(range(len(recordings)), key=lambda i: recordings[i].name)
    order = [order[i] for i in np.random.default_rng(seed).permutation(len(order))]
    n_val = min(len(order) - 1, max(1, round(fraction * len(order)))) if fraction > 0 and len(order) > 1 else 0
    val = sorted(order[:n_val])
    fit = sorted(order[n_val:])
    return [recordings[i] for i in fit], [recordings[i] for i in val]


def marker_spec(params: tm.TrunkParams, marker_names, marker_s, *, max_delay: float) -> mujoco.MjSpec:
    """The trunk's MjSpec without user contact, whose only sensors are the markers (``framepos`` of a site at each
    marker's arc length on the undeformed backbone), with a command-delay history long enough for ``max_delay``."""
    spec = mujoco.MjSpec.from_string(tm.build_xml(params=params.replace(delay=0.0), contact=False, exact=True))
    for sensor in list(spec.sensors):
        spec.delete(sensor)
    lengths = tm.segment_lengths(params.segments, params)
    starts = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    for name, s in zip(marker_names, marker_s):
        i = int(np.clip(np.searchsorted(starts, s, side="right") - 1, 0, params.segments - 1))
        site = spec.body(f"seg{i}").add_site(name=f"{MARKER_PREFIX}{name}", pos=[0, 0, -(float(s) - starts[i])])
        site.size = [0.004, 0, 0]
        spec.add_sensor(
            name=f"{MARKER_PREFIX}{name}",
            type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
            objtype=mujoco.mjtObj.mjOBJ_SITE,
            objname=site.name,
        )
    for act in spec.actuators:
        act.nsample = math.ceil(max_delay / tm.TIMESTEP) + 2 if max_delay > 0 else 0
        act.interp = 1 if max_delay > 0 else 0
        act.delay = params.delay
    return spec


def n_threads() -> int:
    return max(1, min(os.cpu_count() or 1, 16))


@dataclasses.dataclass
class Problem:
    """A calibration set up for ``mujoco.sysid``: the parameters, one ModelSequences per group of recordings on one
    clock (a batched rollout needs equal lengths), and the residual function ``optimize`` and ``default_report``
    call."""

    base: tm.TrunkParams
    settings: Settings
    params: object  # sysid.ParameterDict
    sequences: list  # sysid.ModelSequences, one per clock
    recordings: list
    sizes: dict = dataclasses.field(default_factory=dict)  # residual length per sequence (penalty of a trial step)
    unstable_steps: int = 0  # trial steps rejected because the trunk diverged there

    @property
    def logs(self) -> np.ndarray:
        """Which parameters the optimizer moves in log space: those with a positive lower bound (all but the delay,
        by default). Stiffness, damping, force and density act as ratios and span decades: a step of the same size
        means the same relative change for each."""
        return np.array([self.settings.bound(n)[0] > 0 for n in self.settings.parameters])

    def natural(self, x) -> np.ndarray:
        """Optimizer vector ``x`` -> the parameters' values in their units."""
        x = np.asarray(x, float).reshape(-1)
        return np.where(self.logs, np.exp(x), x)

    def to_x(self, trunk: tm.TrunkParams) -> np.ndarray:
        """The optimizer vector of ``trunk``'s fitted parameters."""
        v = np.array([getattr(trunk, n) for n in self.settings.parameters], float)
        return np.where(self.logs, np.log(np.maximum(v, 1e-300)), v)

    def trunk(self, x) -> tm.TrunkParams:
        """The trunk at optimizer vector ``x`` (in ``settings.parameters`` order)."""
        return self.base.replace(**{n: float(v) for n, v in zip(self.settings.parameters, self.natural(x))})

    def build_model(self, pdict, spec=None) -> mujoco.MjModel:
        del spec  # every candidate is rebuilt from its description (the passed spec is the start's)
        values = [float(pdict[k].value[0]) for k in pdict.keys()]
        first = self.recordings[0]
        return marker_spec(self.trunk(values), first.marker_names, first.marker_s, max_delay=self.max_delay).compile()

    @property
    def max_delay(self) -> float:
        return self.settings.bound("delay")[1] if "delay" in self.settings.parameters else self.base.delay

    def residual(self, x, pdict, return_pred_all: bool = False, **_):
        """sysid's residual signature: ``(x (n,) or (n, k), params) -> (residuals, predicted, measured)``, one
        entry per group (residuals) or per recording (the TimeSeries, as ``default_report`` reads them)."""
        from mujoco import sysid

        residuals, preds, records = [], [], []
        single = np.reshape(x, (len(self.settings.parameters), -1)).shape[1] == 1  # one point, not a Jacobian
        for seq in self.sequences:
            try:
                res, pred, rec = sysid.model_residual(
                    x,
                    pdict,
                    lambda p: self.build_model(p),
                    seq.measured_rollout,
                    modify_residual=self._marker_residual,
                    n_threads=n_threads(),
                    resample_true=False,  # controls are already on the physics clock (control_series)
                    return_pred_all=return_pred_all,
                )
            except ValueError as e:  # UnstableError, or MuJoCo reset a diverging simulation (its clock went back)
                if not isinstance(e, UnstableError) and "strictly increasing" not in str(e):
                    raise
                size = self.sizes.get(id(seq))
                if single and size is not None and not return_pred_all:
                    # An optimizer's trial step into a diverging region: a large residual makes it reject the step
                    residuals.append(np.full((size, 1) if np.ndim(x) == 2 else size, UNSTABLE_RESIDUAL))
                    self.unstable_steps += 1
                    continue
                x2 = np.asarray(x, float).reshape(len(self.settings.parameters), -1)
                x2 = np.where(self.logs[:, None], np.exp(x2), x2)
                span = {n: f"{row.min():.4g}..{row.max():.4g}" for n, row in zip(self.settings.parameters, x2)}
                raise CalibrationError(
                    f"the trunk goes unstable at parameters in {span} (MuJoCo reset a diverging simulation); "
                    "narrow the bounds of the parameter that sits at an extreme"
                ) from None
            if single:
                self.sizes[id(seq)] = res.size
            if np.ndim(x) == 2:  # (N_each, k * chunks), columns k-major: -> (chunks * N_each, k) as the optimizer reads
                k, chunks = x.shape[1], len(seq.measured_rollout)
                res = res.reshape(-1, k, chunks).transpose(2, 0, 1).reshape(-1, k)
            residuals.append(res)
            preds += [[ts] for ts in pred]
            records += [[ts] for ts in rec]
        return residuals, preds, records

    def _marker_residual(self, pdict, predicted, measured, model, return_pred_all, state=None, **_):
        """Recorded minus simulated marker positions (m) at the recorded times inside the simulated span."""
        from mujoco import sysid

        del model, return_pred_all
        times = predicted.times
        if (
            not np.all(np.isfinite(predicted.data))
            or np.abs(predicted.data).max() > MAX_ABS_POSITION
            or (state is not None and not np.all(np.diff(state[:, 0]) > 0))  # MuJoCo reset a diverging step
        ):
            values = self.natural([float(pdict[k].value[0]) for k in pdict.keys()])
            raise UnstableError(f"the trunk goes unstable at {dict(zip(self.settings.parameters, values))}")
        window = sysid.signal_modifier.apply_time_window(measured, times[0], times[-1])
        pred = predicted.resample(window.times)
        # One mapping object for both (sysid compares them), one column per entry: marker_tip_x, ... (sysid's report
        # lays out one plot per mapping entry)
        mapping = {
            f"{name}_{axis}": (kind, idx[a : a + 1])
            for name, (kind, idx) in window.signal_mapping.items()
            for a, axis in enumerate("xyz")
        }
        window = sysid.TimeSeries(window.times, window.data, mapping)
        pred = sysid.TimeSeries(window.times, pred.data, mapping)
        return (window.data - pred.data).ravel(), pred, window


def control_series(r):
    """The recording's commands on the physics clock (k * TIMESTEP, linearly interpolated), so each physics step
    applies the command recorded at its start. (sysid's own resampling spreads n + 1 points over the span, which
    drifts off the clock by a rounding of the span.)"""
    from mujoco import sysid

    t = np.asarray(r.t, float)
    grid = np.arange(int(np.floor(t[-1] / tm.TIMESTEP + 1e-6)) + 1) * tm.TIMESTEP
    u = np.stack([np.interp(grid, t, r.u[:, j]) for j in range(r.u.shape[1])], axis=1)
    return sysid.TimeSeries(grid, u)


def _group_key(r) -> tuple:
    return (len(r.t), round(float(r.t[-1]), 6))


def problem(recordings, base: tm.TrunkParams, settings: Settings, start: tm.TrunkParams | None = None) -> Problem:
    """The sysid problem of fitting ``settings.parameters`` of ``base`` to ``recordings``, starting at ``start``
    (default ``base``) moved off its bounds."""
    from mujoco import sysid

    check_recordings(recordings, base)
    start = start or base
    pdict = sysid.ParameterDict()
    for name in settings.parameters:
        lo, hi = settings.bound(name)
        value = float(np.clip(getattr(start, name), lo, hi))
        value = float(np.clip(value, lo + 0.02 * (hi - lo), hi - 0.02 * (hi - lo)))  # off the bounds
        if name == "delay" and value < 1.5 * tm.TIMESTEP < hi:
            # MuJoCo applies a delay shorter than one step as a whole step: flat below dt, so start above it
            value = 1.5 * tm.TIMESTEP
        if lo > 0:  # log space (Problem.logs)
            pdict.add(sysid.Parameter(f"log_{name}", np.log(value), np.log(lo), np.log(hi)))
        else:
            pdict.add(sysid.Parameter(name, nominal=value, min_value=lo, max_value=hi))
    prob = Problem(base=base, settings=settings, params=pdict, sequences=[], recordings=list(recordings))
    groups: dict[tuple, list] = {}
    for r in recordings:
        groups.setdefault(_group_key(r), []).append(r)
    first = recordings[0]
    spec = marker_spec(start, first.marker_names, first.marker_s, max_delay=prob.max_delay)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    state0 = sysid.create_initial_state(model, data.qpos.copy(), data.qvel.copy(), data.act.copy())
    for key, rs in groups.items():
        prob.sequences.append(
            sysid.ModelSequences(
                f"trunk_{key[0]}",
                spec,
                [r.name for r in rs],
                [state0] * len(rs),
                [control_series(r) for r in rs],
                [
                    sysid.TimeSeries.from_names(np.asarray(r.t, float), r.markers.reshape(len(r.t), -1), model)
                    for r in rs
                ],
            )
        )
    prob.recordings = [r for rs in groups.values() for r in rs]  # the order of the residual's entries
    prob.residual(pdict.as_vector(), pdict)  # the start must simulate (an unstable start is an error here)
    return prob


def paths(prob: Problem, trunk: tm.TrunkParams) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """``(name, times (T,), recorded (T, M, 3), simulated (T, M, 3))`` of every recording of ``prob`` on ``trunk``."""
    x = prob.to_x(trunk)
    _, preds, records = prob.residual(x, prob.params, return_pred_all=True)
    m = len(prob.recordings[0].marker_names)
    return [
        (r.name, rec[0].times, rec[0].data.reshape(-1, m, 3), pred[0].data.reshape(-1, m, 3))
        for r, pred, rec in zip(prob.recordings, preds, records)
    ]


def rms(prob: Problem, trunk: tm.TrunkParams) -> tuple[float, float]:
    """Backbone RMS (over markers, time and recordings) and tip RMS (the marker farthest along), in metres."""
    tip = int(np.argmax(prob.recordings[0].marker_s))
    d = [np.linalg.norm(rec - sim, axis=-1) for _, _, rec, sim in paths(prob, trunk)]
    all_d = np.concatenate([x.ravel() for x in d])
    tip_d = np.concatenate([x[:, tip] for x in d])
    return float(np.sqrt(np.mean(all_d**2))), float(np.sqrt(np.mean(tip_d**2)))


@dataclasses.dataclass
class Result:
    """A finished calibration: the start and fitted trunks, per-parameter uncertainty (95 % half-width, inf where
    the data do not determine it), whether each sits at a bound, and RMS before / after on both sets (metres)."""

    start: tm.TrunkParams
    fitted: tm.TrunkParams
    settings: Settings
    fit_names: list[str]
    validation_names: list[str]
    interval: dict[str, float]
    at_bound: dict[str, str]  # "", "low" or "high"
    rms: dict[str, dict[str, tuple[float, float]]]  # set -> "before"/"after" -> (backbone, tip)
    iterations: int
    status: str
    objective: list[float]
    seconds: float
    problem: Problem
    initial_params: object
    opt_params: object
    opt_result: object


class _Tee:
    """Prints the optimizer's per-iteration lines and keeps them (its final status is read from them)."""

    def __init__(self, log):
        self.log, self.text = log, []

    def write(self, s: str) -> int:
        self.text.append(s)
        if s.strip():
            self.log(s.rstrip("\n"))
        return len(s)

    def flush(self) -> None:
        pass


def calibrate(recordings, base: tm.TrunkParams | None = None, settings: Settings | None = None, *, log=print):
    """Fit ``settings.parameters`` of ``base`` (default: the shipped trunk) to ``recordings`` with
    ``mujoco.sysid``; prints one line per iteration through ``log``. Returns a :class:`Result`; raises
    :class:`CalibrationError` on bad input, an unstable model or no convergence within ``settings.max_iters``."""
    import time

    from mujoco import sysid

    base, settings = base or tm.TrunkParams(), settings or Settings()
    check_recordings(recordings, base)
    fit, val = split(recordings, settings.validation, settings.seed)
    log(f"calibrating {len(settings.parameters)} parameters on {len(fit)} recordings ({len(val)} held out)")
    prob = problem(fit, base, settings)
    initial = prob.params.copy()
    x0 = initial.as_vector()
    tee = _Tee(log)
    t0 = time.perf_counter()
    objective, status = [], "converged"
    for round_ in range(1 + settings.restarts):  # noqa: B007  (round_ is read after the loop)
        # Gauss-Newton's damping grows where the problem is ill-conditioned (stiffness, force, damping and mass nearly
        # trade off); a fresh start from the point reached resets it. Restart while a round still gains > 10 %.
        opt_params, opt_result = sysid.optimize(
            initial_params=prob.params,
            residual_fn=prob.residual,
            optimizer="mujoco",
            verbose=False,
            max_iters=settings.max_iters,
            x_scale="jac",
            output=tee,
        )
        trace = [float(v) for v in opt_result.extras.get("objective", [])]
        objective += trace
        text = "".join(tee.text)
        tee.text.clear()
        status = next((m for m in ("maximum iterations", "factorization failed") if m in text), "converged")
        if status != "converged" or not trace or trace[-1] > 0.9 * trace[0] or round_ == settings.restarts:
            break
        log(f"restart {round_ + 1} from the point reached (objective {trace[0]:.4g} -> {trace[-1]:.4g})")
        prob.params = opt_params
    seconds = time.perf_counter() - t0
    if prob.unstable_steps:
        log(f"{prob.unstable_steps} trial step(s) made the trunk diverge and were rejected")
    x = opt_params.as_vector()
    fitted = prob.trunk(x)
    if status != "converged":
        best = ", ".join(f"{n} = {getattr(fitted, n):.6g}" for n in settings.parameters)
        raise CalibrationError(
            f"no convergence within {settings.max_iters} iterations ({status}); nothing written. Raise --max-iters, "
            f"narrow the bounds, or start from the best point so far (a --config TOML with: {best})"
        )
    lo, hi = opt_params.get_bounds()
    width = hi - lo
    at = ["low" if v - a <= 1e-3 * w else "high" if b - v <= 1e-3 * w else "" for v, a, b, w in zip(x, lo, hi, width)]
    residuals, _, _ = prob.residual(x, opt_params)
    _, intervals = sysid.calculate_intervals(residuals, opt_result.jac)
    # A log-space interval h is the relative half-width: about value * h in the parameter's units.
    intervals = np.where(prob.logs, prob.natural(x) * np.ravel(intervals), np.ravel(intervals))
    start = prob.trunk(x0)
    rms_table = {"fit": {"before": rms(prob, start), "after": rms(prob, fitted)}}
    if val:
        vprob = problem(val, base, settings)
        rms_table["validation"] = {"before": rms(vprob, start), "after": rms(vprob, fitted)}
    return Result(
        start=start,
        fitted=fitted,
        settings=settings,
        fit_names=[r.name for r in fit],
        validation_names=[r.name for r in val],
        interval={n: float(v) for n, v in zip(settings.parameters, np.ravel(intervals))},
        at_bound=dict(zip(settings.parameters, at)),
        rms=rms_table,
        iterations=len(objective) - 1 - round_,
        status=status,
        objective=objective,
        seconds=seconds,
        problem=prob,
        initial_params=initial,
        opt_params=opt_params,
        opt_result=opt_result,
    )
