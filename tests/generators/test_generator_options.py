"""Generator options (issue #16): flow-time samplers, coupled noise, EMA, condition dropout, guidance, reflow."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

import jgrounding as jg
from jgrounding import semantics, training
from jgrounding.config import SampleConfig
from jgrounding.evaluation import generate
from jgrounding.generators import flows, methods
from jgrounding.generators.networks import VelocityMLP
from jgrounding.training import trainer


@pytest.mark.parametrize(
    "name,mean",
    [
        ("uniform", 0.5),
        ("logit_normal", 0.5),
        # pi0: lambda = 1 - (Beta(1.5, 1) * 0.999 + 0.001); E Beta(1.5, 1) = 0.6
        ("beta", 1 - (0.6 * 0.999 + 0.001)),
    ],
)
def test_flow_time_samplers_lie_in_the_unit_interval_with_their_mean(name, mean):
    lam = np.asarray(flows.sample_flow_time(jax.random.key(0), (20_000,), name))
    assert lam.min() > 0 and lam.max() < 1
    assert abs(lam.mean() - mean) < 0.01


def test_unknown_time_sampler_lists_the_valid_ones():
    with pytest.raises(ValueError, match="uniform, logit_normal, beta"):
        flows.sample_flow_time(jax.random.key(0), (3,), "cosine")
    with pytest.raises(ValueError, match="time_sampler"):
        training.TrainConfig(time_sampler="cosine")


def test_rf_loss_uses_the_coupled_noise_it_is_given():
    c = jax.random.normal(jax.random.key(1), (5, 3))
    noise = jax.random.normal(jax.random.key(2), (5, 3))
    exact = lambda x, t: c - noise
    assert float(flows.rf_loss(exact, c, jax.random.key(3), noise=noise)) == 0.0
    assert float(flows.rf_loss(exact, c, jax.random.key(3))) > 0.1  # a fresh draw is another eps


def test_ema_follows_the_warmed_up_recursion():
    # loss = (p - 1)^2 on a scalar; with ema_decay d: e_{k+1} = d_k e_k + (1 - d_k) p_{k+1},
    # d_k = min(d, (1 + k) / (10 + k)), e_0 = p_0.
    cfg = training.TrainConfig(steps=5, chunk=5, ema_decay=0.5, learning_rate=0.1, weight_decay=0.0)
    step = training.make_step(lambda p, idx, key: (p - 1.0) ** 2, 1, cfg)
    state = training.init_state(jnp.float32(0.0), jax.random.key(0), cfg)
    e = 0.0
    for k in range(5):
        state, _ = step(state)
        e = min(0.5, (1 + k) / (10 + k)) * e + (1 - min(0.5, (1 + k) / (10 + k))) * float(state.params)
    assert np.isclose(float(state.ema), e, atol=1e-6)
    assert training.eval_params(state) is state.ema
    plain = training.init_state(jnp.float32(0.0), jax.random.key(0), dataclasses.replace(cfg, ema_decay=0.0))
    assert plain.ema is None and training.eval_params(plain) is plain.params


def test_condition_dropout_zeroes_the_condition():
    model = VelocityMLP(8, rngs=nnx.Rngs(0))
    x, t = jnp.ones((2, 8)), jnp.full((2,), 0.3)
    text, z = jnp.ones((2, 384)), jnp.array([1, 2])
    dropped = model(x, t, text, z, keep=jnp.array([0.0, 1.0]))
    h = nnx.silu(x @ model.l1.kernel.value[:8] + model.time_context(t) + model.null_context(2))
    h = nnx.silu(model.l3(nnx.silu(model.l2(h))))
    assert np.allclose(dropped[0], model.l4(h)[0], atol=1e-5)
    assert np.allclose(dropped[1], model(x, t, text, z)[1], atol=1e-5)


@pytest.fixture(scope="module")
def tiny():
    lib = jg.load_library()
    cfg = training.TrainConfig(steps=20, chunk=10, condition_dropout=0.2)
    return lib, trainer.fit(
        "tuple_spline_rf", lib, (0, 1), cfg, intent_emb=semantics.intent_embeddings(), progress=False
    )


def test_guidance_extrapolates_from_the_null_condition(tiny):
    lib, tr = tiny
    model = nnx.merge(tr.graphdef, jax.tree.map(lambda x: x[0], tr.params))
    cond = jnp.asarray(semantics.intent_embeddings()[:3])
    z = jnp.array([0, 1, 3])
    eps = jax.random.normal(jax.random.key(0), (3, 16))  # what the sampler draws from its key
    w = 2.0
    got = methods.spec(tr.method).generator.sample(model, cond, z, jax.random.key(0), 16, SampleConfig("euler", 1, w))
    tc = model.time_context(jnp.zeros(1))[0]
    v_c = model.velocity(eps, tc, model.context(cond, z))
    v_u = model.velocity(eps, tc, model.null_context(3))
    assert np.allclose(got, eps + v_c + w * (v_c - v_u), atol=1e-5)  # one Euler step, dt = 1


def test_guidance_zero_is_the_conditional_sampler(tiny):
    lib, tr = tiny
    cond = semantics.intent_embeddings()[lib.heldout.intent[:4]]

    def draw(config):
        return generate.generate(tr, cond, lib.heldout.intensity[:4], jax.random.key(5), num_samples=2, config=config)

    a, b, c = (draw(SampleConfig(steps=4, **w)) for w in ({}, {"guidance": 0.0}, {"guidance": 1.0}))
    assert np.array_equal(a, b) and not np.allclose(a, c)


def test_options_that_do_not_apply_are_refused():
    lib = jg.load_library()
    with pytest.raises(ValueError, match="deterministic regressor"):
        trainer.fit("tuple_spline_cnn", lib, (0,), training.TrainConfig(steps=1, condition_dropout=0.1))
    with pytest.raises(ValueError, match="rectified flow"):
        trainer.fit("tuple_spline_ddpm", lib, (0,), training.TrainConfig(steps=1, time_sampler="beta"))


@pytest.mark.slow
def test_reflow_keeps_seeds_shapes_and_starts_from_the_teacher(tiny):
    lib, tr = tiny
    rf = trainer.reflow(
        tr,
        lib,
        training.TrainConfig(steps=10, chunk=10, learning_rate=0.0, weight_decay=0.0),
        pairs_per_example=2,
        progress=False,
    )
    assert rf.seeds == tr.seeds and rf.losses.shape == (2, 10)
    same = jax.tree.map(lambda a, b: bool(np.allclose(a, b)), rf.params, tr.params)
    assert all(jax.tree.leaves(same))  # learning rate 0: the student is its teacher
