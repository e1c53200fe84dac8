"""Scale-out (issue: reliability): sharded training and evaluation equal the single-device run.

The sharded runs happen in a subprocess with four forced host devices
(``XLA_FLAGS=--xla_force_host_platform_device_count=4``), which print JSON for the asserts here.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jgrounding.config import SampleConfig
from jgrounding.evaluation import generate
from jgrounding.training import distributed, trainer

ROOT = Path(__file__).resolve().parents[2]

WORKER = r"""
import json
import jax, jax.numpy as jnp, numpy as np
import jgrounding as jg
from jgrounding import semantics, training
from jgrounding.config import SampleConfig
from jgrounding.evaluation import generate
from jgrounding.training import distributed, trainer

out = {"device_count": jax.device_count(), "initialized": distributed.initialize()}
mesh = distributed.make_mesh()
out["mesh"] = dict(mesh.shape)

# The seed axis of a compiled training chunk stays split over the mesh (8 toy seeds, 2 per device).
chunk = training.make_chunk(lambda s, _: (s + 1.0, s.sum()), 3, mesh)
states, losses = chunk(distributed.shard(jnp.arange(8.0), mesh))
out["chunk_shards"] = sorted(str(s.device) for s in states.addressable_shards)
out["chunk_shard_shape"] = list(states.addressable_shards[0].data.shape)
out["chunk_values"] = np.asarray(states).tolist()

# Training: 5 seeds (padded to 8 on 4 devices) vs the single-device vmapped run.
lib = jg.load_library()
emb = semantics.intent_embeddings()
cfg = training.TrainConfig(steps=200, chunk=100)
seen = []
single = trainer.fit("tuple_spline_rf", lib, (0, 1, 2, 3, 4), cfg, intent_emb=emb, progress=False)
sharded = trainer.fit("tuple_spline_rf", lib, (0, 1, 2, 3, 4), cfg, intent_emb=emb, progress=False, mesh=mesh,
                        on_chunk=lambda s, done: seen.append((done, int(np.shape(s.step)[0]))))
pairs = list(zip(jax.tree.leaves(single.params), jax.tree.leaves(sharded.params)))
out["param_shapes_equal"] = all(np.shape(a) == np.shape(b) for a, b in pairs)
out["param_max_diff"] = max(float(np.abs(np.asarray(a) - np.asarray(b)).max()) for a, b in pairs)
out["loss_shape"] = list(sharded.losses.shape)
out["loss_max_diff"] = float(np.abs(np.asarray(single.losses) - np.asarray(sharded.losses)).max())
out["on_chunk"] = seen

# Evaluation: 13 held-out tuples x 3 samples = 39 trajectories in batches of 12 (the last one padded);
# a batch of 10 is rounded up to 12 on 4 devices, so it draws the same noise as a batch of 12.
cond, z = emb[lib.heldout.intent[:13]], lib.heldout.intensity[:13]
u1 = generate.generate(sharded, cond, z, jax.random.key(7), num_samples=3, batch=12)
u4 = generate.generate(sharded, cond, z, jax.random.key(7), num_samples=3, batch=12, mesh=mesh)
u4r = generate.generate(sharded, cond, z, jax.random.key(7), num_samples=3, batch=10, mesh=mesh)
out["gen_shape"] = list(u4.shape)
out["gen_max_diff"] = float(np.abs(u1 - u4).max())
out["gen_rounded_max_diff"] = float(np.abs(u1 - u4r).max())
out["gen_safe"] = bool(jg.safety.is_safe(u4))
fn = generate.generate_fn(sharded, sharded.resolve(SampleConfig()), mesh)
y = fn(distributed.replicate(sharded.params, mesh), *distributed.shard((jnp.asarray(cond[:12]), jnp.asarray(z[:12])), mesh),
       distributed.replicate(jax.random.split(jax.random.key(0), 5), mesh))
out["gen_shard_shape"] = list(y.addressable_shards[0].data.shape)
out["gen_shard_devices"] = len({s.device for s in y.addressable_shards})
print("RESULT " + json.dumps(out))
"""


# Two processes with two CPU devices each, joined by jax.distributed (gloo collectives on CPU).
MULTI_HOST = r"""
import json, sys
import jax, numpy as np
import jgrounding as jg
from jgrounding import training
from jgrounding.config import SampleConfig
from jgrounding.evaluation import generate
from jgrounding.training import distributed, trainer

assert distributed.initialize()  # from JAX_COORDINATOR_ADDRESS / JAX_NUM_PROCESSES / JAX_PROCESS_ID
mesh = distributed.make_mesh()
emb = np.random.default_rng(0).normal(size=(16, 384)).astype(np.float32)
tr = trainer.fit("tuple_spline_rf", jg.load_library(), (0, 1, 2), training.TrainConfig(steps=20, chunk=10),
                   intent_emb=emb, progress=False, mesh=mesh)
u = generate.generate(tr, emb[:6], np.arange(6) % 4, jax.random.key(1), num_samples=4, batch=8, mesh=mesh, config=SampleConfig(steps=4))
np.savez(sys.argv[1], u=u, **{f"p{i}": np.asarray(x) for i, x in enumerate(jax.tree.leaves(tr.params))})
print("RESULT " + json.dumps({"process": jax.process_index(), "processes": jax.process_count(),
                              "devices": jax.device_count(), "local_devices": jax.local_device_count()}))
"""


def _env(devices: int) -> dict:
    env = {
        **os.environ,
        "JAX_PLATFORMS": "cpu",
        "XLA_FLAGS": f"--xla_force_host_platform_device_count={devices}",
        "PYTHONPATH": str(ROOT),
    }
    for name in distributed.ENV + ("SLURM_NTASKS", "OMPI_COMM_WORLD_SIZE"):
        env.pop(name, None)
    return env


def _result(stdout: str) -> dict:
    line = [x for x in stdout.splitlines() if x.startswith("RESULT ")][-1]
    return json.loads(line[len("RESULT ") :])


@pytest.fixture(scope="module")
def sharded_run():
    proc = subprocess.run(
        [sys.executable, "-c", WORKER], env=_env(4), cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return _result(proc.stdout)


def test_four_forced_host_devices_form_one_data_mesh(sharded_run):
    assert sharded_run["device_count"] == 4
    assert sharded_run["mesh"] == {"data": 4}
    assert sharded_run["initialized"] is False  # one host: initialize() is a no-op


def test_training_chunk_keeps_the_seed_axis_split(sharded_run):
    assert len(set(sharded_run["chunk_shards"])) == 4
    assert sharded_run["chunk_shard_shape"] == [2]
    np.testing.assert_array_equal(sharded_run["chunk_values"], np.arange(8.0) + 3)


def test_sharded_training_equals_single_device(sharded_run):
    assert sharded_run["param_shapes_equal"]
    assert sharded_run["param_max_diff"] < 1e-5
    assert sharded_run["loss_shape"] == [5, 200]  # the padding seeds are dropped
    assert sharded_run["loss_max_diff"] < 1e-5
    assert sharded_run["on_chunk"] == [[100, 5], [200, 5]]  # checkpoints see the unpadded seeds


def test_sharded_generation_equals_single_device(sharded_run):
    assert sharded_run["gen_shape"] == [5, 13, 3, 150, 4]
    assert sharded_run["gen_max_diff"] < 1e-5
    assert sharded_run["gen_rounded_max_diff"] < 1e-5
    assert sharded_run["gen_safe"]
    assert sharded_run["gen_shard_devices"] == 4 and sharded_run["gen_shard_shape"] == [5, 3, 150, 4]


def test_initialize_is_a_noop_on_one_host(monkeypatch):
    for name in distributed.ENV + ("SLURM_NTASKS", "OMPI_COMM_WORLD_SIZE"):
        monkeypatch.delenv(name, raising=False)
    assert distributed.initialize() is False
    monkeypatch.setenv("JAX_NUM_PROCESSES", "1")
    assert distributed.initialize() is False


@pytest.mark.parametrize(
    "env, match",
    [
        ({"JAX_COORDINATOR_ADDRESS": "10.0.0.1:1234"}, "JAX_NUM_PROCESSES, JAX_PROCESS_ID"),
        ({"JAX_COORDINATOR_ADDRESS": "10.0.0.1:1234", "JAX_NUM_PROCESSES": "two"}, "must be an integer"),
        (
            {"JAX_COORDINATOR_ADDRESS": "10.0.0.1:1234", "JAX_NUM_PROCESSES": "2", "JAX_PROCESS_ID": "2"},
            "0..JAX_NUM_PROCESSES-1",
        ),
    ],
)
def test_initialize_names_what_a_multi_host_job_needs(monkeypatch, env, match):
    for name in distributed.ENV + ("SLURM_NTASKS", "OMPI_COMM_WORLD_SIZE"):
        monkeypatch.delenv(name, raising=False)
    for k, v in env.items():
        monkeypatch.setenv(k, v)
    with pytest.raises(ValueError, match=match):
        distributed.initialize()


@pytest.mark.parametrize("bad", [0, -1, 99, True, 1.5, "all"])
def test_make_mesh_rejects_bad_device_counts(bad):
    with pytest.raises(ValueError, match="num_devices must be an integer in 1.."):
        distributed.make_mesh(bad)


def test_shard_needs_a_multiple_of_the_device_count():
    mesh = distributed.make_mesh(1)
    assert distributed.gather(distributed.shard(np.arange(3.0), mesh)).tolist() == [0.0, 1.0, 2.0]
    with pytest.raises(ValueError, match="multiple of the 1 devices"):
        distributed.shard(np.float32(1.0), mesh)
    padded = distributed.pad_leading({"a": np.arange(5.0)}, 4)
    assert padded["a"].tolist() == [0, 1, 2, 3, 4, 0, 0, 0]
    assert distributed.take_leading(padded, 5)["a"].tolist() == [0, 1, 2, 3, 4]


@pytest.mark.slow
def test_multi_host_job_equals_one_process(tmp_path):
    import socket

    import jax

    import jgrounding as jg
    from jgrounding import training

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    procs = []
    for pid in range(2):
        env = {
            **_env(2),
            "JAX_COORDINATOR_ADDRESS": f"127.0.0.1:{port}",
            "JAX_NUM_PROCESSES": "2",
            "JAX_PROCESS_ID": str(pid),
        }
        procs.append(
            subprocess.Popen(
                [sys.executable, "-c", MULTI_HOST, str(tmp_path / f"p{pid}.npz")],
                env=env,
                cwd=ROOT,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
        )
    outs = [p.communicate(timeout=240) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err[-3000:]
    results = [_result(out) for out, _ in outs]
    assert [r["process"] for r in results] == [0, 1]
    assert all(r["processes"] == 2 and r["devices"] == 4 and r["local_devices"] == 2 for r in results)

    emb = np.random.default_rng(0).normal(size=(16, 384)).astype(np.float32)
    tr = trainer.fit(
        "tuple_spline_rf",
        jg.load_library(),
        (0, 1, 2),
        training.TrainConfig(steps=20, chunk=10),
        intent_emb=emb,
        progress=False,
    )
    u = generate.generate(
        tr, emb[:6], np.arange(6) % 4, jax.random.key(1), num_samples=4, batch=8, config=SampleConfig(steps=4)
    )
    params = [np.asarray(x) for x in jax.tree.leaves(tr.params)]
    for pid in range(2):
        got = np.load(tmp_path / f"p{pid}.npz")
        assert got["u"].shape == (3, 6, 4, 150, 4)
        np.testing.assert_allclose(got["u"], u, atol=1e-5)
        for i, p in enumerate(params):
            np.testing.assert_allclose(got[f"p{i}"], p, atol=1e-5)
