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
