"""Trained semantic head (Sec. III-A, Eq. 3 learned): frozen MiniLM features -> p(m | r), p(z | r).

Eq. (3) keeps its meaning, with a learned mismatch in place of cosine distances:

    (m, z) = argmin_{m in M, z in Z}  L_sem(r, m, z),   L_sem = -log p(m | r) - log p(z | r)

so the answer is always one of the 16 x 4 tuples. ``p(m | r)`` is a softmax over the 16 intents plus one
"no behaviour" class (interface commands, noise), whose mass lowers the confidence without ever being
returned. ``p(z | r)`` is ordinal (cumulative-link) regression, P(z > k) = sigmoid(s(r) - theta_k) with
ordered thresholds theta_0 < theta_1 < theta_2, so "subtle" and "emphatic" are far apart by construction.

The features are one of the named input pipelines of :mod:`jgrounding.semantics.features` (the config's
``inputs``; the shipped head's: ``tuned``, MiniLM with its top layers trained with the head). Parameters are a small pytree shipped in
``jgrounding/assets/semantic_head.npz`` (``python -m tools.train_semantics`` regenerates it, deterministically).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding.io import asset
from jgrounding.semantics.features import Inputs, inputs_named
from jgrounding.vocabulary import NUM_INTENTS

ASSET = asset("semantic_head.npz")
NUM_CLASSES = NUM_INTENTS + 1  # the 16 intents and "none" (last)
NONE = NUM_INTENTS


@dataclasses.dataclass(frozen=True)
class HeadConfig:
    hidden: int = 128  # width of the intent MLP's hidden layer (0: linear)
    z_hidden: int = 0  # width of the intensity scorer's hidden layer (0: linear score)
    l2: float = 1e-4  # weight decay
    learning_rate: float = 3e-3
    steps: int = 400  # full-batch Adam steps
    dropout: float = 0.1  # on the input features, intent branch
    seed: int = 0
    inputs: str = "eq3"  # the input pipeline, by its name in jgrounding.semantics.features.INPUTS
    num_reasons: int = 0  # classes of the "why no behaviour" head (0: none)
    reason_weight: float = 0.3  # its loss weight
    tuned_layers: int = 0  # "tuned": how many top encoder layers were trained with the head (shipped as deltas)
    # The MiniLM layers the encoder keeps, by index (empty: all six). A distilled student keeps fewer:
    # its layers start from these, learn the six-layer teacher's token states, then train with the head; all of
    # them are then tuned and shipped as deltas from these base layers.
    encoder_layers: tuple[int, ...] = ()

    def __post_init__(self):
        inputs_named(self.inputs)  # a clear error naming the valid pipelines
        from jgrounding.semantics.encoder import NUM_LAYERS

        object.__setattr__(self, "encoder_layers", tuple(int(i) for i in self.encoder_layers))
        if any(not 0 <= i < NUM_LAYERS for i in self.encoder_layers) or list(self.encoder_layers) != sorted(
            set(self.encoder_layers)
        ):
            raise ValueError(
                f"encoder_layers {self.encoder_layers}: increasing MiniLM layer indices in 0..{NUM_LAYERS - 1}"
            )
        if self.tuned_layers > self.num_encoder_layers:
            raise ValueError(f"tuned_layers {self.tuned_layers} > the encoder's {self.num_encoder_layers} layers")

    @property
    def num_encoder_layers(self) -> int:
        """How many transformer layers the encoder this head reads runs."""
        from jgrounding.semantics.encoder import NUM_LAYERS

        return len(self.encoder_layers) or NUM_LAYERS

    @property
    def features(self) -> Inputs:
        """The input pipeline this head reads (:data:`jgrounding.semantics.features.INPUTS`)."""
        return inputs_named(self.inputs)

    @property
    def num_features(self) -> int:
        return self.features.width

    @classmethod
    def from_dict(cls, d: dict) -> HeadConfig:
        """The config a head file records; older files name the pipeline by ``use_eq3`` and an empty ``inputs``."""
        d = dict(d)
        use_eq3 = d.pop("use_eq3", True)
        return cls(**d | {"inputs": d.get("inputs") or ("eq3" if use_eq3 else "embedding")})


def init(key, cfg: HeadConfig, num_features: int | None = None) -> dict:
    """Parameters: intent MLP (features -> 17 logits) and ordinal intensity scorer (features -> s, theta)."""
    k_hidden, k_out, k_z, k_zh, k_why = jax.random.split(key, 5)
    f, h, zh = num_features or cfg.num_features, cfg.hidden, cfg.z_hidden
    glorot = jax.nn.initializers.glorot_normal()
    params = {
        "z_w": glorot(k_z, (zh or f, 1)),
        "z_b": jnp.zeros(()),
        "z_theta0": jnp.array(-1.5),
        "z_gaps": jnp.array([1.0, 1.0]),
    }
    if zh:
        params |= {"z_w1": glorot(k_zh, (f, zh)), "z_b1": jnp.zeros(zh)}
    if h:
        params |= {
            "w1": glorot(k_hidden, (f, h)),
            "b1": jnp.zeros(h),
            "w2": glorot(k_out, (h, NUM_CLASSES)),
            "b2": jnp.zeros(NUM_CLASSES),
        }
    else:
        params |= {"w2": glorot(k_out, (f, NUM_CLASSES)), "b2": jnp.zeros(NUM_CLASSES)}
    if cfg.num_reasons:
        params |= {"why_w": glorot(k_why, (h or f, cfg.num_reasons)), "why_b": jnp.zeros(cfg.num_reasons)}
    return params


def _hidden(params: dict, x):
    return jax.nn.gelu(x @ params["w1"] + params["b1"]) if "w1" in params else x


def reason_logits(params: dict, x):
    """Args: x ``(N, F)``. Returns ``(N, R)`` logits of why a text calls for no behaviour (the reason head)."""
    return _hidden(params, x) @ params["why_w"] + params["why_b"]


def intent_logits(params: dict, x):
    """Args: x ``(N, F)`` features. Returns ``(N, 17)`` logits over the intents and "none"."""
    return _hidden(params, x) @ params["w2"] + params["b2"]


def thresholds(params: dict):
    """The ordered cut points theta ``(3,)``: theta0, then positive gaps (softplus)."""
    return params["z_theta0"] + jnp.concatenate([jnp.zeros(1), jnp.cumsum(jax.nn.softplus(params["z_gaps"]))])


def intensity_score(params: dict, x):
    """Args: x ``(N, F)``. Returns the ordinal intensity score s ``(N,)`` (P(z > k) = sigmoid(s - theta_k))."""
    if "z_w1" in params:
        x = jax.nn.gelu(x @ params["z_w1"] + params["z_b1"])
    return (x @ params["z_w"])[:, 0] + params["z_b"]


def ordinal_log_probs(s, theta, xp=jnp):
    """log p(z) ``(N, 4)`` of the cumulative-link model from scores s ``(N,)`` and cut points theta ``(3,)``;
    ``xp``: ``jax.numpy`` or ``numpy``."""
    sigmoid = jax.nn.sigmoid if xp is jnp else (lambda v: 1.0 / (1.0 + np.exp(-v)))
    above = sigmoid(s[:, None] - theta[None])  # P(z > k), (N, 3), decreasing in k
    cdf = xp.concatenate([xp.ones_like(s)[:, None], above, xp.zeros_like(s)[:, None]], axis=1)
    return xp.log(xp.clip(cdf[:, :-1] - cdf[:, 1:], 1e-7, 1.0))


def intensity_log_probs(params: dict, x):
    """Args: x ``(N, F)``. Returns ``(N, 4)`` log p(z | r) of the cumulative-link model."""
    return ordinal_log_probs(intensity_score(params, x), thresholds(params))


def loss(params: dict, key, x, intent, intensity, weight, dropout: float = 0.0, why=None, why_weight: float = 0.0):
    """Weighted cross-entropy of the intent (17-way) plus the ordinal intensity NLL (rows with intensity >= 0).

    Args: x ``(N, F)``; intent ``(N,)`` in 0..16; intensity ``(N,)`` in 0..3 or -1 (no label); weight ``(N,)``;
    why ``(N,)``: the no-behaviour reason class, or -1 (no label), weighted by ``why_weight``.
    """
    keep = jax.random.bernoulli(key, 1.0 - dropout, x.shape) / (1.0 - dropout)
    logp = jax.nn.log_softmax(intent_logits(params, x * keep))
    ce = -jnp.take_along_axis(logp, intent[:, None], 1)[:, 0]
    zlogp = intensity_log_probs(params, x)
    has_z = intensity >= 0
    zce = -jnp.take_along_axis(zlogp, jnp.maximum(intensity, 0)[:, None], 1)[:, 0] * has_z
    total = jnp.sum(weight * ce) + jnp.sum(weight * zce)
    if why is not None and "why_w" in params:
        wlogp = jax.nn.log_softmax(reason_logits(params, x * keep))
        wce = -jnp.take_along_axis(wlogp, jnp.maximum(why, 0)[:, None], 1)[:, 0] * (why >= 0)
        total = total + why_weight * jnp.sum(wce) / jnp.maximum(jnp.sum(why >= 0), 1) * jnp.sum(weight)
    return total / jnp.sum(weight)


@functools.partial(jax.jit, static_argnames="cfg")
def train(key, x, intent, intensity, weight, cfg: HeadConfig, why=None) -> tuple[dict, jnp.ndarray]:
    """Full-batch AdamW for ``cfg.steps`` steps inside one ``lax.scan``.

    Args: key; x ``(N, F)``; intent ``(N,)``; intensity ``(N,)`` (-1: none); weight ``(N,)``; why ``(N,)`` the
    no-behaviour reason class or -1 (only with ``cfg.num_reasons``).
    Returns: (params, losses ``(steps,)``).
    """
    import optax  # training only: grounding does not import it

    init_key, dropout_key = jax.random.split(key)
    params = init(init_key, cfg, x.shape[1])
    opt = optax.adamw(cfg.learning_rate, weight_decay=cfg.l2)

    def step(carry, k):
        p, s = carry
        value, grads = jax.value_and_grad(loss)(p, k, x, intent, intensity, weight, cfg.dropout, why, cfg.reason_weight)
        updates, s = opt.update(grads, s, p)
        return (optax.apply_updates(p, updates), s), value

    (params, _), losses = jax.lax.scan(step, (params, opt.init(params)), jax.random.split(dropout_key, cfg.steps))
    return params, losses


def _members(params: dict) -> int:
    """How many heads an ensemble stacks on a leading axis (0: a single head)."""
    return params["b2"].shape[0] if params["b2"].ndim == 2 else 0


def _single(params: dict, x, temperature):
    h = _hidden(params, x)
    logits = h @ params["w2"] + params["b2"]
    why = h @ params["why_w"] + params["why_b"] if "why_w" in params else jnp.zeros((x.shape[0], 1))
    return logits / temperature, intensity_log_probs(params, x), why


def _predict_all(params: dict, x, temperature):
    """Args: x ``(N, F)``; temperature scalar. Returns intent probs ``(N, 17)``, intensity probs ``(N, 4)`` and the
    no-behaviour reason probs ``(N, R)`` (``(N, 1)`` without a reason head), in one compiled call.

    An ensemble (parameters stacked on a leading axis, :func:`stack`) averages its members' intent logits and
    their intensity and reason probabilities."""
    if _members(params):
        logits, zlogp, why = jax.vmap(_single, in_axes=(0, None, None))(params, x, temperature)
        return (
            jax.nn.softmax(logits.mean(0)),
            jnp.exp(zlogp).mean(0),
            jax.nn.softmax(why, axis=-1).mean(0),
        )
    logits, zlogp, why = _single(params, x, temperature)
    return jax.nn.softmax(logits), jnp.exp(zlogp), jax.nn.softmax(why, axis=-1)


predict_all = jax.jit(_predict_all)


KNN_POOLS = ("sentence", "chosen")  # the pooled vectors a nearest-neighbour table can be made of, by index
KNN_GATE_FLAGS = ("has_rejected", "log_line", "system_prefix", "not_understood", "background")


def knn_blend(knn: dict, p_intent, p_intensity, sentence, extras, k: int):
    """The nearest-neighbour vote over the training texts, blended into the head's intent (and intensity)
    probabilities.

    ``p = (1 - a) p_head + a p_knn`` for the texts the table's gate lets through (a gate over the extras' columns:
    those must be zero; the shipped table's: the chosen part names no action, and no rejected part, log, system,
    not-understood or background cue; an empty gate lets every text vote); other texts keep ``p_head``. ``p_knn``:
    the 17-way vote of the ``k`` training texts nearest to the query (the text's tuned pooled vector the table was
    made of, :attr:`Head.knn_pool`), cosine, weighted by exp((sim - best sim) / tau). With a ``temperature`` in the
    table, p^(1/T) renormalised, for every text; with a ``situation_temperature``, the same again for the texts the
    gate lets through (``tools.semantics_knn --situation-temperature``; the shipped table has none: the one
    tried did not pass its ship rule). With an intensity vote in the table (``onehot_z`` and its weight ``b``),
    the same neighbours' intensities vote too (those labelled with one; a text none of whose neighbours is keeps the
    head's): ``p_z = (1 - b) p_z_head + b p_z_knn`` for the texts the gate lets through.

    Args: knn (:func:`load_knn`: ``table`` ``(N, 384)`` unit vectors, ``onehot`` ``(N, 17)``, ``gate`` ``(E,)``
    0/1 over the extras' columns that must be zero (all zero: every text votes), ``tau``, ``a``, and optionally
    ``temperature``, ``situation_temperature``, and ``onehot_z`` ``(N, 4)`` (zero rows: no intensity label) with
    ``b``); p_intent ``(B, 17)``; p_intensity ``(B, 4)``; sentence: the query ``(B, 384)``, unit vectors; extras
    ``(B, E)``.
    Returns (p_intent ``(B, 17)``, p_intensity ``(B, 4)``)."""
    knn = jax.tree.map(jnp.asarray, knn)  # numpy tables too (tools.semantics_knn, tests): indexed by traced indices
    situation = jnp.sum(jnp.abs(extras) * knn["gate"], 1) == 0

    def blend(p):
        p_m, p_z = p
        sim = sentence @ knn["table"].T
        best, idx = jax.lax.top_k(sim, k)
        # An identity that keeps XLA's CPU top-k kernel: with the slice below fused onto its output the vote
        # took 0.50 ms instead of 0.14 ms (measured on 2 cores, 3,064 x 384 table).
        best = jax.lax.optimization_barrier(best)
        w = jnp.exp((best - best[:, :1]) / knn["tau"])
        vote = jnp.einsum("bk,bkc->bc", w, knn["onehot"][idx]) / jnp.sum(w, 1, keepdims=True)
        p_m = jnp.where(situation[:, None], (1.0 - knn["a"]) * p_m + knn["a"] * vote, p_m)
        if "onehot_z" in knn:
            vote_z = jnp.einsum("bk,bkc->bc", w, knn["onehot_z"][idx])
            mass = jnp.sum(vote_z, 1, keepdims=True)
            mixed = (1.0 - knn["b"]) * p_z + knn["b"] * vote_z / jnp.maximum(mass, 1e-12)
            p_z = jnp.where(situation[:, None] & (mass > 0), mixed, p_z)
        return p_m, p_z

    # With a gate, a batch none of whose texts passes it skips the table.
    p, p_z = jax.lax.cond(jnp.any(situation), blend, lambda p: p, (p_intent, p_intensity))
    if "temperature" in knn:  # a temperature fitted on dev to the blended distribution (every text's)
        p = _sharpen(p, knn["temperature"])
    if "situation_temperature" in knn:  # one fitted on the situation hold-outs, for the texts the gate lets through
        p = jnp.where(situation[:, None], _sharpen(p, knn["situation_temperature"]), p)
    return p, p_z


def _sharpen(p, t):
    """A temperature on distributions ``(B, C)``: p^(1/t), renormalised."""
    q = jnp.exp(jnp.log(jnp.clip(p, 1e-12, 1.0)) / t)
    return q / jnp.sum(q, 1, keepdims=True)


@functools.partial(jax.jit, static_argnames=("knn_k", "knn_pool"))
def predict_tuned(
    enc_params: dict, params: dict, ids, mask, pools, extras, temperature, knn=None, knn_k: int = 0, knn_pool: int = 0
):
    """The tuned head's whole grounding of a batch in one compiled program: the encoder (with its tuned top
    layers) pooled four ways (:func:`jgrounding.semantics.encoder.pool_ids`), the pooled vectors next to the
    non-encoder inputs, then :func:`predict_all`, and with ``knn`` (:attr:`Head.knn`) the nearest-neighbour
    vote blended into the intent (and intensity) probabilities (:func:`knn_blend`, ``knn_k`` neighbours of the text's pooled
    vector ``knn_pool``: 0 the whole text, 1 its chosen part).

    Args: enc_params (:meth:`Head.encoder_params`); ids, mask ``(B, L)``; pools ``(B, 4, L)``; extras ``(B, E)``
    (:func:`jgrounding.semantics.features.tuned_extras`). Returns :func:`predict_all`'s three arrays and the
    text's sentence vector ``(B, 384)`` (the tuned encoder's whole-text pooling), which the learned no-motion
    detector reads (:mod:`jgrounding.semantics.nomotion`), so it needs no second encoder pass."""
    from jgrounding.semantics import encoder

    pooled = encoder.pool_ids(enc_params, ids, mask, pools)
    x = jnp.concatenate([pooled.reshape(pooled.shape[0], -1), extras], axis=1)
    p_intent, p_intensity, p_why = _predict_all(params, x, temperature)
    if knn is not None:
        p_intent, p_intensity = knn_blend(knn, p_intent, p_intensity, pooled[:, knn_pool], extras, knn_k)
    return p_intent, p_intensity, p_why, pooled[:, 0]


def predict(params: dict, x, temperature):
    """Args: x ``(N, F)``; temperature scalar. Returns (intent probs ``(N, 17)``, intensity probs ``(N, 4)``)."""
    p_m, p_z, _ = predict_all(params, x, temperature)
    return p_m, p_z


def stack(members: list[dict]) -> dict:
    """An ensemble: the members' parameters stacked on a leading axis (same config, different seeds)."""
    return jax.tree.map(lambda *xs: np.stack(xs), *members)


def decide(p_intent: np.ndarray, p_intensity: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (3) with the learned mismatch: argmin over the 16 x 4 tuples of -log p(m) - log p(z).

    Args: p_intent ``(N, 17)``; p_intensity ``(N, 4)``. Returns intent ``(N,)``, intensity ``(N,)`` and the
    confidence ``(N,)`` = p(m | r) of the chosen intent (mass on "none" lowers it).
    """
    m = np.argmax(p_intent[:, :NUM_INTENTS], axis=1)
    z = np.argmax(p_intensity, axis=1)
    return m, z, p_intent[np.arange(len(m)), m]


def flatten(tree: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in tree.items():
        out |= flatten(v, f"{prefix}{k}/") if isinstance(v, dict) else {f"{prefix}{k}": v}
    return out


def unflatten(flat: dict) -> dict:
    out: dict = {}
    for k, v in flat.items():
        *path, leaf = k.split("/")
        node = out
        for part in path:
            node = node.setdefault(part, {})
        node[leaf] = v
    return out


def base_layers(cfg: HeadConfig, layers: dict | None = None) -> dict:
    """The frozen MiniLM's stacked layers (numpy, float32; ``layers``: all six, already read) that the encoder of
    ``cfg`` starts from: all six, or those ``cfg.encoder_layers`` keeps."""
    from jgrounding.semantics import encoder

    layers = encoder.load_numpy()["layers"] if layers is None else layers
    if cfg.encoder_layers:
        layers = jax.tree.map(lambda x: np.ascontiguousarray(x[list(cfg.encoder_layers)]), layers)
    return layers


def top_deltas(top: dict, cfg: HeadConfig) -> dict:
    """Tuned top encoder layers (stacked like :func:`encoder.load_params`' layers) as float16 differences from
    the frozen MiniLM's (:func:`base_layers`), which is how they are shipped (small, and exact to ~1e-6 of the
    weights)."""
    base = jax.tree.map(lambda x: x[-cfg.tuned_layers :], base_layers(cfg))
    return jax.tree.map(lambda t, b: (np.asarray(t, np.float32) - b).astype(np.float16), top, base)


def merged_layers(deltas: dict, cfg: HeadConfig, layers: dict | None = None) -> dict:
    """The encoder's stacked layers in float32 numpy (:func:`base_layers`, ``layers``: all six, already read) with
    the top ``cfg.tuned_layers`` replaced by base + ``deltas``: the trained encoder's weights, before
    :func:`with_top` stores them for grounding."""
    k = cfg.tuned_layers
    return jax.tree.map(
        lambda b, d: np.concatenate([b[:-k], b[-k:] + np.asarray(d, np.float32)]), base_layers(cfg, layers), deltas
    )


def with_top(deltas: dict, cfg: HeadConfig) -> dict:
    """The encoder's weights (the layers ``cfg.encoder_layers`` keeps) with its top ``cfg.tuned_layers`` layers
    replaced by base + ``deltas``, as grounding reads them: the dense matrices stored as
    :data:`jgrounding.semantics.encoder.MATRIX_STORAGE` says (:func:`jgrounding.semantics.encoder.stored_matrices`).

    Merged in numpy from the weights file and put on the device in one transfer (no small compiled ops and no
    second copy of the frozen encoder on a fresh process's first call)."""
    from jgrounding.semantics import encoder

    encoder.enable_compilation_cache()
    params = dict(encoder.load_numpy())
    params["layers"] = merged_layers(deltas, cfg, params["layers"])
    return jax.device_put(encoder.stored_matrices(params))


def save(path, params: dict, cfg: HeadConfig, meta: dict, top_delta: dict | None = None) -> Path:
    """Write the head (and the tuned encoder layers' float16 deltas, :func:`top_deltas`) atomically."""
    from jgrounding.io import write_atomic

    arrays = {f"param/{k}": np.asarray(v) for k, v in params.items()}
    arrays |= {f"top/{k}": np.asarray(v) for k, v in flatten(top_delta or {}).items()}
    buf = io.BytesIO()
    np.savez(buf, **arrays, config=json.dumps(dataclasses.asdict(cfg)), meta=json.dumps(meta, sort_keys=True))
    return write_atomic(path, buf.getvalue())


@dataclasses.dataclass(frozen=True)
class Head:
    params: dict
    config: HeadConfig
    temperature: float
    threshold: float
    meta: dict
    encoder: dict | None = dataclasses.field(default=None, compare=False, repr=False)
    knn: dict | None = dataclasses.field(default=None, compare=False, repr=False)  # :func:`load_knn`

    @property
    def knn_k(self) -> int:
        """How many neighbours the vote reads (0: no vote)."""
        return int(self.knn["meta"]["k"]) if self.knn else 0

    @property
    def knn_pool(self) -> int:
        """Which pooled vector the vote compares: 0 the whole text, 1 its chosen part (rejected words left out)."""
        return KNN_POOLS.index(self.knn["meta"].get("representation", "sentence")) if self.knn else 0

    def knn_arrays(self) -> dict | None:
        """The vote's device arrays as :func:`predict_tuned` takes them (None: no vote)."""
        return self.knn["arrays"] if self.knn else None

    def run_tuned(self, ids, mask, pools, extras):
        """:func:`predict_tuned` with this head's encoder, parameters, temperature and vote: the one program a
        grounding runs (intent, intensity and reason probabilities of the batch, and its sentence vectors)."""
        return predict_tuned(
            self.encoder_params(),
            self.params,
            ids,
            mask,
            pools,
            extras,
            self.temperature,
            self.knn_arrays(),
            knn_k=self.knn_k,
            knn_pool=self.knn_pool,
        )

    def encoder_params(self) -> dict:
        """The encoder weights this head reads (the frozen MiniLM, or with its tuned top layers)."""
        from jgrounding.semantics import encoder

        return self.encoder if self.encoder is not None else encoder.load_params()


def made_for_another_head(meta: dict, message: str) -> bool:
    """Whether an asset fitted on the shipped head's outputs (its ``meta["head_digest"]``) was made for another head
    than the shipped one; if so, warns with ``message`` (``{made}``: the asset's head, ``{shipped}``: the shipped
    head's digest), attributed to the caller's caller. The learned detector and the act/hold operating point check
    themselves this way."""
    shipped = load().meta.get("params_digest")
    if meta.get("head_digest") == shipped:
        return False
    import warnings

    warnings.warn(message.format(made=meta.get("head_digest"), shipped=shipped), stacklevel=3)
    return True


@functools.lru_cache(maxsize=4)
def load(path: str | None = None) -> Head:
    """The shipped head (``jgrounding/assets/semantic_head.npz``); ``FileNotFoundError`` says how to regenerate it. A tuned
    head made with the shipped nearest-neighbour table (``jgrounding/assets/semantic_knn.npz``, :func:`load_knn`) comes with
    it, and with the confidence threshold refitted on dev with the vote."""
    path = Path(path or ASSET)
    if not path.exists():
        raise FileNotFoundError(f"{path} missing; regenerate it with `python -m tools.train_semantics`")
    with np.load(path) as f:
        params = {k.split("/", 1)[1]: jnp.asarray(f[k]) for k in f.files if k.startswith("param/")}
        cfg = HeadConfig.from_dict(json.loads(str(f["config"])))
        meta = json.loads(str(f["meta"]))
        deltas = unflatten({k.split("/", 1)[1]: f[k] for k in f.files if k.startswith("top/")})
    enc = with_top(deltas, cfg) if cfg.tuned_layers else None
    threshold = float(meta["threshold"])
    knn = load_knn(meta.get("params_digest", "")) if cfg.features.one_program else None
    if knn is not None:
        threshold = float(knn["meta"]["threshold"])
    return Head(params, cfg, float(meta["temperature"]), threshold, meta, enc, knn)


KNN_ASSET = ASSET.with_name("semantic_knn.npz")


def knn_digest(table, labels, intensities=None) -> str:
    """Digest of a nearest-neighbour table: its vectors (float16), their intent labels and, for a table with an
    intensity vote, their intensity labels."""
    h = hashlib.sha256(np.asarray(table, np.float16).tobytes())
    h.update(np.asarray(labels, np.int32).tobytes())
    if intensities is not None:
        h.update(np.asarray(intensities, np.int32).tobytes())
    return h.hexdigest()[:16]


def save_knn(path, table, labels, gate, meta: dict, intensities=None) -> Path:
    """Write a nearest-neighbour table atomically: ``table`` ``(N, 384)`` unit vectors (stored float16),
    ``labels`` ``(N,)`` in 0..16, ``gate`` ``(E,)`` 0/1 over the extras; ``meta``: k, tau, a, threshold,
    head_digest (the head whose encoder made the vectors), and ``b`` (the intensity vote's weight) with
    ``intensities`` ``(N,)`` in 0..3 or -1 (no label); its digest is added (:func:`knn_digest`)."""
    from jgrounding.io import write_atomic

    table = np.asarray(table, np.float16)
    meta = dict(meta, digest=knn_digest(table, labels, intensities))
    buf = io.BytesIO()
    np.savez(
        buf,
        table=table,
        labels=np.asarray(labels, np.int8),
        gate=np.asarray(gate, np.float32),
        meta=json.dumps(meta, sort_keys=True),
        **({} if intensities is None else {"intensities": np.asarray(intensities, np.int8)}),
    )
    return write_atomic(path, buf.getvalue())


def intensity_onehot(intensities) -> np.ndarray:
    """One-hot rows ``(N, 4)`` float32 of intensity labels ``(N,)`` in 0..3; -1 (no label) gives a zero row, which
    votes for no intensity in :func:`knn_blend`."""
    rows = np.eye(5, dtype=np.float32)[np.asarray(intensities)]  # -1 picks the last row: zero in the first 4
    return rows[:, :4]


def load_knn(head_digest: str, path=None) -> dict | None:
    """The nearest-neighbour table made for the head with parameters digest ``head_digest`` (None when the asset is
    missing or was made for another head): ``arrays``, the device arrays :func:`knn_blend` reads (``table``
    ``(N, 384)``, stored float16, ``onehot`` ``(N, 17)``, ``gate`` ``(E,)``, scalars ``tau`` and ``a``,
    ``temperature`` and ``situation_temperature`` when the meta's are not 1, and ``onehot_z`` ``(N, 4)`` with ``b``
    when the table has an intensity vote), and its ``meta`` (which pooled vector, k, the refitted threshold).
    ``ValueError`` when its digest does not match."""
    path = Path(path or KNN_ASSET)
    if not path.exists():
        return None
    with np.load(path) as f:
        meta = json.loads(str(f["meta"]))
        if meta.get("head_digest") != head_digest:
            return None
        table, labels, gate = f["table"], f["labels"].astype(np.int32), f["gate"]
        intensities = f["intensities"].astype(np.int32) if "intensities" in f.files else None
    if knn_digest(table, labels, intensities) != meta["digest"]:
        raise ValueError(
            f"{path}: the table's digest does not match its meta; regenerate it with `python -m tools.semantics_knn --write`"
        )
    onehot = np.eye(NUM_CLASSES, dtype=np.float32)[labels]
    arrays = jax.device_put(  # float32 on the device: no conversion per call
        {
            "table": table.astype(np.float32),
            "onehot": onehot,
            "gate": gate,
            "tau": np.float32(meta["tau"]),
            "a": np.float32(meta["a"]),
        }
        | ({"temperature": np.float32(meta["temperature"])} if meta.get("temperature", 1.0) != 1.0 else {})
        | (
            {"situation_temperature": np.float32(meta["situation_temperature"])}
            if meta.get("situation_temperature", 1.0) != 1.0
            else {}
        )
        | (
            {"onehot_z": intensity_onehot(intensities), "b": np.float32(meta["b"])}
            if intensities is not None and meta.get("b", 0.0) > 0
            else {}
        )
    )
    return {"arrays": arrays, "meta": meta}


def digest(params: dict) -> str:
    h = hashlib.sha256()
    for k in sorted(params):
        h.update(k.encode() + np.asarray(params[k], np.float32).tobytes())
    return h.hexdigest()[:16]
