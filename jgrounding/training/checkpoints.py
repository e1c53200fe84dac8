"""The one checkpoint writer: orbax PyTree checkpoints with integrity metadata, written atomically.

Layout of a checkpoint directory::

    <dir>/params/        orbax PyTreeCheckpointer of the parameters (and optimizer state when resuming)
    <dir>/meta.json      method, seeds, P, config, vocabulary, library sha256, package version, step,
                         params_sha256 (a digest of every stored array: catches bit rot and edits)

A checkpoint is first written to ``<dir>.tmp-<pid>`` and then renamed into place, so a reader never
sees half a checkpoint. Replacing an existing one moves it aside to ``<dir>.old-<pid>`` first; a
writer killed between the two renames leaves that complete copy, which :func:`restore` puts back, and
the next :func:`save` clears what dead writers left. :func:`restore` refuses (``ValueError`` naming
the file) a checkpoint whose metadata does not match what the caller expects (vocabulary included),
whose arrays do not match their digest or have the wrong shapes, or whose parameters contain NaN/Inf.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import jax
import numpy as np
import orbax.checkpoint as ocp

from jgrounding.vocabulary import INTENSITIES, INTENTS

FORMAT_VERSION = 1


def _version() -> str:
    from jgrounding import __version__

    return __version__


def save(directory: str | Path, tree, meta: dict) -> Path:
    """Atomically write ``tree`` (a pytree of arrays) and ``meta`` to ``directory``."""
    directory = Path(directory).resolve()
    tmp = directory.with_name(f"{directory.name}.tmp-{os.getpid()}")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    # Leaves are stored by their flatten order, so any pytree (nnx State, optax states, typed keys as
    # key_data) restores exactly into the caller's target structure.
    leaves = [np.asarray(x) for x in jax.tree_util.tree_leaves(jax.device_get(tree))]
    ocp.PyTreeCheckpointer().save(tmp / "params", {f"{i:05d}": x for i, x in enumerate(leaves)})
    full = {
        "format_version": FORMAT_VERSION,
        "intents": list(INTENTS),
        "intensities": list(INTENSITIES),
        "package_version": _version(),
        **meta,
        "params_sha256": _digest(leaves),
    }
    (tmp / "meta.json").write_text(json.dumps(full, indent=1, sort_keys=True, default=str))
    old = directory.with_name(f"{directory.name}.old-{os.getpid()}")
    if directory.exists():
        directory.rename(old)
    tmp.rename(directory)
    if old.exists():
        shutil.rmtree(old)
    for stale in _leftovers(directory):  # half-written copies of writers that were killed
        shutil.rmtree(stale, ignore_errors=True)
    return directory


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _leftovers(directory: Path, kinds=("tmp", "old")) -> list[Path]:
    """``<dir>.tmp-<pid>`` / ``<dir>.old-<pid>`` siblings left by writers that no longer run."""
    out = []
    for kind in kinds:
        for p in directory.parent.glob(f"{directory.name}.{kind}-*"):
            pid = p.name.rsplit("-", 1)[1]
            if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
                out.append(p)
    return out


def _recover(directory: Path) -> None:
    """Put back the previous checkpoint when a writer was killed between moving it aside and renaming."""
    if directory.exists():
        return
    old = [p for p in _leftovers(directory, ("old",)) if (p / "meta.json").exists() and (p / "params").exists()]
    if old:
        max(old, key=lambda p: p.stat().st_mtime).rename(directory)


def _digest(arrays) -> str:
    """sha256 over the dtype, shape and bytes of each array, in order."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def read_meta(directory: str | Path) -> dict:
    path = Path(directory) / "meta.json"
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise ValueError(f"checkpoint metadata {path} is missing or unreadable: {e}")


def restore(directory: str | Path, target, expect: dict | None = None):
    """Load (tree, meta) from ``directory`` into the structure and shapes of ``target`` (a pytree)."""
    directory = Path(directory)
    _recover(directory)
    if not (directory / "params").exists():
        raise FileNotFoundError(f"no checkpoint at {directory} (expected {directory / 'params'})")
    meta = read_meta(directory)
    if meta.get("format_version") != FORMAT_VERSION:
        raise ValueError(
            f"checkpoint {directory} has format_version {meta.get('format_version')}, expected {FORMAT_VERSION}"
        )
    intents, intensities = tuple(meta.get("intents", ())), tuple(meta.get("intensities", ()))
    if intents != INTENTS or intensities != INTENSITIES:
        raise ValueError(
            f"checkpoint {directory} was trained for another vocabulary ({len(intents)} intents, "
            f"{len(intensities)} intensities; this package has {len(INTENTS)} intents "
            f"{', '.join(INTENTS)} and {len(INTENSITIES)} intensities {', '.join(INTENSITIES)})"
        )
    for key, value in (expect or {}).items():
        if meta.get(key) != value:
            raise ValueError(f"checkpoint {directory}: {key} is {meta.get(key)!r}, expected {value!r}")
    try:
        stored = ocp.PyTreeCheckpointer().restore((directory / "params").resolve())
    except Exception as e:  # orbax raises many kinds on corruption
        raise ValueError(f"checkpoint {directory} could not be read ({type(e).__name__}: {e})")
    flat_t, treedef = jax.tree_util.tree_flatten(target)
    flat = [np.asarray(stored[k]) for k in sorted(stored)]
    if "params_sha256" in meta and _digest(flat) != meta["params_sha256"]:
        raise ValueError(
            f"checkpoint {directory} is corrupt: its arrays do not match params_sha256 in "
            f"{directory / 'meta.json'}; refusing to load it"
        )
    if len(flat) != len(flat_t):
        raise ValueError(f"checkpoint {directory} holds {len(flat)} arrays, expected {len(flat_t)}")
    # a target leaf is an array or a jax.ShapeDtypeStruct (methods.abstract)
    flat_t = [b if hasattr(b, "shape") and hasattr(b, "dtype") else np.asarray(b) for b in flat_t]
    for a, b in zip(flat, flat_t):
        if np.shape(a) != tuple(b.shape):
            raise ValueError(
                f"checkpoint {directory} has an array of shape {np.shape(a)} where {tuple(b.shape)} is expected"
            )
    tree = jax.tree_util.tree_unflatten(treedef, [np.asarray(a, dtype=b.dtype) for a, b in zip(flat, flat_t)])
    if not all(
        np.all(np.isfinite(np.asarray(x)))
        for x in jax.tree_util.tree_leaves(tree)
        if np.issubdtype(np.asarray(x).dtype, np.floating)
    ):
        raise ValueError(f"checkpoint {directory} contains NaN or Inf parameters; refusing to load it")
    return tree, meta
