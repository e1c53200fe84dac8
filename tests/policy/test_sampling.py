"""The public sampler's fast path (issue #14): batched tuples, determinism, bucket independence, errors
and no re-tracing."""

import dataclasses

import jax
import numpy as np
import pytest

import jgrounding as jg
from jgrounding import safety, sim
from jgrounding.config import SampleConfig
from jgrounding.policy import sampling
from jgrounding.training import checkpoints


def test_sequences_of_tuples_give_n_k_trajectories():
    key = jax.random.key(4)
    U = jg.sample(key, ["greeting", 9, "coiling"], ["subtle", "moderate", 3], num_samples=5, steps=4)
    assert U.shape == (3, 5, 150, 4) and U.dtype == np.float32 and safety.is_safe(U)
    np.testing.assert_array_equal(
        U, jg.sample(key, ["greeting", 9, "coiling"], ["subtle", "moderate", 3], num_samples=5, steps=4)
    )
    assert not np.array_equal(
        U, jg.sample(jax.random.key(5), ["greeting", 9, "coiling"], ["subtle", "moderate", 3], num_samples=5, steps=4)
    )
    # the first tuple's samples are those of the single-tuple call with the same key
    np.testing.assert_allclose(U[0], jg.sample(key, "greeting", "subtle", num_samples=5, steps=4), atol=1e-5)


def test_a_single_value_is_repeated_against_a_sequence():
    key = jax.random.key(0)
    a = jg.sample(key, np.arange(4), "emphatic", num_samples=2, steps=2)
    b = jg.sample(key, [0, 1, 2, 3], ["emphatic"] * 4, num_samples=2, steps=2)
    assert a.shape == (4, 2, 150, 4)
    np.testing.assert_array_equal(a, b)


def test_samples_do_not_depend_on_the_batch_bucket_or_chunking():
    key = jax.random.key(7)
    big = jg.sample(key, "nodding", "pronounced", num_samples=700, steps=2)  # chunks of 640 + 60
    assert big.shape == (700, 150, 4) and safety.is_safe(big)
    np.testing.assert_allclose(big[:3], jg.sample(key, "nodding", "pronounced", num_samples=3, steps=2), atol=1e-5)
    np.testing.assert_allclose(big[0], jg.sample(key, "nodding", "pronounced", steps=2), atol=1e-5)
    assert len({float(np.abs(big[i] - big[0]).max()) for i in (1, 640, 699)}) == 3  # rows differ


@pytest.mark.parametrize(
    "intents, intensities, exc, match",
    [
        (["greeting", "dance"], ["subtle", "subtle"], ValueError, "unknown intent 'dance'; valid intents: greeting"),
        (["greeting"], ["subtle", "loud"], ValueError, "same length"),
        ([0, 1], ["subtle", "extreme"], ValueError, "valid intensit.*: subtle"),
        ([], [], ValueError, "at least one tuple"),
        ({"a": 1}, "subtle", ValueError, "valid: greeting"),
        ([], [], ValueError, "valid intents: greeting"),
        ([[0, 1]], "subtle", ValueError, "greeting"),
        ([16], "subtle", ValueError, "out of range 0..15"),
    ],
)
def test_sequences_are_validated_with_the_vocabulary_messages(intents, intensities, exc, match):
    with pytest.raises(exc, match=match):
        jg.sample(jax.random.key(0), intents, intensities)


def test_too_many_trajectories_per_call_are_refused():
    with pytest.raises(ValueError, match="at most"):
        jg.sample(jax.random.key(0), list(range(16)) * 8, "subtle", num_samples=sampling.MAX_SAMPLES)


def test_repeated_public_calls_trace_once_per_sampler_steps_bucket():
    name = str(sampling.DEFAULT_CHECKPOINT)
    sampler, steps = "midpoint", 3
    for seed, (intent, intensity, k) in enumerate(
        [("greeting", "subtle", 1), (4, 2, 1), ("resting", 0, 1), ("pointing", 1, 5), (0, 3, 7), ([1, 2], 0, 3)]
    ):
        jg.sample(jax.random.key(seed), intent, intensity, num_samples=k, sampler=sampler, steps=steps)
        jg.sample(jax.random.PRNGKey(seed), intent, intensity, num_samples=k, sampler=sampler, steps=steps)
    config = sampling.model().config(sampler, steps)  # the cache key: the resolved config, the bucket, the start
    assert config == SampleConfig(sampler, steps, config.guidance, config.noise_scale)
    assert sampling.TRACES[(name, config, 1, "blend")] == 1
    assert sampling.TRACES[(name, config, 8, "blend")] == 1  # 5, 7 and 2 x 3 share the bucket of 8
    assert sampling.TRACES[(name, config, 2, "blend")] == 0


def test_equal_configs_share_one_program_and_do_not_trace_again():
    name = str(sampling.DEFAULT_CHECKPOINT)
    before = sum(sampling.TRACES.values())
    first = jg.sample(jax.random.key(1), "nodding", "subtle", config=SampleConfig(steps=50, guidance=0.25))
    again = jg.sample(jax.random.key(1), "nodding", "subtle", config=SampleConfig(steps=50, guidance=0.25))
    np.testing.assert_array_equal(first, again)
    assert sum(sampling.TRACES.values()) == before + 1  # one trace for two calls with equal configs
    resolved = SampleConfig("euler", 50, 0.25, 1.0)  # sampler None resolved to the generator's default
    assert sampling.TRACES[(name, resolved, 1, "blend")] == 1
    # the same settings spelled out are the same program
    jg.sample(jax.random.key(2), "nodding", "subtle", config=resolved)
    assert sum(sampling.TRACES.values()) == before + 1


def test_a_config_is_used_as_given_and_the_keywords_take_the_recorded_settings():
    key = jax.random.key(6)
    recorded = sampling.default_config(steps=4)
    assert recorded == sampling.model(sampling.shipped_checkpoint(4)).config(None, 4)  # the model serving S = 4
    np.testing.assert_array_equal(jg.sample(key, 3, 1, steps=4), jg.sample(key, 3, 1, config=recorded))
    hotter = dataclasses.replace(recorded, noise_scale=recorded.noise_scale + 0.5)
    assert not np.allclose(jg.sample(key, 3, 1, config=recorded), jg.sample(key, 3, 1, config=hotter))


@pytest.mark.parametrize(
    "kwargs, exc, match",
    [
        ({"steps": 8}, ValueError, "not both"),
        ({"sampler": "euler"}, ValueError, r"dataclasses.replace\(config, sampler='euler'\)"),
    ],
)
def test_keywords_that_would_conflict_with_config_are_refused(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        jg.sample(jax.random.key(0), "greeting", "subtle", config=SampleConfig(steps=4), **kwargs)


@pytest.mark.parametrize(
    "config, exc, match",
    [
        ({"steps": 4}, TypeError, "config must be a jgrounding.config.SampleConfig"),
        (SampleConfig(sampler="ddim"), ValueError, "unknown sampler 'ddim' for tuple_spline_rf; valid: euler"),
        (SampleConfig(steps=5000), ValueError, r"steps must be an integer in 1\.\.1000"),
    ],
)
def test_a_bad_config_is_refused_at_the_boundary_naming_the_valid_choices(config, exc, match):
    with pytest.raises(exc, match=match):
        jg.sample(jax.random.key(0), "greeting", "subtle", config=config)
    with pytest.raises(exc, match=match):
        sampling.screened(jax.random.key(0), "greeting", "subtle", config=config)


@pytest.mark.slow
def test_fuzzed_public_calls_are_all_safe():
    from experiments import bench_fuzz

    counts = bench_fuzz.fuzz(seed=1, trajectories=20_000)  # `python -m experiments.bench fuzz`: >= 1,000,000
    assert counts["bad"] == 0 and counts["trajectories"] >= 20_000 and len(counts["configs"]) >= 4


def test_sample_blends_in_from_the_current_command_and_a_stream_never_jumps():
    key = jax.random.key(3)
    raw = jg.sample(key, "beckoning", "emphatic", current=None)  # the model's own first step
    assert jg.sample(key, "beckoning", "emphatic")[0] == pytest.approx(np.zeros(4))  # default: from rest
    held = np.array([0.3, 0.1, 0.6, 0.0], np.float32)
    u = jg.sample(key, "beckoning", "emphatic", num_samples=4, current=held)
    assert jg.safety.is_safe(u, current=held) and np.allclose(u[:, 0], held)
    np.testing.assert_allclose(u[0, jg.safety.BLEND_STEPS :], raw[jg.safety.BLEND_STEPS :], atol=1e-5)
    # a stream of consecutive responses, each from where the last left the robot, never exceeds the bound
    stream, current = [np.zeros((1, 4), np.float32)], "rest"
    for turn, (m, z) in enumerate(
        [("greeting", 3), ("refusing", 3), ("coiling", 0), ("celebrating", 3), ("withdrawal", 2), ("embracing", 3)]
    ):
        out = jg.sample(jax.random.key(turn), m, z, current=current)
        stream.append(out)
        current = out[-1]
    assert np.abs(np.diff(np.concatenate(stream), axis=0)).max() <= jg.safety.MAX_SLEW + 1e-6
    with pytest.raises(ValueError, match="rest"):
        jg.sample(key, "beckoning", "emphatic", current="home")


@pytest.mark.slow
def test_screened_samples_all_pass_the_simulator_and_the_rejections_are_counted():

    res = sampling.screened(jax.random.key(0), ["nodding", "comforting"], "emphatic", num_samples=6)
    assert res.u.shape == (2, 6, 150, 4) and res.candidates >= 12 and 0 <= res.rejected <= res.candidates - 12
    assert sim.feasible(sim.rollout(res.u.reshape(-1, 150, 4))).all()
    u = jg.sample(jax.random.key(0), "nodding", "emphatic", num_samples=3, screen=True)
    assert u.shape == (3, 150, 4) and sim.feasible(sim.rollout(u)).all()


def test_screening_that_cannot_pass_raises_a_clear_error(monkeypatch):
    monkeypatch.setattr(sim, "margins", lambda u, engine="auto", trunk=None: -np.ones(len(u)))  # nothing is feasible
    with pytest.raises(sampling.ScreeningError, match="budget of 8 candidates"):
        sampling.screened(jax.random.key(0), "nodding", "emphatic", num_samples=2, budget=8)


def test_loading_a_checkpoint_names_the_shipped_library_without_importing_it():
    from jgrounding import library

    assert checkpoints.DEFAULT_LIBRARY == library.DEFAULT_PATH


def test_precomputed_tuple_contexts_give_the_same_samples():
    # jg.sample gathers every tuple's first-layer context from a table computed once (Trained.contexts) instead
    # of running the condition layer on every call; the samples must be what the condition gives

    for steps in (50, 2):  # the shipped RF and the few-step model
        model = sampling.model(sampling.shipped_checkpoint(steps))
        tr, table = model.trained, model._contexts
        assert table is not None and table.shape[0] == 64
        m, z = np.array([0, 5, 15]), np.array([3, 1, 0])
        config = model.config(None, steps)
        key = jax.random.key(4)
        direct = tr.actuation(key, model.intent_emb[m], z, config)
        gathered = tr.actuation(key, None, z, config, context=table[m * 4 + z])
        np.testing.assert_allclose(np.asarray(gathered), np.asarray(direct), atol=1e-5)
    assert tr.contexts(model.intent_emb).shape == table.shape
    regressor = sampling.Model(
        dataclasses.replace(tr, method="tuple_spline_cnn"), model.intent_emb
    )  # a regressor takes no context
    assert regressor._contexts is None
