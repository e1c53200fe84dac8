"""The sampling benchmark's parts run: the network floor the peer report cites, and the fixed-cost breakdown."""

import re

from experiments import bench_sample
from jgrounding import load_library
from jgrounding.policy import sampling


def test_network_floor_and_fixed_cost_run_on_the_single_trajectory_programs():
    lib = load_library()
    model = sampling.model(sampling.shipped_checkpoint(2))
    assert bench_sample.network_ms(model, 2, reps=3, lib=lib) > 0
    lines = bench_sample.fixed_cost(lib, 2, reps=3)
    parts = dict(re.findall(r"^\| (.+?) \| (-?[0-9.]+) \|$", "\n".join(lines), flags=re.M))
    assert float(parts["network + spline, ungated, less dispatch"]) >= 0
    assert len(parts) == 6 and "dispatch: a compiled program of the same arguments that returns one of them" in parts


def test_the_matmul_rate_is_measured_on_the_networks_own_shapes(monkeypatch):
    """matmul_gflops counts the same FLOPs as flops_per_sample (the share it reports compares like with like)
    and returns a rate measured on this machine."""
    model = sampling.model()  # S = 50, with guidance: rows doubled
    seen = {}
    real = bench_sample.median_s

    def timed(call, reps):
        seen["s"] = real(call, reps)
        return seen["s"]

    monkeypatch.setattr(bench_sample, "median_s", timed)
    rate = bench_sample.matmul_gflops(model, steps=3, batch=8, reps=2)
    assert rate > 0
    flop = bench_sample.flops_per_sample(model, 3) * 8  # the sampler's FLOPs of 8 samples at S = 3
    assert abs(rate * 1e9 * seen["s"] - flop) / flop < 1e-9


def test_the_bfloat16_trial_halves_the_weights_and_samples_within_the_bounds():
    """experiments.bench_bf16: the trial model stores every float weight as bfloat16 (half the bytes), samples
    through the same gate, and stays close to the float32 model from the same key; its weights-as-argument program
    gives the float32 model's own network output."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from experiments import bench_bf16
    from jgrounding import safety

    ms = bench_bf16.models()
    f32, half = ms["float32"], ms["bfloat16 storage"]
    assert {x.dtype for x in jax.tree.leaves(half.trained.params) if jnp.issubdtype(x.dtype, jnp.floating)} == {
        jnp.dtype(jnp.bfloat16)
    }
    assert 1.9 < bench_bf16.weight_bytes(f32) / bench_bf16.weight_bytes(half) <= 2.0
    a = f32.sample(jax.random.key(3), "greeting", "moderate", 4)
    b = half.sample(jax.random.key(3), "greeting", "moderate", 4)
    assert safety.is_safe(b) and 0 < np.abs(a - b).max() < 0.2
    call, args = bench_bf16.weights_as_arguments(f32, jnp.float32)
    out = np.asarray(call(*args[0]))
    assert out.shape == (1, 150, 4) and np.isfinite(out).all()
