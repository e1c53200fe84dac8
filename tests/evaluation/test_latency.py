"""The one latency measurement times the public path (tuple methods) and says what it times."""

import jax
import numpy as np
import pytest

from jgrounding.config import SampleConfig
from jgrounding.evaluation import latency
from jgrounding.generators import methods
from jgrounding.generators.trained import Trained
from jgrounding.policy import sampling


def test_latency_goes_through_the_public_sampler_once_per_setting():
    trained, emb = sampling.load()
    before = sum(sampling.TRACES.values())
    ms = latency.latency_ms(
        trained, np.arange(16), np.arange(16) % 4, jax.random.key(0), SampleConfig(steps=2), reps=20
    )
    assert np.isfinite(ms) and ms > 0
    assert latency.measures(trained) == latency.PUBLIC
    assert sum(sampling.TRACES.values()) == before + 1  # 21 public calls, one trace


def test_raw_conditioning_is_timed_through_the_core_and_says_so():
    graphdef, params = methods.init("raw_dense_cnn", (0,), 4)
    trained = Trained("raw_dense_cnn", graphdef, params, (0,), 4)
    assert latency.measures(trained) == latency.CORE
    cond = np.random.default_rng(0).normal(size=(5, 384)).astype(np.float32)
    assert latency.latency_ms(trained, None, np.arange(5) % 4, jax.random.key(0), cond=cond, reps=3) > 0
    assert latency.core_ms(trained, cond, np.arange(5) % 4, jax.random.key(0), batch=7, reps=2) > 0


def test_the_benchmarks_core_runs_on_the_runtime_jg_sample_uses():
    # bench sample's public/core ratio compares like with like: a single trajectory on XLA's classic CPU
    # runtime (as jg.sample compiles it), a batch on the default one; the same trajectories either way
    trained, emb = sampling.load()
    assert sampling.compiler_options(1) == sampling.CLASSIC_RUNTIME and sampling.compiler_options(2) is None
    config = SampleConfig(steps=2)
    for batch in (1, 3):
        cond, z = emb[np.arange(batch)], np.arange(batch, dtype=np.int32) % 4
        args = (jax.numpy.asarray(cond), jax.numpy.asarray(z), jax.random.key(1))
        aot = latency.core_fn(trained, config, example=args)
        assert isinstance(aot, jax.stages.Compiled)
        np.testing.assert_allclose(
            np.asarray(aot(*args)), np.asarray(latency.core_fn(trained, config)(*args)), atol=1e-5
        )
    assert latency.core_ms(trained, emb[:4], np.arange(4) % 4, jax.random.key(0), config, reps=3, like_public=True) > 0


def test_the_median_interval_takes_the_order_statistics_that_cover_95_percent():
    x = np.arange(10.0)[::-1]  # unsorted on purpose
    med, lo, hi = latency.median_interval(x)
    assert (med, lo, hi) == (4.5, 1.0, 8.0)  # 2nd and 9th of 10: coverage 1 - 2 * 11/1024 = 97.9 %
    assert latency.median_interval(np.arange(20.0))[1:] == (5.0, 14.0)  # 6th and 15th of 20: 95.9 %
    assert latency.median_interval([3.0, 1.0, 2.0])[1:] == (1.0, 3.0)  # too few rounds: min and max


def test_the_paired_time_test_says_faster_only_when_the_rounds_agree():
    base = np.linspace(1.0, 2.0, 10)
    c = latency.compare_ms(base * 0.9, base)
    assert c["verdict"] == "faster" and c["faster_rounds"] == 10 and c["p"] == 2 / 1024
    assert abs(c["ratio"] - 0.9) < 1e-12
    mixed = base * np.where(np.arange(10) % 2 == 0, 0.9, 1.1)  # faster in half the rounds
    assert latency.compare_ms(mixed, base)["verdict"] == "not distinguishable"
    one_off = base * np.r_[0.9, np.full(9, 1.05)]
    c = latency.compare_ms(one_off, base)
    assert c["verdict"] == "slower" and abs(c["p"] - 2 * 11 / 1024) < 1e-12
    assert latency.compare_ms(base, base)["verdict"] == "not distinguishable"  # ties left out: p = 1
    with pytest.raises(ValueError, match="equal-length"):
        latency.compare_ms(base, base[:5])


def test_interleaved_timing_runs_every_entry_in_every_round():
    import jax.numpy as jnp

    seen = []

    def entry(name, n):
        f = jax.jit(lambda x: jnp.sin(x) * n)
        return (lambda x: (seen.append(name), f(x))[1]), [(jnp.ones(64),)] * 3

    out = latency.interleaved_ms({"a": entry("a", 1.0), "b": entry("b", 2.0), "c": entry("c", 3.0)}, rounds=6)
    assert {k: v.shape for k, v in out.items()} == {"a": (6,), "b": (6,), "c": (6,)}
    assert all(np.all(v > 0) for v in out.values())
    rounds = [tuple(dict.fromkeys(seen[3 + 9 * r : 3 + 9 * (r + 1)])) for r in range(6)]  # after 3 warm-up calls
    assert all(sorted(r) == ["a", "b", "c"] for r in rounds)
    assert len(set(rounds)) > 1  # the order changes between rounds
