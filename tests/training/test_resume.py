"""Kill-and-resume (issue: reliability): a training process SIGKILLed mid-run resumes from its last
chunk checkpoint and ends with parameters identical to an uninterrupted run."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from jgrounding.generators import methods
from jgrounding.training import checkpoints, distributed

ROOT = Path(__file__).resolve().parents[2]
STEPS, CHUNK = 1000, 100


def _command(out: Path) -> list[str]:
    return [
        sys.executable,
        "-m",
        "experiments.train",
        "--method",
        "tuple_spline_rf",
        "--steps",
        str(STEPS),
        "--chunk",
        str(CHUNK),
        "--seeds",
        "0,1",
        "--out",
        str(out),
    ]


def _env() -> dict:
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "PYTHONPATH": str(ROOT)}
    for name in distributed.ENV + ("SLURM_NTASKS", "OMPI_COMM_WORLD_SIZE", "XLA_FLAGS"):
        env.pop(name, None)
    return env


def _final_params(out: Path):
    _, template = methods.init("tuple_spline_rf", (0,), 4)
    params, meta = checkpoints.restore(out, template, expect={"method": "tuple_spline_rf", "step": STEPS})
    assert meta["run_config"]["train"]["steps"] == STEPS and meta["run_config"]["train"]["chunk"] == CHUNK
    return [np.asarray(x) for x in __import__("jax").tree.leaves(params)]


@pytest.mark.slow
def test_sigkilled_training_resumes_to_identical_parameters(tmp_path):
    killed_out, full_out = tmp_path / "killed", tmp_path / "full"
    full = subprocess.Popen(
        _command(full_out), env=_env(), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    victim = subprocess.Popen(
        _command(killed_out), env=_env(), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    run_meta = Path(str(killed_out) + ".run") / "meta.json"
    deadline = time.monotonic() + 120
    while not run_meta.exists() and victim.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.3)  # a few chunks in: the kill lands inside a chunk or inside a checkpoint write
    assert victim.poll() is None, "the training run finished before it could be killed"
    os.kill(victim.pid, signal.SIGKILL)
    victim.wait()
    assert victim.returncode == -signal.SIGKILL
    assert not killed_out.exists()  # the final checkpoint was never written

    resumed = subprocess.run(_command(killed_out), env=_env(), cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stdout[-2000:] + resumed.stderr[-2000:]
    line = next(x for x in resumed.stdout.splitlines() if x.startswith("resuming"))
    step = int(line.rsplit(" ", 1)[1])
    assert 0 < step < STEPS and step % CHUNK == 0
    out, _ = full.communicate(timeout=300)
    assert full.returncode == 0, out[-2000:]
    assert "resuming" not in out

    for a, b in zip(_final_params(killed_out), _final_params(full_out), strict=True):
        np.testing.assert_array_equal(a, b)
    leftovers = [p.name for p in tmp_path.iterdir() if p.name not in ("killed", "full")]
    assert leftovers == []  # no run state, half-written or moved-aside checkpoint left behind
