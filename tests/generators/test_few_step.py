"""One-step generators (issue #25): MeanFlow and the shortcut model (jgrounding/generators/few_step.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jgrounding as jg
from experiments import train as train_cli
from jgrounding import training
from jgrounding.config import ModelConfig, SampleConfig
from jgrounding.generators import few_step, methods
from jgrounding.policy import sampling
from jgrounding.training import trainer

FEW_STEP = ("tuple_spline_meanflow", "tuple_spline_shortcut")


def _point_mass_field(c):
    """The exact flow to a single data point c: straight paths, so the velocity of any jump from (x, t)
    is (c - x) / (1 - t) whatever its length."""
    return lambda x, t, s: (c - x) / (1.0 - t[:, None])


@pytest.mark.parametrize("loss", [few_step.meanflow_loss, few_step.shortcut_loss])
def test_the_exact_field_of_a_point_mass_has_zero_loss_and_a_wrong_one_does_not(loss):
    # For data = one point c, z_t = (1 - t) eps + t c gives c - z_t = (1 - t)(c - eps), so the field
    # returns v = c - eps; MeanFlow: du/dt = v . (-1 / (1 - t)) + (c - z) / (1 - t)^2 = 0, target = v;
    # shortcut: two jumps of d land on the same straight line, so their mean velocity is v too.
    c = jnp.tile(jnp.linspace(-0.5, 0.5, 6)[None], (64, 1))
    key = jax.random.key(0)
    assert float(loss(_point_mass_field(c), c, key)) == pytest.approx(0.0, abs=1e-6)
    assert float(loss(lambda x, t, s: jnp.zeros_like(x), c, key)) > 0.01


@pytest.mark.parametrize("method", FEW_STEP)
def test_networks_and_samples_have_the_flow_shapes(method):
    spec = methods.spec(method)
    model = methods.build_model(method, 4, jax.random.key(0))
    cond, inten = jnp.ones((3, 384)), jnp.array([0, 1, 3])
    batch = {"cond": cond, "intensity": inten, "target": jnp.zeros((3, 16))}
    assert jnp.isfinite(spec.generator.loss(model, batch, jax.random.key(1), training.TrainConfig()))
    for steps in (1, 4, 100):
        y = spec.generator.sample(model, cond, inten, jax.random.key(2), 16, SampleConfig(steps=steps))
        assert y.shape == (3, 16) and bool(jnp.isfinite(y).all())
    assert model(jnp.zeros((3, 16)), jnp.zeros(3), jnp.ones(3), cond, inten).shape == (3, 16)
    assert ModelConfig().width == model.l2.in_features  # Table I sizes


def test_the_shortcut_step_size_is_one_over_s_up_to_64_then_the_flow_field():
    assert few_step.Shortcut.second(1).tolist() == [1.0]
    assert few_step.Shortcut.second(4).tolist() == [0.25] * 4
    assert set(few_step.Shortcut.second(128).tolist()) == {0.0}
    assert few_step.MeanFlow.second(50).tolist() == pytest.approx([0.02] * 50)


@pytest.mark.parametrize("method", FEW_STEP)
def test_training_lowers_the_loss_on_a_tiny_problem(method):
    # Two conditions, one target each: the exact field exists (a point mass per condition), so the loss
    # can fall far below its value at initialization.
    k_cond, k_target, k_init = jax.random.split(jax.random.key(0), 3)
    data = {
        "cond": jax.random.normal(k_cond, (2, 384)),
        "intensity": jnp.array([0, 3]),
        "target": jax.random.uniform(k_target, (2, 16), minval=-0.8, maxval=0.8),
    }
    graphdef, params = methods.init(method, (0,))
    config = training.TrainConfig(steps=800, chunk=800)
    step = training.make_step(trainer.loss_fn(method, graphdef, data, config), 2, config)
    state = jax.vmap(lambda p: training.init_state(p, k_init, config))(params)
    _, losses = training.train(state, step, config, progress=False)
    losses = np.asarray(losses[0])
    assert losses[-100:].mean() < 0.75 * losses[:100].mean()  # MeanFlow: 0.25 -> 0.16 (its weight ~ 1 / sqrt(err))


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    out = tmp_path_factory.mktemp("ckpt") / "tuple_spline_shortcut"
    assert (
        train_cli.main(["--method", "tuple_spline_shortcut", "--steps", "20", "--chunk", "20", "--out", str(out)]) == 0
    )
    return out


def test_one_step_through_jg_sample_passes_the_gate_and_traces_once(checkpoint):
    name = str(checkpoint)
    for seed, (intent, intensity) in enumerate([("greeting", "subtle"), (4, 2), ("resting", 0)]):
        u = jg.sample(jax.random.key(seed), intent, intensity, steps=1, checkpoint=checkpoint)
        assert u.shape == (150, 4) and jg.safety.is_safe(u)
        assert np.allclose(u[0], 0.0)  # blended in from rest
    config = sampling.model(checkpoint).config(None, 1)  # the keywords' resolved config keys the program cache
    assert sampling.TRACES[(name, config, 1, "blend")] == 1
    many = jg.sample(jax.random.key(9), ["greeting", "pointing"], "moderate", num_samples=3, steps=1, checkpoint=name)
    assert many.shape == (2, 3, 150, 4) and jg.safety.is_safe(many)


def test_start_conditioned_one_step_starts_exactly_at_the_current_command(checkpoint):
    held = np.array([0.3, 0.1, 0.6, 0.0], np.float32)
    u = jg.sample(
        jax.random.key(0), "beckoning", 2, steps=1, current=held, start_conditioned=True, checkpoint=checkpoint
    )
    np.testing.assert_allclose(u[0], held, atol=1e-6)


def test_few_step_methods_are_not_table_ii_rows():
    assert set(FEW_STEP) == set(methods.FEW_STEP) and not set(FEW_STEP) & set(methods.METHODS)
    with pytest.raises(ValueError, match="tuple_spline_meanflow"):
        methods.spec("meanflow")


def test_a_sampler_the_few_step_model_lacks_is_served_by_the_default():
    key = jax.random.key(4)
    u = jg.sample(key, "greeting", "moderate", steps=2, sampler="midpoint")  # routed: the default RF
    assert u.shape == (150, 4) and jg.safety.is_safe(u)
    config = sampling.model().config("midpoint", 2)
    assert sampling.TRACES[(str(sampling.DEFAULT_CHECKPOINT), config, 1, "blend")] == 1
    assert jg.sample(key, "greeting", "moderate", steps=2).shape == (150, 4)  # the shipped few-step model


def test_noise_scale_is_the_temperature_of_the_initial_noise(monkeypatch):
    with pytest.raises(ValueError, match=r"noise_scale must be a number in \[0.1, 4.0\]"):
        SampleConfig(noise_scale=0.0)
    seen = []
    jump = few_step.jump_sample
    monkeypatch.setattr(few_step, "jump_sample", lambda net, eps, *a, **k: seen.append(eps) or jump(net, eps, *a, **k))
    model = methods.build_model("tuple_spline_meanflow", 4, jax.random.key(0))
    cond, inten, key = jnp.ones((2, 384)), jnp.array([0, 3]), jax.random.key(5)
    for scale in (1.0, 1.5):
        few_step.MeanFlow().sample(model, cond, inten, key, 16, SampleConfig(steps=2, noise_scale=scale))
    np.testing.assert_allclose(seen[1], 1.5 * seen[0], rtol=1e-6)
    np.testing.assert_allclose(seen[0], jax.random.normal(key, (2, 16)), rtol=1e-6)


def test_a_recorded_noise_scale_applies_to_its_step_counts_through_jg_sample(checkpoint, tmp_path):
    import json
    import shutil

    hot = tmp_path / "tuple_spline_shortcut"
    shutil.copytree(checkpoint, hot)
    meta = json.loads((hot / "meta.json").read_text())
    meta.setdefault("sample", {})["noise_scale"] = {"1": 1.5, "4": 1.0}
    (hot / "meta.json").write_text(json.dumps(meta))
    # a step count not listed takes the scale of the smallest listed S above it, beyond the largest the largest's
    assert [sampling.model(hot).temperature(s) for s in (1, 2, 3, 4, 50)] == [1.5, 1.0, 1.0, 1.0, 1.0]
    key, args = jax.random.key(3), (["greeting", "pointing"], "moderate")
    base = {s: jg.sample(key, *args, num_samples=4, steps=s, checkpoint=checkpoint, current=None) for s in (1, 2)}
    hotter = {s: jg.sample(key, *args, num_samples=4, steps=s, checkpoint=hot, current=None) for s in (1, 2)}
    assert not np.allclose(base[1], hotter[1]) and np.array_equal(base[2], hotter[2])
    meta["sample"]["noise_scale"] = 9.0
    bad = tmp_path / "bad" / "tuple_spline_shortcut"
    shutil.copytree(checkpoint, bad)
    (bad / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="noise_scale"):
        sampling.model(bad)
