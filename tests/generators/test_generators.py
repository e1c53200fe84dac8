"""Flows, training, checkpoints and the public sampler (issue: generators)."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import nnx

import jgrounding as jg
from jgrounding import safety, training
from jgrounding.config import ModelConfig
from jgrounding.generators import flows, methods
from jgrounding.generators.networks import CNNRegressor, VelocityMLP
from jgrounding.training import checkpoints, trainer

MODES = jnp.array([[-0.8, 0.8], [0.8, -0.8]])  # two modes for the same condition


def toy_train(generator: str, steps: int = 2500):
    """Train a tiny model on a 2-mode dataset (one condition); returns samples (512, 2)."""
    rngs = nnx.Rngs(0)
    model = VelocityMLP(2, True, ModelConfig(width=64), rngs=rngs) if generator != "cnn" else None
    if generator == "cnn":
        model = CNNRegressor(1, True, channels=16, rngs=rngs)
    graphdef, params = nnx.split(model)
    data = jnp.repeat(MODES, 64, axis=0)

    def loss(p, idx, key):
        m = nnx.merge(graphdef, p)
        y = data[idx]
        cond, inten = jnp.zeros((y.shape[0], 384)), jnp.zeros((y.shape[0],), jnp.int32)
        if generator == "cnn":
            return jnp.mean((m(cond, inten)[:, 0, :2] - y) ** 2)
        net = lambda x, t: m(x, t, cond, inten)  # noqa: E731
        return flows.rf_loss(net, y, key) if generator == "rf" else flows.ddpm_loss(net, y, key)

    cfg = training.TrainConfig(steps=steps, chunk=steps, batch_size=64)
    step = training.make_step(loss, data.shape[0], cfg)
    state = jax.tree.map(lambda x: x[None], training.init_state(params, jax.random.key(1), cfg))
    state, losses = training.train(state, step, cfg, progress=False)
    p = jax.tree.map(lambda x: x[0], state.params)
    m = nnx.merge(graphdef, p)
    c512, z512 = jnp.zeros((512, 384)), jnp.zeros((512,), jnp.int32)
    eps = jax.random.normal(jax.random.key(2), (512, 2))
    if generator == "cnn":
        return np.asarray(m(c512, z512)[:, 0, :2]), np.asarray(losses[0])
    net = lambda x, t: m(x, t, c512, z512)  # noqa: E731
    if generator == "rf":
        return np.asarray(flows.rf_sample(net, eps, steps=50)), np.asarray(losses[0])
    return np.asarray(flows.ddpm_sample(net, eps, jax.random.key(3))), np.asarray(losses[0])


@pytest.mark.parametrize("generator", ["rf", "ddpm"])
def test_distributional_generators_recover_both_modes(generator):
    x, losses = toy_train(generator)
    assert losses[-200:].mean() < losses[:50].mean()  # the loss falls
    d = np.linalg.norm(x[:, None] - np.asarray(MODES)[None], axis=-1)
    near = d.min(axis=1) < 0.35
    frac = np.bincount(d.argmin(axis=1)[near], minlength=2) / len(x)
    assert near.mean() > 0.8 and frac.min() > 0.25  # both modes, not their mean
    assert np.linalg.norm(x.mean(0)) < 0.4


def test_cnn_regressor_collapses_to_the_mean():
    x, _ = toy_train("cnn", steps=600)
    assert np.abs(x - x.mean(0)).max() < 1e-5  # deterministic: one output for one condition
    assert np.linalg.norm(x.mean(0)) < 0.2  # ... the average of the two modes


@pytest.mark.parametrize("sampler", flows.RF_SAMPLERS)
def test_rf_samplers_integrate_a_known_field(sampler):
    # v(x, t) = target - eps along the straight line: exact for any step count
    target = jnp.ones((4, 3))
    eps = jnp.zeros((4, 3))
    out = flows.rf_sample(lambda x, t: target - eps, eps, steps=4, sampler=sampler)
    np.testing.assert_allclose(out, target, atol=1e-6)


def test_resumed_training_equals_uninterrupted(tmp_path):
    lib = jg.load_library()
    cfg = training.TrainConfig(steps=60, chunk=20)
    emb = np.random.default_rng(0).normal(size=(16, 384)).astype(np.float32)
    full = trainer.fit("tuple_spline_rf", lib, (0, 1), cfg, intent_emb=emb, progress=False)

    saved = {}

    def stop_after_first(states, done):
        if done == 20:
            tree = dataclasses.replace(states, key=jax.random.key_data(states.key))
            checkpoints.save(tmp_path / "run", tree, {"method": "tuple_spline_rf", "step": done})
            saved["template"] = tree
            raise KeyboardInterrupt  # simulated kill at a chunk boundary

    with pytest.raises(KeyboardInterrupt):
        trainer.fit("tuple_spline_rf", lib, (0, 1), cfg, intent_emb=emb, progress=False, on_chunk=stop_after_first)
    tree, meta = checkpoints.restore(tmp_path / "run", saved["template"], expect={"method": "tuple_spline_rf"})
    states = dataclasses.replace(tree, key=jax.random.wrap_key_data(jnp.asarray(tree.key)))
    resumed = trainer.fit("tuple_spline_rf", lib, (0, 1), cfg, intent_emb=emb, progress=False, initial_states=states)
    for a, b in zip(jax.tree.leaves(full.params), jax.tree.leaves(resumed.params)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_checkpoint_refuses_bad_files(tmp_path):
    tree = {"w": np.ones((2, 3), np.float32)}
    checkpoints.save(tmp_path / "ok", tree, {"method": "tuple_spline_rf"})
    back, meta = checkpoints.restore(tmp_path / "ok", tree)
    np.testing.assert_array_equal(back["w"], tree["w"])
    with pytest.raises(ValueError, match="shape"):
        checkpoints.restore(tmp_path / "ok", {"w": np.ones((3, 3), np.float32)})
    with pytest.raises(ValueError, match="method"):
        checkpoints.restore(tmp_path / "ok", tree, expect={"method": "tuple_spline_ddpm"})
    checkpoints.save(tmp_path / "nan", {"w": np.full((2, 3), np.nan, np.float32)}, {})
    with pytest.raises(ValueError, match="NaN"):
        checkpoints.restore(tmp_path / "nan", tree)
    with pytest.raises(FileNotFoundError):
        checkpoints.restore(tmp_path / "none", tree)
    assert not list(tmp_path.glob("*.tmp-*"))  # nothing half-written left behind


def test_sample_shapes_bounds_determinism():
    u = jg.sample(jax.random.key(0), "comforting", "moderate")
    assert u.shape == (150, 4) and u.dtype == np.float32 and safety.is_safe(u)
    U = jg.sample(jax.random.key(0), "embracing", "emphatic", num_samples=30)
    assert U.shape == (30, 150, 4) and safety.is_safe(U)
    np.testing.assert_array_equal(u, jg.sample(jax.random.key(0), "comforting", "moderate"))
    assert not np.array_equal(u, jg.sample(jax.random.key(1), "comforting", "moderate"))
    np.testing.assert_array_equal(jg.sample(jax.random.PRNGKey(3), 2, 1), jg.sample(jax.random.key(3), 2, 1))
    assert jg.sample(jax.random.key(0), "nodding", "subtle", sampler="rk4", steps=4).shape == (150, 4)


def test_sample_follows_the_library():
    lib = jg.load_library()
    j = 5 * 4 + 3
    U = jg.sample(jax.random.key(0), int(lib.heldout.intent[j]), int(lib.heldout.intensity[j]), num_samples=16)
    # embracing is one-to-many (two variants, library v2): some sample reaches the held-out variant
    assert float(np.sqrt(((U - lib.heldout.u[j]) ** 2).mean(axis=(1, 2))).min()) < 0.35


@pytest.mark.parametrize(
    "kwargs, exc, match",
    [
        (dict(intent="dance"), ValueError, "greeting"),
        (dict(intensity="extreme"), ValueError, "subtle"),
        (dict(num_samples=0), ValueError, "num_samples"),
        (dict(num_samples=10**6), ValueError, "num_samples"),
        (dict(sampler="heun"), ValueError, "euler"),
        (dict(steps=0), ValueError, "steps"),
        (dict(key=7), TypeError, "jax.random.key"),
    ],
)
def test_sample_rejects_bad_input(kwargs, exc, match):
    args = dict(key=jax.random.key(0), intent="greeting", intensity="moderate")
    args.update(kwargs)
    with pytest.raises(exc, match=match):
        jg.sample(args.pop("key"), args.pop("intent"), args.pop("intensity"), **args)


def test_method_names_are_validated():
    with pytest.raises(ValueError, match="tuple_spline_rf"):
        methods.spec("tuple_spline_gan")


def test_every_generator_declares_the_protocol_abilities_and_the_registry_reads_them():
    from jgrounding.generators.base import Generator

    abilities = Generator.__annotations__  # declared once, on the protocol: name -> "bool" or "tuple[str, ...]"
    assert {"uses_context", "inpaints", "null_condition", "iterative"} <= set(abilities)
    for name, s in methods.REGISTRY.items():
        for ability, hint in abilities.items():
            assert isinstance(getattr(s.generator, ability), bool if hint == "bool" else tuple), (name, ability)
    starts = {n for n in methods.REGISTRY if methods.can_start_condition(n)}
    assert starts == {"tuple_spline_rf", "tuple_spline_meanflow", "tuple_spline_shortcut", "tuple_spline_rf_physics"}
    assert not methods.spec("tuple_spline_ddpm").generator.inpaints  # a DDPM sampler keeps no known coordinates
    assert not methods.spec("tuple_spline_cnn").generator.null_condition  # a regressor has no guidance
