"""Rectified flow (Sec. III-C, Eqs. rf_loss and rf_inference) and the DDPM baseline, as pure functions.

Convention of the paper: lambda = 0 is noise, lambda = 1 is data; c_lambda = (1 - lambda) eps + lambda c
and the velocity target is c - eps. ``velocity(x, t)`` below is any function of a flat batch.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jgrounding.config import DDPM_SAMPLERS, RF_SAMPLERS, ModelConfig, SampleConfig, TrainConfig
from jgrounding.generators.networks import VelocityMLP

DDPM_STEPS = 50  # diffusion steps; the ancestral sampler uses all of them (Table I: S = 50)
DATA_BOUND = 1.0  # targets are normalized to [-1, 1] (methods._encode); DDIM clips its x0 estimate to it


def _pi0_beta(key, shape):  # pi0: tau ~ Beta(1.5, 1) * 0.999 + 0.001 with tau = 1 noise, so lambda = 1 - tau
    return 1.0 - (jax.random.beta(key, 1.5, 1.0, shape) * 0.999 + 0.001)


# Flow-time distributions for training, ``(key, shape) -> lambda in (0, 1)`` (lambda = 0 noise, 1 data):
# uniform (the paper); logit-normal sigmoid(N(0, 1)) (Esser et al., SD3), weighting the middle of the path;
# Beta as in pi0, weighting the noisy end, where the velocity field is hardest to learn.
TIME_SAMPLERS = {
    "uniform": jax.random.uniform,
    "logit_normal": lambda key, shape: jax.nn.sigmoid(jax.random.normal(key, shape)),
    "beta": _pi0_beta,
}


def sample_flow_time(key, shape, time_sampler: str = "uniform") -> jax.Array:
    """Flow times ``shape`` (e.g. ``(B,)``) drawn from :data:`TIME_SAMPLERS` ``[time_sampler]``."""
    if time_sampler not in TIME_SAMPLERS:
        raise ValueError(f"unknown time sampler {time_sampler!r}; valid: {', '.join(TIME_SAMPLERS)}")
    return TIME_SAMPLERS[time_sampler](key, shape)


def rf_loss(velocity, c, key, *, time_sampler: str = "uniform", noise=None):
    """Eq. (rf_loss): E || v(c_lambda, lambda) - (c - eps) ||^2 for a batch ``c`` ``(B, D)``.

    Args:
      velocity: ``v(x (B, D), lambda (B,)) -> (B, D)``.
      c: data ``(B, D)`` (lambda = 1).
      key: draws eps (unless ``noise`` is given) and lambda.
      time_sampler: one of :data:`TIME_SAMPLERS` (:func:`sample_flow_time`).
      noise: coupled noise ``(B, D)`` (reflow: the eps each ``c`` was generated from); default a fresh draw.
    Returns: the scalar loss.
    """
    k_eps, k_lam = jax.random.split(key)
    eps = jax.random.normal(k_eps, c.shape) if noise is None else noise
    lam = sample_flow_time(k_lam, c.shape[:1], time_sampler)
    c_lam = (1.0 - lam[:, None]) * eps + lam[:, None] * c
    return jnp.mean((velocity(c_lam, lam) - (c - eps)) ** 2)


_RF_OFFSETS = {"euler": (0.0,), "midpoint": (0.0, 0.5), "rk4": (0.0, 0.5, 1.0)}  # evaluation times per step / dt


def _time_features(grid: np.ndarray, embed_time):
    """The network's time input at every evaluation of a sampler, computed once before its loop.

    ``grid``: the static evaluation times ``(steps, n)``. Without ``embed_time`` the velocity gets the
    time itself; with it, ``embed_time(t (steps * n,)) -> (steps * n, F)`` (a model's time embedding
    and its share of the first layer) is evaluated in one batch instead of once per network call.
    """
    if embed_time is None:
        return jnp.asarray(grid, jnp.float32), lambda x, f: jnp.full(x.shape[:1], f)
    with jax.ensure_compile_time_eval():  # constant parameters (the public sampler): computed once, at trace time
        feats = jax.jit(embed_time)(jnp.asarray(grid.reshape(-1), jnp.float32))  # one program, not op by op
    return feats.reshape(grid.shape + feats.shape[-1:]), lambda x, f: f


INPAINT = ("final", "path")


def guided(model, ctx, w: float):
    """``net(x, time_ctx)`` of a model with a precomputed condition context ``ctx (B, H)``; with classifier-free
    guidance ``w`` > 0: net_c + w (net_c - net_null), the conditional and null rows through the network as one
    batch (shared by the flows and the few-step generators)."""
    if not w:
        return lambda x, time_ctx: model.velocity(x, time_ctx, ctx)
    b = ctx.shape[0]
    both = jnp.concatenate([ctx, model.null_context(b)])

    def net(x, time_ctx):
        v = model.velocity(jnp.concatenate([x, x]), time_ctx, both)
        return v[:b] + w * (v[:b] - v[b:])

    return net


def rf_sample(
    velocity,
    eps,
    steps: int = SampleConfig.steps,
    sampler: str = RF_SAMPLERS[0],
    embed_time=None,
    known=None,
    inpaint: str = "final",
):
    """Eq. (rf_inference): integrate dc/dlambda = v from lambda = 0 (noise ``eps``) to 1 in ``steps``.

    ``velocity(x, t)`` with ``t`` of shape ``(B,)``; or, with ``embed_time``, ``velocity(x, f)`` with
    ``f = embed_time(t)`` precomputed for every step (see :func:`_time_features`).

    ``known``: ``(mask (D,) or (B, D) bool, c_known (B, D))`` fixes the masked coordinates of the data to
    ``c_known`` (start-conditioned sampling: the first Catmull-Rom control is the robot's current command).
    ``inpaint="final"`` (default) integrates the flow as learned and fixes them at the end: the other
    controls come from the model's own distribution. ``inpaint="path"`` sets them after every step (at flow
    time lambda) to the straight path ``lambda c_known + (1 - lambda) eps`` of their noise, so the other
    coordinates are generated *given* them; that needs a model that saw such starts in training. Library v3
    starts every demonstration at rest; on it, from a mid-motion command, "path" put 0.51 of the samples
    within r of a demonstration after the first key moment, "final" 0.98, and samples from rest 0.99
    (Prec@r of the benchmark, steps 50..149; ``python -m experiments.bench serve``, docs/serving.md).
    """
    if sampler not in RF_SAMPLERS:
        raise ValueError(f"unknown sampler {sampler!r}; valid: {', '.join(RF_SAMPLERS)}")
    if inpaint not in INPAINT:
        raise ValueError(f"unknown inpaint {inpaint!r}; valid: {', '.join(INPAINT)}")
    dt = 1.0 / steps
    grid = (np.arange(steps)[:, None] + np.asarray(_RF_OFFSETS[sampler])[None]) * dt
    feats, as_input = _time_features(grid, embed_time)

    def step(k, x):
        f = feats[k]
        v = lambda y, i: velocity(y, as_input(y, f[i]))
        if sampler == "euler":
            return x + dt * v(x, 0)
        if sampler == "midpoint":
            return x + dt * v(x + 0.5 * dt * v(x, 0), 1)
        k1 = v(x, 0)
        k2 = v(x + 0.5 * dt * k1, 1)
        k3 = v(x + 0.5 * dt * k2, 1)
        k4 = v(x + dt * k3, 2)
        return x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

    if known is None:
        return jax.lax.fori_loop(0, steps, step, eps)
    mask, c_known = known
    if inpaint == "final":
        return jnp.where(mask, c_known, jax.lax.fori_loop(0, steps, step, eps))

    def inpainted(k, x):
        lam = (k + 1) * dt
        return jnp.where(mask, lam * c_known + (1.0 - lam) * eps, step(k, x))

    return jax.lax.fori_loop(0, steps, inpainted, eps)


def ddpm_schedule(steps: int = DDPM_STEPS):
    """Cosine noise schedule (Nichol & Dhariwal) -> (betas, alphas, alpha_bars), each ``(steps,)``."""
    s = 0.008
    t = jnp.arange(steps + 1) / steps
    f = jnp.cos((t + s) / (1 + s) * jnp.pi / 2) ** 2
    alpha_bar = f / f[0]
    betas = jnp.clip(1.0 - alpha_bar[1:] / alpha_bar[:-1], 1e-5, 0.999)
    alphas = 1.0 - betas
    return betas, alphas, jnp.cumprod(alphas)


def ddpm_loss(noise_pred, c, key, steps: int = DDPM_STEPS):
    """Epsilon-prediction loss; ``noise_pred(x_t, t)`` gets t = step / steps in [0, 1)."""
    _, _, abar = ddpm_schedule(steps)
    k_eps, k_t = jax.random.split(key)
    eps = jax.random.normal(k_eps, c.shape)
    i = jax.random.randint(k_t, c.shape[:1], 0, steps)
    a = abar[i][:, None]
    x_t = jnp.sqrt(a) * c + jnp.sqrt(1 - a) * eps
    return jnp.mean((noise_pred(x_t, i / steps) - eps) ** 2)


def ddpm_sample(
    noise_pred, x_T, key, steps: int = DDPM_STEPS, sampler: str = "ancestral", sample_steps=None, embed_time=None
):
    """Reverse diffusion from ``x_T``: ``ancestral`` (all ``steps``) or ``ddim`` (``sample_steps``, eta 0).

    ``noise_pred(x, t)`` with ``t = step / steps`` of shape ``(B,)``, or ``noise_pred(x, embed_time(t))``.
    """
    betas, alphas, abar = ddpm_schedule(steps)
    if sampler == "ancestral":
        feats, as_input = _time_features((np.arange(steps)[::-1] / steps)[:, None], embed_time)

        def body(k, carry):
            x, key = carry
            i = steps - 1 - k
            key, sub = jax.random.split(key)
            eps = noise_pred(x, as_input(x, feats[k, 0]))
            mean = (x - betas[i] / jnp.sqrt(1 - abar[i]) * eps) / jnp.sqrt(alphas[i])
            var = betas[i] * (1 - jnp.where(i > 0, abar[i - 1], 1.0)) / (1 - abar[i])
            noise = jnp.where(i > 0, 1.0, 0.0) * jax.random.normal(sub, x.shape)
            return mean + jnp.sqrt(var) * noise, key

        return jax.lax.fori_loop(0, steps, body, (x_T, key))[0]
    if sampler != "ddim":
        raise ValueError(f"unknown DDPM sampler {sampler!r}; valid: {', '.join(DDPM_SAMPLERS)}")
    n = sample_steps or steps
    idx_np = np.round(np.linspace(steps - 1, 0, n)).astype(np.int32)
    idx = jnp.asarray(idx_np)
    feats, as_input = _time_features((idx_np / steps)[:, None], embed_time)

    def body(k, x):
        i = idx[k]
        prev = jnp.where(k + 1 < n, abar[idx[jnp.minimum(k + 1, n - 1)]], 1.0)
        eps = noise_pred(x, as_input(x, feats[k, 0]))
        # The predicted clean sample is clipped to the data range, and the noise made consistent with it:
        # at the first, noisiest step abar ~ 1e-5, and dividing by its root amplifies any error in eps.
        x0 = jnp.clip((x - jnp.sqrt(1 - abar[i]) * eps) / jnp.sqrt(abar[i]), -DATA_BOUND, DATA_BOUND)
        eps = (x - jnp.sqrt(abar[i]) * x0) / jnp.sqrt(1 - abar[i])
        return jnp.sqrt(prev) * x0 + jnp.sqrt(1 - prev) * eps

    return jax.lax.fori_loop(0, n, body, x_T)


def condition_keep(batch: dict, key, config: TrainConfig):
    """(key left, ``keep (B,)`` float mask or None): with condition dropout, each example's condition is kept
    with probability 1 - ``config.condition_dropout`` (else the null condition is trained, for guidance)."""
    if not config.condition_dropout:
        return key, None
    key, k_drop = jax.random.split(key)
    keep = jax.random.bernoulli(k_drop, 1.0 - config.condition_dropout, batch["cond"].shape[:1])
    return key, keep.astype(jnp.float32)


class ConditionalFlow:
    """The one base of the flow, diffusion and few-step generators: a conditional MLP over the flat target
    (``network``: :class:`VelocityMLP`, or the few-step :class:`~jgrounding.generators.networks.TwoTimeMLP`),
    condition dropout in training (the null condition), and in sampling a precomputable condition context,
    the noise temperature and classifier-free guidance. Subclasses give ``samplers``, ``loss`` and
    ``integrate`` (the sampler's loop from the initial noise)."""

    sequence = False
    iterative = True  # sampling steps S apply
    uses_context = True  # the condition enters as a first-layer context row (precomputable per tuple)
    inpaints = True
    null_condition = True
    flow_times = True
    reflows = False
    network = VelocityMLP

    def init(self, key, representation, num_controls: int, num_tendons: int, use_intensity: bool, config: ModelConfig):
        """``Generator.init``: the MLP over the flat target (N_u x L values)."""
        dim = num_tendons * representation.length(num_controls)
        return self.network(dim, use_intensity, config, rngs=nnx.Rngs(key))

    @staticmethod
    def conditioned(model, batch: dict, key, config: TrainConfig):
        """(key left for the loss, ``net(x, *times)``); with condition dropout the null condition is trained too."""
        key, keep = condition_keep(batch, key, config)
        return key, lambda x, *times: model(x, *times, batch["cond"], batch["intensity"], keep)

    def sample(self, model, cond, intensity, key, dim: int, config: SampleConfig, *, known=None, context=None):
        """Integrate from noise ``eps = noise_scale N(key) (B, D)``; guidance w: v = v_c + w (v_c - v_null), the
        conditional and null rows through the network as one batch. ``known``: coordinates fixed by inpainting.
        ``context``: the condition's first-layer rows ``(B, H)`` when already computed
        (``model.context(cond, intensity)``; ``cond`` is then unused). ``config.sampler`` None: the default."""
        if config.sampler is None:  # SampleConfig's "the generator's default" (Trained.resolve fills it in)
            config = dataclasses.replace(config, sampler=self.samplers[0])
        # What does not change across flow steps is computed once, before the sampler's loop: the
        # condition's share of the first layer, and the time embedding's share for every step.
        context = model.context(cond, intensity) if context is None else context
        eps = config.noise_scale * jax.random.normal(key, (context.shape[0], dim))  # temperature of the noise
        net = guided(model, context, config.guidance)
        return self.integrate(net, eps, key, config, model.time_context, known)


class RectifiedFlow(ConditionalFlow):
    """Sec. III-C: the paper's generator (Eqs. rf_loss, rf_inference)."""

    samplers = RF_SAMPLERS
    reflows = True  # its loss takes coupled noise and its sampler is an ODE (2-rectified flow)

    def loss(self, model, batch, key, config: TrainConfig):
        key, net = self.conditioned(model, batch, key, config)
        return rf_loss(net, batch["target"], key, time_sampler=config.time_sampler, noise=batch.get("noise"))

    @staticmethod
    def integrate(net, eps, key, config: SampleConfig, embed_time, known=None):
        del key  # the ODE is deterministic given eps
        return rf_sample(net, eps, steps=config.steps, sampler=config.sampler, embed_time=embed_time, known=known)


class DDPM(ConditionalFlow):
    """The diffusion baseline of Table II (epsilon prediction, cosine schedule): no inpainting, and its
    discrete diffusion steps take no flow-time distribution."""

    samplers = DDPM_SAMPLERS
    inpaints = False
    flow_times = False

    def loss(self, model, batch, key, config: TrainConfig):
        key, net = self.conditioned(model, batch, key, config)
        return ddpm_loss(net, batch["target"], key)

    @staticmethod
    def integrate(net, eps, key, config: SampleConfig, embed_time, known=None):
        del known  # never given: inpaints is False (methods.check_start_conditioning, at the boundary)
        return ddpm_sample(
            net,
            eps,
            jax.random.fold_in(key, 1),
            sampler=config.sampler,
            sample_steps=config.steps,
            embed_time=embed_time,
        )
