"""Scale-out on JAX's own distribution: one 1-D device mesh, data-parallel over samples and seeds.

Nothing here is a second implementation of training or sampling. :func:`jgrounding.evaluation.generate.generate` and
:func:`jgrounding.training.trainer.fit` (through :func:`training.train`) take ``mesh=``; with a mesh

- evaluation shards the flattened (condition x sample) batch over the mesh axis ``"data"`` (the
  parameters are replicated), and
- training shards the vmapped seed axis of the training states over ``"data"``; a seed count that
  is not a multiple of the device count is padded with copies of the first seed's state, whose
  results are dropped.

Random draws use JAX's partitionable threefry (the default since jax 0.5), so a sharded run draws
the same noise as a single-device run and agrees with it to float rounding.

Multi-host: call :func:`initialize` first in every process (it wraps ``jax.distributed.initialize``
and does nothing on one host); :func:`make_mesh` then spans the devices of all hosts, host values
enter the mesh with :func:`shard` / :func:`replicate` (the same value on every process, as JAX
requires) and results come back to every process with :func:`gather`. See ``docs/distributed.md``.
"""

from __future__ import annotations

import os

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import AxisType, Mesh, NamedSharding, PartitionSpec

AXIS = "data"  # the one mesh axis: batch elements (evaluation) or seeds (training)
ENV = ("JAX_COORDINATOR_ADDRESS", "JAX_NUM_PROCESSES", "JAX_PROCESS_ID")


def _env_int(name: str) -> int | None:
    text = os.environ.get(name)
    if text is None or text == "":
        return None
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"environment variable {name} must be an integer, got {text!r}") from None


def _launcher() -> str | None:
    """A cluster launcher that ``jax.distributed.initialize`` detects by itself (SLURM, Open MPI)."""
    if int(os.environ.get("SLURM_NTASKS", "1") or 1) > 1:
        return "SLURM"
    if int(os.environ.get("OMPI_COMM_WORLD_SIZE", "1") or 1) > 1:
        return "Open MPI"
    return None


def initialize(
    coordinator_address: str | None = None,
    num_processes: int | None = None,
    process_id: int | None = None,
    local_device_ids=None,
) -> bool:
    """Join a multi-host job through ``jax.distributed.initialize``; a no-op on a single host.

    Arguments override the environment variables ``JAX_COORDINATOR_ADDRESS`` (``host:port`` of
    process 0), ``JAX_NUM_PROCESSES`` and ``JAX_PROCESS_ID``; under a SLURM or Open MPI launch with
    more than one task JAX finds all three itself. Returns True when the job is (now) distributed,
    False when there is nothing to join (one process). Call it before any other JAX computation.
    """
    if jax.distributed.is_initialized():
        return True
    address = coordinator_address or os.environ.get("JAX_COORDINATOR_ADDRESS") or None
    count = num_processes if num_processes is not None else _env_int("JAX_NUM_PROCESSES")
    pid = process_id if process_id is not None else _env_int("JAX_PROCESS_ID")
    launcher = _launcher()
    if address is None and count is None and pid is None and launcher is None:
        return False  # one host: nothing to join
    if count == 1 and launcher is None:
        return False
    if launcher is None and None in (address, count, pid):
        missing = [n for n, v in zip(ENV, (address, count, pid)) if v is None]
        raise ValueError(
            f"a multi-host job needs {', '.join(ENV)} (or the matching arguments of "
            f"initialize(), or a SLURM / Open MPI launch); missing: {', '.join(missing)}"
        )
    if count is not None and (count < 1 or pid is None or not 0 <= pid < count):
        raise ValueError(f"JAX_PROCESS_ID must be in 0..JAX_NUM_PROCESSES-1, got process {pid} of {count}")
    jax.distributed.initialize(address, count, pid, local_device_ids)
    return True


def make_mesh(num_devices: int | None = None) -> Mesh:
    """A 1-D mesh with axis ``"data"`` over all devices of all processes (or the first ``num_devices``)."""
    devices = jax.devices()
    n = len(devices) if num_devices is None else num_devices
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= len(devices):
        raise ValueError(f"num_devices must be an integer in 1..{len(devices)} (the devices JAX sees), got {n!r}")
    if n != len(devices) and jax.process_count() > 1:
        raise ValueError(f"a multi-host mesh must span all {len(devices)} devices, got num_devices={n}")
    # Auto axes, named: jax >= 0.7 makes Explicit axes the default of jax.make_mesh, under which a gather over
    # seed-split indices (the training batch's rows) must state its output sharding; jgrounding's programs let
    # the compiler choose, as jax 0.6 did. Both stacks accept the keyword (docs/versions.md).
    return jax.make_mesh((int(n),), (AXIS,), devices=devices[:n], axis_types=(AxisType.Auto,))


def sharding(mesh: Mesh, *spec) -> NamedSharding:
    """``NamedSharding(mesh, PartitionSpec(*spec))``; no spec = replicated, ``(AXIS,)`` = split axis 0."""
    return NamedSharding(mesh, PartitionSpec(*spec))


def _is_key(x) -> bool:
    return isinstance(x, jax.Array) and jnp.issubdtype(x.dtype, jax.dtypes.prng_key)


def _put(x, s: NamedSharding):
    if _is_key(x):  # typed keys travel as their uint32 data
        return jax.random.wrap_key_data(_put(jax.random.key_data(x), s), impl=jax.random.key_impl(x))
    if isinstance(x, jax.Array) and x.is_fully_addressable:
        x = np.asarray(x)  # a host value: device_put checks it is the same on every process
    return jax.device_put(x, s)


def shard(tree, mesh: Mesh):
    """Put every leaf of ``tree`` on ``mesh`` split along its leading axis (a multiple of the mesh size)."""
    for x in jax.tree_util.tree_leaves(tree):
        if np.ndim(x) == 0 or np.shape(x)[0] % mesh.size:
            raise ValueError(
                f"a sharded leading axis must be a multiple of the {mesh.size} devices, got shape {np.shape(x)}"
            )
    s = sharding(mesh, AXIS)
    return jax.tree.map(lambda x: _put(x, s), tree)


def replicate(tree, mesh: Mesh):
    """Put a full copy of every leaf of ``tree`` on every device of ``mesh``."""
    s = sharding(mesh)
    return jax.tree.map(lambda x: _put(x, s), tree)


def gather(tree):
    """Global arrays -> the full values on this process (numpy; typed keys stay typed jax keys)."""

    def one(x):
        if _is_key(x):
            return jax.random.wrap_key_data(jnp.asarray(one(jax.random.key_data(x))), impl=jax.random.key_impl(x))
        if isinstance(x, jax.Array) and not x.is_fully_addressable:
            from jax.experimental import multihost_utils

            return np.asarray(multihost_utils.process_allgather(x, tiled=True))
        return np.asarray(x)

    return jax.tree.map(one, tree)


def pad_leading(tree, multiple: int):
    """Pad the leading axis of every leaf to a multiple of ``multiple`` with copies of element 0."""
    n = int(np.shape(jax.tree_util.tree_leaves(tree)[0])[0])
    pad = -n % multiple
    if pad == 0:
        return tree
    return jax.tree.map(lambda x: jnp.concatenate([x, jnp.repeat(x[:1], pad, axis=0)]), tree)


def take_leading(tree, n: int):
    """The first ``n`` entries of the leading axis of every leaf (undoes :func:`pad_leading`)."""
    return jax.tree.map(lambda x: x[:n], tree)
