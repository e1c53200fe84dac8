"""The one latency measurement times the public path (tuple methods) and says what it times."""

import jax
import numpy as np

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
