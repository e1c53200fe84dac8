"""One-step generators: MeanFlow and a shortcut model, as pure losses and one jump sampler.

Convention of the paper (as :mod:`jgrounding.generators.flows`): lambda = 0 is noise, lambda = 1 is data,
``z_t = (1 - t) eps + t c`` and the instantaneous velocity is ``v = c - eps``. Both networks take a
second time beside ``t`` (:class:`jgrounding.generators.networks.TwoTimeMLP`) and sampling jumps
``x <- x + (1 / S) net(x, t_k, second_k)`` for ``t_k = k / S``: S = 1 is one network call.

- **MeanFlow** (Geng et al., 2025, "Mean Flows for One-step Generative Modeling"): ``u(z_t, t, s)`` is the
  *average* velocity over [t, s], ``(s - t) u = int_t^s v``; differentiating in t gives the MeanFlow
  identity ``u = v + (s - t) du/dt`` with ``du/dt = v . d_z u + d_t u`` (a JVP, ``jax.jvp``), which is the
  regression target (stop-gradient). The second input is the interval length ``s - t``.
- **Shortcut model** (Frans et al., 2025, "One Step Diffusion via Shortcut Models"): ``s(z_t, t, d)``
  is the velocity for a jump of size d; d = 0 is trained by flow matching, and two jumps of d must
  equal one of 2d (self-consistency). One training run serves every S in 1..64 (d = 1 / S) and, with
  d = 0, any larger S (Euler on the instantaneous field).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding.config import SampleConfig, TrainConfig
from jgrounding.generators.flows import INPAINT, ConditionalFlow, sample_flow_time
from jgrounding.generators.networks import TwoTimeMLP

MEANFLOW_JUMP_SHARE = 0.25  # share of examples with s != t (the paper's best; the rest is flow matching)
MEANFLOW_ADAPTIVE_P = 0.5  # adaptive loss weight 1 / (||err||^2 + c)^p; 0.5 ~ Pseudo-Huber (paper: 0.5 or 1)
MEANFLOW_ADAPTIVE_C = 1e-3
SHORTCUT_BOOTSTRAP_SHARE = 0.25  # share of each batch trained on self-consistency (the paper's k = 1/4)
SHORTCUT_FINEST = 64  # 2d spans [1/64, 1]; shorter halves query d = 0 (the flow-matching field)


def meanflow_loss(average_velocity, c, key, *, time_sampler: str = "uniform"):
    """MeanFlow loss: || u(z_t, t, s) - sg(v + (s - t) du/dt) ||^2, adaptively weighted.

    Args:
      average_velocity: ``u(x (B, D), t (B,), s (B,)) -> (B, D)``, the average velocity over [t, s].
      c: data ``(B, D)`` (lambda = 1).
      key: draws eps, the two times and which examples jump.
      time_sampler: distribution of both times (:func:`jgrounding.generators.flows.sample_flow_time`).
    Returns: the scalar loss.
    """
    k_eps, k_t, k_s, k_jump = jax.random.split(key, 4)
    b = c.shape[0]
    eps = jax.random.normal(k_eps, c.shape)
    a, e = sample_flow_time(k_t, (b,), time_sampler), sample_flow_time(k_s, (b,), time_sampler)
    jump = jax.random.bernoulli(k_jump, MEANFLOW_JUMP_SHARE, (b,))
    t = jnp.where(jump, jnp.minimum(a, e), a)
    s = jnp.where(jump, jnp.maximum(a, e), a)
    z = (1.0 - t[:, None]) * eps + t[:, None] * c
    v = c - eps
    # du/dt along the path: tangents (dz, dt, ds) = (v, 1, 0).
    u, du_dt = jax.jvp(average_velocity, (z, t, s), (v, jnp.ones_like(t), jnp.zeros_like(s)))
    target = jax.lax.stop_gradient(v + (s - t)[:, None] * du_dt)
    err = jnp.sum((u - target) ** 2, axis=-1)
    weight = jax.lax.stop_gradient(1.0 / (err + MEANFLOW_ADAPTIVE_C) ** MEANFLOW_ADAPTIVE_P)
    return jnp.mean(weight * err) / c.shape[1]


def shortcut_loss(shortcut, c, key, *, time_sampler: str = "uniform"):
    """Shortcut-model loss: flow matching at d = 0 plus self-consistency ``s(z_t, t, 2d) = (s_t + s_{t+d}) / 2``.

    Args:
      shortcut: ``s(x (B, D), t (B,), d (B,)) -> (B, D)``, the velocity of a jump of size d.
      c: data ``(B, D)``; the last ``SHORTCUT_BOOTSTRAP_SHARE`` of the rows (at least one) are
        self-consistency examples, the others flow matching.
      key: draws eps, the times and the step sizes.
      time_sampler: flow-time distribution of the flow-matching rows.
    Returns: the scalar loss.
    """
    k_eps, k_t, k_level, k_grid = jax.random.split(key, 4)
    b = c.shape[0]
    boot = jnp.arange(b) >= b - max(1, int(round(b * SHORTCUT_BOOTSTRAP_SHARE)))  # (B,) static split
    eps = jax.random.normal(k_eps, c.shape)
    # Self-consistency rows: 2d = 2^-level, level ~ U[0, log2 FINEST]; t uniform on [0, 1 - 2d]. Flow-matching
    # rows: d = 0. (Every row goes through the network for the targets too: the condition is per row.)
    two_d = jnp.where(boot, 2.0 ** -jax.random.uniform(k_level, (b,), maxval=np.log2(SHORTCUT_FINEST)), 0.0)
    d = two_d / 2
    t = jnp.where(boot, jax.random.uniform(k_grid, (b,)) * (1.0 - two_d), sample_flow_time(k_t, (b,), time_sampler))
    z = (1.0 - t[:, None]) * eps + t[:, None] * c
    d_half = jnp.where(two_d <= 1.0 / SHORTCUT_FINEST, 0.0, d)  # the finest halves: the flow-matching field
    s1 = shortcut(z, t, d_half)
    s2 = shortcut(z + d[:, None] * s1, t + d, d_half)
    target = jnp.where(boot[:, None], jax.lax.stop_gradient(0.5 * (s1 + s2)), c - eps)
    return jnp.mean((shortcut(z, t, two_d) - target) ** 2)


def jump_sample(network, eps, times, seconds, embed_time=None, known=None, inpaint: str = "final"):
    """``x <- x + (t_{k+1} - t_k) net(x, t_k, second_k)`` from lambda = 0 (noise ``eps (B, D)``) to 1.

    ``times``: the ``S + 1`` static flow times ``(S + 1,)`` (numpy); ``seconds``: the second input of
    each jump ``(S,)``. With ``embed_time(t (S,), s (S,)) -> (S, F)`` (a model's share of its first
    layer) the network is called as ``net(x, f)``, the features computed once before the loop;
    otherwise as ``net(x, t (B,), s (B,))``. ``known``: ``(mask, c_known)`` fixes the masked
    coordinates as :func:`jgrounding.generators.flows.rf_sample` does (``inpaint`` "final" or "path").
    """
    if inpaint not in INPAINT:
        raise ValueError(f"unknown inpaint {inpaint!r}; valid: {', '.join(INPAINT)}")
    times = np.asarray(times, np.float32)
    steps = len(times) - 1
    dts, ends = jnp.asarray(np.diff(times)), jnp.asarray(times[1:])
    with jax.ensure_compile_time_eval():  # constant parameters (the public sampler): computed once, at trace time
        t0, s0 = jnp.asarray(times[:-1]), jnp.asarray(np.asarray(seconds, np.float32))
        feats = None if embed_time is None else jax.jit(embed_time)(t0, s0)  # one program, not op by op

    def step(k, x):
        if feats is None:
            v = network(x, jnp.full(x.shape[:1], t0[k]), jnp.full(x.shape[:1], s0[k]))
        else:
            v = network(x, feats[k])
        x = x + dts[k] * v
        if known is None or inpaint == "final":
            return x
        mask, c_known = known
        return jnp.where(mask, ends[k] * c_known + (1.0 - ends[k]) * eps, x)

    out = jax.lax.fori_loop(0, steps, step, eps)
    return out if known is None else jnp.where(known[0], known[1], out)


class _Jump(ConditionalFlow):
    """MeanFlow and the shortcut model on the flow base: a :class:`TwoTimeMLP` and the jump sampler.
    Subclasses give ``loss`` and ``second`` (the network's second input for each of S jumps)."""

    samplers = ("euler",)  # one jump per step: x + dt * net(x, t, second)
    network = TwoTimeMLP

    def integrate(self, net, eps, key, config: SampleConfig, embed_time, known=None):
        del key  # the jumps are deterministic given eps
        times = np.linspace(0.0, 1.0, config.steps + 1)
        return jump_sample(net, eps, times, self.second(config.steps), embed_time, known)


class MeanFlow(_Jump):
    """Average-velocity field u(z, t, s) with the MeanFlow identity as target (second input: s - t)."""

    def loss(self, model, batch, key, config: TrainConfig):
        key, net = self.conditioned(model, batch, key, config)
        return meanflow_loss(lambda x, t, s: net(x, t, s - t), batch["target"], key, time_sampler=config.time_sampler)

    @staticmethod
    def second(steps: int) -> np.ndarray:
        return np.full(steps, 1.0 / steps)


class Shortcut(_Jump):
    """Shortcut model s(z, t, d): d = 1 / S for S <= 64 jumps, d = 0 (the flow-matching field) beyond."""

    def loss(self, model, batch, key, config: TrainConfig):
        key, net = self.conditioned(model, batch, key, config)
        return shortcut_loss(net, batch["target"], key, time_sampler=config.time_sampler)

    @staticmethod
    def second(steps: int) -> np.ndarray:
        return np.full(steps, 1.0 / steps if steps <= SHORTCUT_FINEST else 0.0)
