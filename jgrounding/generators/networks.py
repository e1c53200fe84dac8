"""Networks of Table I (Flax NNX): the velocity / noise MLP and the deterministic 1-D CNN regressors.

Each model takes a flat target ``x`` (controls 4 x P or dense 150 x 4, flattened), a flow/diffusion
time ``t`` and a condition: the frozen text embedding (E_m(m) of the intent, or of the raw response)
plus, for tuple conditioning, a learnable intensity embedding E_z(z).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import nnx

from jgrounding.config import NUM_TENDONS, ModelConfig
from jgrounding.vocabulary import INTENSITIES


def sinusoidal(t: jax.Array, dim: int, scale: float = 1000.0) -> jax.Array:
    """Sinusoidal embedding of times ``(...,)`` in [0, 1] -> ``(..., dim)`` (Table I: dim 128); angular
    frequencies from ``scale`` down to ``scale / 10^4``."""
    half = dim // 2
    freqs = jnp.exp(-jnp.log(10_000.0) * jnp.arange(half) / half)
    ang = scale * t[..., None] * freqs
    return jnp.concatenate([jnp.sin(ang), jnp.cos(ang)], axis=-1)


class Condition(nnx.Module):
    """E_m(m) (frozen, given) concatenated with a learnable E_z(z); raw conditioning uses only the text."""

    def __init__(self, use_intensity: bool, config: ModelConfig = ModelConfig(), *, rngs: nnx.Rngs):
        self.use_intensity = use_intensity
        self.text_dim = config.text_dim
        self.intensity = nnx.Embed(len(INTENSITIES), config.intensity_dim, rngs=rngs) if use_intensity else None

    @property
    def dim(self) -> int:
        return self.text_dim + (self.intensity.features if self.use_intensity else 0)

    def __call__(self, text_emb, intensity):
        if not self.use_intensity:
            return text_emb
        return jnp.concatenate([text_emb, self.intensity(intensity)], axis=-1)


class VelocityMLP(nnx.Module):
    """v_theta(c_lambda, lambda | E_m, E_z): MLP (Table I: 4 layers, width 256, SiLU, 128-d time embedding).

    Layers are ``l1 .. l<depth>``: the first takes [x, time embedding, condition]; the last is linear.
    """

    def __init__(self, dim: int, use_intensity: bool = True, config: ModelConfig = ModelConfig(), *, rngs: nnx.Rngs):
        self.dim, self.time_dim, self.depth = dim, config.time_dim, config.depth
        self.cond = Condition(use_intensity, config, rngs=rngs)
        sizes = [dim + config.time_dim + self.cond.dim] + [config.width] * (config.depth - 1) + [dim]
        for i in range(config.depth):
            setattr(self, f"l{i + 1}", nnx.Linear(sizes[i], sizes[i + 1], rngs=rngs))

    def _head(self, h):
        """SiLU after the first layer, then the hidden layers and the linear output."""
        h = nnx.silu(h)
        for i in range(2, self.depth):
            h = nnx.silu(getattr(self, f"l{i}")(h))
        return getattr(self, f"l{self.depth}")(h)

    def context(self, text_emb, intensity):
        """The condition's share of the first layer: constant across flow steps, so computed once."""
        w = self.l1.kernel.value[self.dim + self.time_dim :]
        return self.cond(text_emb, intensity) @ w + self.l1.bias.value

    def null_context(self, batch: int):
        """:meth:`context` of the null condition (all-zero condition vector, the classifier-free guidance
        "unconditional" input trained by condition dropout) ``-> (batch, width)``."""
        return jnp.broadcast_to(self.l1.bias.value, (batch, self.l1.out_features))

    def time_context(self, t):
        """The flow time's share of the first layer ``(n,) -> (n, width)``: a sampler computes it for all
        its steps at once, before its loop (the schedule is fixed)."""
        return sinusoidal(t, self.time_dim) @ self.l1.kernel.value[self.dim : self.dim + self.time_dim]

    def velocity(self, x, time_context, context):
        """One network evaluation from precomputed :meth:`time_context` and :meth:`context` rows."""
        return self._head(x @ self.l1.kernel.value[: self.dim] + time_context + context)

    def __call__(self, x, t, text_emb, intensity, keep=None):
        """``keep (B,)`` in {0, 1}: 0 replaces the condition by the null condition (condition dropout)."""
        cond = self.cond(text_emb, intensity)
        if keep is not None:
            cond = cond * keep[:, None]
        return self._head(self.l1(jnp.concatenate([x, sinusoidal(t, self.time_dim), cond], axis=-1)))


class Conv1D(nnx.Module):
    """'Same'-padded 1-D convolution as one matmul over stacked shifted windows.

    Written out (rather than ``nnx.Conv``) because under ``vmap`` over seeds XLA turns a batched conv
    into a grouped convolution, which is ~10x slower on CPU than this einsum.
    """

    def __init__(self, cin: int, cout: int, kernel: int, *, rngs: nnx.Rngs):
        self.kernel = kernel
        scale = 1.0 / jnp.sqrt(cin * kernel)
        self.w = nnx.Param(jax.random.uniform(rngs.params(), (kernel, cin, cout), minval=-scale, maxval=scale))
        self.b = nnx.Param(jnp.zeros((cout,)))

    def __call__(self, x):  # (..., L, C)
        half = self.kernel // 2
        pad = [(0, 0)] * (x.ndim - 2) + [(half, self.kernel - 1 - half), (0, 0)]
        xp = jnp.pad(x, pad)
        length = x.shape[-2]
        windows = jnp.stack([xp[..., i : i + length, :] for i in range(self.kernel)], axis=-2)  # (..., L, k, C)
        return jnp.einsum("...lkc,kco->...lo", windows, self.w.value) + self.b.value


class CNNRegressor(nnx.Module):
    """Deterministic 1-D CNN: condition -> (length, N_u) trajectory (dense, T=150) or controls (P)."""

    def __init__(
        self,
        length: int,
        use_intensity: bool = True,
        channels: int = 64,
        num_tendons: int = NUM_TENDONS,
        config: ModelConfig = ModelConfig(),
        *,
        rngs: nnx.Rngs,
    ):
        self.length = length
        self.base = max(length // 4, 1) if length > 16 else length
        self.cond = Condition(use_intensity, config, rngs=rngs)
        self.inp = nnx.Linear(self.cond.dim, self.base * channels, rngs=rngs)
        self.c1 = Conv1D(channels, channels, config.cnn_kernel, rngs=rngs)
        self.c2 = Conv1D(channels, channels, config.cnn_kernel, rngs=rngs)
        self.c3 = Conv1D(channels, channels, config.cnn_kernel, rngs=rngs)
        self.out = Conv1D(channels, num_tendons, 3, rngs=rngs)
        self.channels = channels

    def __call__(self, text_emb, intensity):
        h = nnx.relu(self.inp(self.cond(text_emb, intensity)))
        h = h.reshape(h.shape[:-1] + (self.base, self.channels))
        h = nnx.relu(self.c1(h))
        h = nnx.relu(self.c2(h))
        h = nnx.relu(self.c3(h))
        if self.base != self.length:  # upsample to the dense horizon; the output layer works per step
            # nearest-neighbour upsampling (a gather): cheap forward and backward on CPU
            src = jnp.minimum((jnp.arange(self.length) * self.base) // self.length, self.base - 1)
            h = h[..., src, :]
        return self.out(h)  # (..., length, N_u)


# Angular frequency of the fastest time feature of the two-time MLP. MeanFlow's target holds d/dt of the
# network (a JVP): with the flow MLP's 1000 that derivative is dominated by the embedding's own
# oscillation and training diverged (one seed, 6,000 steps: Prec@r 0.00 at S = 1 against 0.39 with 30 and
# 0.58 with 10); the shortcut model also learned better (Prec@r 0.11 with 1000, 0.29 with 30 and 10).
TWO_TIME_SCALE = 10.0


class TwoTimeMLP(VelocityMLP):
    """The velocity MLP with a second time input: ``net(x, t, s | E_m, E_z)``, Table I sizes.

    The few-step generators (:mod:`jgrounding.generators.few_step`) condition on where a jump starts
    (flow time ``t``) and how far it goes: the interval length for MeanFlow's average velocity, the step
    size ``d`` for a shortcut model. Both are embedded like the flow time (128-d sinusoidal each) and
    enter the first layer beside it: ``[x, emb(t), emb(s), condition]``.
    """

    def __init__(self, dim: int, use_intensity: bool = True, config: ModelConfig = ModelConfig(), *, rngs: nnx.Rngs):
        self.dim, self.time_dim, self.depth = dim, config.time_dim, config.depth
        self.cond = Condition(use_intensity, config, rngs=rngs)
        self.time_scale = TWO_TIME_SCALE
        sizes = [dim + 2 * config.time_dim + self.cond.dim] + [config.width] * (config.depth - 1) + [dim]
        for i in range(config.depth):
            setattr(self, f"l{i + 1}", nnx.Linear(sizes[i], sizes[i + 1], rngs=rngs))

    def context(self, text_emb, intensity):
        w = self.l1.kernel.value[self.dim + 2 * self.time_dim :]
        return self.cond(text_emb, intensity) @ w + self.l1.bias.value

    def time_context(self, t, s):
        """Both times' share of the first layer ``(n,), (n,) -> (n, width)``, computed once per sampler."""
        k = self.l1.kernel.value
        a, b = self.dim, self.dim + self.time_dim
        emb_t, emb_s = sinusoidal(t, self.time_dim, self.time_scale), sinusoidal(s, self.time_dim, self.time_scale)
        return emb_t @ k[a:b] + emb_s @ k[b : b + self.time_dim]

    def __call__(self, x, t, s, text_emb, intensity, keep=None):
        """``x (B, D)``, times ``t, s (B,)``; ``keep (B,)`` in {0, 1}: 0 = the null condition."""
        cond = self.cond(text_emb, intensity)
        if keep is not None:
            cond = cond * keep[:, None]
        emb = [sinusoidal(t, self.time_dim, self.time_scale), sinusoidal(s, self.time_dim, self.time_scale)]
        return self._head(self.l1(jnp.concatenate([x, *emb, cond], axis=-1)))
