"""MJX engines for :func:`jgrounding.sim.rollout`: ``jit(vmap(scan over physics steps))`` on MJX's JAX
implementation (engine ``"mjx"``) or on its Warp implementation (engine ``"mjx-warp"``: MuJoCo Warp's kernels,
called from the same JAX program through XLA's foreign-function interface).

Each control step holds the command for ``SUBSTEPS`` physics steps (one flat ``lax.scan`` over every physics
step); the backbone, tendon lengths and the normal force on the user are read at the end of each control
step.

Sensors are disabled in the MJX model: everything is read from the state directly. The user force is
the sum of the contact normal forces (every contact in the model involves the user: the segments do
not collide with each other), which is what the native engine's ``touch`` sensor over the user
measures (checked equal to float precision). Reading MJX's own touch sensor instead would fail on the
contact-free model (MJX 3.3.7 cannot evaluate a touch sensor when the model has no contact pairs) and
costs a ray cast per contact and step. The Warp
implementation keeps the model's sensors and reads them as the native engine does (MuJoCo Warp evaluates the
``touch`` sensor). One compiled function per (batch size, contact, implementation), cached; call :func:`enable_compilation_cache`
(done by the experiments and the test suite) to make compilation a one-time cost across processes.
"""

from __future__ import annotations

import copy
import functools
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

# MJX 3.3.7 has no public contact-force function; this one private helper is isolated in _user_force.
from mujoco.mjx._src import support as mjx_support  # contact_force_dim: pyramid -> normal force

from jgrounding import io
from jgrounding.sim import measures
from jgrounding.sim.native import from_sensordata, load_model


def enable_compilation_cache(path: str | Path | None = None) -> None:
    """Turn on JAX's persistent compilation cache (:func:`jgrounding.io.enable_compilation_cache`) in ``path``
    (default: the machine's, :func:`jgrounding.io.cache_dir`, unless a folder is already set; nothing when
    ``JGROUNDING_CACHE=off``), so a compiled MJX rollout survives the process: compiled once per machine, not once
    per process or clone."""
    io.enable_compilation_cache(path, min_compile_secs=1.0)


# On the CPU, XLA 0.10.2 runs the rollout program of 64 trunks or more into a deadlock: it waits at 0 % CPU forever
# inside Eigen's multi-threaded kernels (48 trunks run; XLA_FLAGS=--xla_cpu_multi_thread_eigen=false runs 64 too, but
# that flag is process-wide and would slow every other program, and it is not honoured per program). So on the CPU
# engine "mjx" runs batches as chunks of at most this many trunks; accelerators keep their large chunks.
CPU_MAX_CHUNK = 32
# MuJoCo Warp allocates contacts for all worlds of a batch and constraint rows per world up front. The trunk touches
# the user through CONTACT_SEGMENTS capsule pairs (at most 2 contacts each); each contact has 4 pyramid rows.
WARP_CONTACTS_PER_TRUNK = 16
WARP_ROWS_PER_TRUNK = 128


def warp_unavailable() -> str | None:
    """Why MJX's Warp implementation cannot run here, or None when it can. Warp runs on an NVIDIA GPU (CUDA) or,
    much slower, on the CPU through its LLVM backend; it needs the ``warp-lang`` package (``make install``, or
    ``pip install 'jgrounding[warp]'``)."""
    try:
        import warp

        warp.config.quiet = True  # no banner or per-kernel log lines on the terminal
    except ImportError as e:
        return f"warp-lang is not installed ({e}); install it with `pip install 'jgrounding[warp]'`"
    if jax.default_backend() == "cpu":
        return None
    try:
        jax.devices("cuda")
    except RuntimeError:
        kinds = ", ".join(sorted({d.device_kind for d in jax.devices()}))
        return f"Warp runs on NVIDIA GPUs (CUDA) or on the CPU, and JAX's devices here are {kinds}"
    return None


@functools.lru_cache(maxsize=8)
def _model(trunk: str | None, contact: bool, impl: str = "jax"):
    m = copy.copy(load_model(trunk, contact))  # a copy: the cached native model keeps its sensors
    if impl == "jax":
        m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR
    body_ids = np.array([m.body(f"seg{i}").id for i in range(measures.NUM_SEGMENTS)])
    mx = mjx.put_model(m, impl=impl)
    if impl == "warp":  # MuJoCo Warp warns on every step that ends at the solver's iteration limit (the model's
        # 4 iterations, as in native MuJoCo, which is silent about it); keep its warnings of buffer overflows.
        from mujoco.mjx.third_party.mujoco_warp import OverflowType

        warn = int(OverflowType.ALL & ~OverflowType.ITERATIONS)
        mx = mx.replace(opt=mx.opt.replace(_impl=mx.opt._impl.replace(warn_overflow=warn)))
    return m, mx, body_ids, m.site("tip").id


def _user_force(mx, d) -> jax.Array:
    """Total contact normal force (N) on the user; inactive contacts contribute 0."""
    dims = sorted(set(np.asarray(d._impl.contact.dim).tolist()))  # static: fixed by the model
    return sum((mjx_support.contact_force_dim(mx, d, dim)[0][:, 0].sum() for dim in dims), jnp.zeros(()))


def compiler_options() -> dict | None:
    """XLA options every MJX program is compiled with (the one place): on the CPU, XLA's newer fusion emitters off.

    From jaxlib 0.7.1 on, XLA:CPU generates fused loops with its "fusion emitters" by default, and for MuJoCo's
    step (kinematics, tendons, collision, the constraint solver: thousands of small fusions) that more than
    doubles the compile: ``jit(mjx.step)`` of the trunk compiled in 48 s with jax 0.7.0, 91 s with 0.7.1,
    106 s with 0.10.2 + MJX 3.17, and 43 s with 0.10.2 with this option (docs/versions.md; the same 2-core
    machine and load). jax 0.6.2 already defaults to it off. It does not cure everything: with contact pairs inside a
    scan the newest stack still compiles far slower (docs/versions.md), which is one reason engine "auto" runs native
    MuJoCo on the CPU. Other backends: no option.
    """
    if jax.default_backend() != "cpu":
        return None
    return {"xla_cpu_use_fusion_emitters": False}


@functools.lru_cache(maxsize=8)
def _compiled_warp(trunk: str | None, contact: bool, chunk: int):
    m, mx, _, _ = _model(trunk, contact, "warp")
    d0 = mjx.make_data(
        m, impl="warp", naconmax=WARP_CONTACTS_PER_TRUNK * chunk, njmax=WARP_ROWS_PER_TRUNK
    )  # naconmax counts every world of the batch

    def one(u):  # u: (T, 4); the model's sensors, read at the end of each control step
        def physics_step(d, ctrl):
            d = mjx.step(mx, d.replace(ctrl=ctrl))
            return d, d.sensordata

        _, out = jax.lax.scan(physics_step, d0, jnp.repeat(u, measures.SUBSTEPS, axis=0))
        return out[measures.SUBSTEPS - 1 :: measures.SUBSTEPS]

    return jax.jit(jax.vmap(one))


@functools.lru_cache(maxsize=8)
def _compiled(trunk: str | None, contact: bool):
    m, mx, body_ids, tip_id = _model(trunk, contact)

    def one(u):  # u: (T, 4)
        d0 = mjx.make_data(mx)

        def physics_step(d, ctrl):
            d = mjx.step(mx, d.replace(ctrl=ctrl))
            points = jnp.concatenate([d.xpos[body_ids], d.site_xpos[tip_id][None]], axis=0)
            return d, (points, d.ten_length, _user_force(mx, d))

        # One flat scan over the T x SUBSTEPS physics steps, each control held SUBSTEPS steps, read at the end of
        # each control step. Not a scan of control steps around a scan of substeps: for the shipped model XLA traced
        # and compiled that nesting in 13.6 + 37.0 s against 9.1 + 19.1 s flat (results/bench_trunk_compile_jax0.6.2.md),
        # at the price of a slower small batch on the CPU (2 trunks: 6,315 against 7,874 physics steps/s).
        _, out = jax.lax.scan(physics_step, d0, jnp.repeat(u, measures.SUBSTEPS, axis=0))
        return jax.tree.map(lambda x: x[measures.SUBSTEPS - 1 :: measures.SUBSTEPS], out)

    return jax.jit(jax.vmap(one), compiler_options=compiler_options())


def lower_rollout(batch: int, contact: bool = True):
    """The compiled-to-be MJX rollout program for a chunk of ``batch`` trunks, traced and lowered (``jax.stages.
    Lowered``): what :func:`rollout_mjx` compiles, for measuring its compile time (``.compile()``)."""
    return _compiled(None, contact).lower(jnp.zeros((batch, measures.NUM_STEPS, measures.NUM_CHANNELS), jnp.float32))


def _rest_tip(trunk: str | None, contact: bool):
    """A trunk of its own: its tip at rest (None for the shipped trunk, whose tip hangs straight down)."""
    if trunk is None:
        return None
    m = _model(trunk, contact)[0]
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return d.site_xpos[m.site("tip").id].copy()


def rollout_warp(
    u: np.ndarray, contact: bool = True, chunk: int | None = None, trunk: str | None = None
) -> measures.Rollout:
    """``(B, T, 4)`` validated commands -> :class:`measures.Rollout` via MJX's Warp implementation (float32), in
    padded chunks of ``chunk`` (default: the whole batch). Raises ``RuntimeError`` naming the reason where Warp
    cannot run (:func:`warp_unavailable`)."""
    why = warp_unavailable()
    if why:
        raise RuntimeError(f'engine "mjx-warp" cannot run here: {why}; valid engines here: auto, native, mjx')
    u = jnp.asarray(u, jnp.float32)
    chunk = chunk or u.shape[0]
    fn = _compiled_warp(trunk, contact, chunk)
    outs = []
    for i in range(0, u.shape[0], chunk):
        part = u[i : i + chunk]
        pad = chunk - part.shape[0]
        outs.append(np.asarray(jax.device_get(fn(jnp.pad(part, ((0, pad), (0, 0), (0, 0))))))[: chunk - pad])
    return from_sensordata(np.concatenate(outs).astype(np.float64), _rest_tip(trunk, contact))


def rollout_mjx(
    u: np.ndarray, contact: bool = True, chunk: int | None = None, trunk: str | None = None
) -> measures.Rollout:
    """``(B, T, 4)`` validated commands -> :class:`measures.Rollout` via MJX (float32).

    With ``chunk``, the batch runs as padded chunks of that size, so one compiled program serves every
    batch size (compilation, not execution, dominates on CPU).
    """
    if jax.default_backend() == "cpu":  # chunk=None is the whole batch, which may be above the CPU's bound
        chunk = min(chunk or u.shape[0], CPU_MAX_CHUNK)
    fn = _compiled(trunk, contact)
    u = jnp.asarray(u, jnp.float32)
    if chunk is None or u.shape[0] == chunk:
        outs = [jax.device_get(fn(u))]
    else:
        outs = []
        for i in range(0, u.shape[0], chunk):
            part = u[i : i + chunk]
            pad = chunk - part.shape[0]
            res = jax.device_get(fn(jnp.pad(part, ((0, pad), (0, 0), (0, 0)))))
            outs.append(tuple(x[: chunk - pad] for x in res))
    points, tendon, touch = (np.concatenate(x) for x in zip(*outs))
    return measures.finish_rollout(
        np.asarray(points, np.float64),
        np.asarray(tendon, np.float64),
        np.asarray(touch, np.float64),
        _rest_tip(trunk, contact),
    )
