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

import dataclasses
import functools
import hashlib
import json
import os
import shutil
from pathlib import Path

import jax
import numpy as np
import orbax.checkpoint as ocp

from jgrounding import io
from jgrounding.config import SampleConfig, model_config
from jgrounding.generators import methods
from jgrounding.generators.trained import Trained
from jgrounding.vocabulary import INTENSITIES, INTENTS, intensity_index, intent_index

# = jgrounding.library.DEFAULT_PATH, named here so that loading a checkpoint does not import the library
# package (and the physics it screens with): jg.sample's first call stays short.
DEFAULT_LIBRARY = io.asset("library.npz")

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
    """The parsed ``meta.json`` of a checkpoint (a fresh dict). The file is read once per version: the text is
    cached by its path, size and modification time, so loading a model does not read it again."""
    path = Path(directory) / "meta.json"
    try:
        st = path.stat()
        return json.loads(_meta_text(str(path.resolve()), st.st_mtime_ns, st.st_size))
    except (OSError, ValueError) as e:
        raise ValueError(f"checkpoint metadata {path} is missing or unreadable: {e}")


@functools.lru_cache(maxsize=64)
def _meta_text(path: str, mtime_ns: int, size: int) -> str:
    del mtime_ns, size  # cache keys: a rewritten file is read again
    return Path(path).read_text()


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
    # a target leaf is an array or a jax.ShapeDtypeStruct (methods.init(..., abstract=True))
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


# --- Trained models: what a checkpoint records of one, and the one restore with the one library rule --------


def meta_of(trained: Trained) -> dict:
    """What every checkpoint of a :class:`Trained` records so that :func:`restore_trained` rebuilds it: method,
    seeds, sizes, its sampling defaults and the library it was trained on (version, and the file's sha256
    when the model knows the file)."""
    meta = {
        "method": trained.method,
        "seeds": list(trained.seeds),
        "num_controls": trained.num_controls,
        "num_tendons": trained.num_tendons,
        "model": dataclasses.asdict(trained.model),
        "sample": dataclasses.asdict(trained.sample_config),
    }
    if trained.noise_scales:
        meta["sample"]["noise_scale"] = {str(k): v for k, v in sorted(trained.noise_scales.items())}
    lib = trained.library or {}
    if lib.get("version"):
        meta["library_version"] = lib["version"]
    if lib.get("path") and Path(lib["path"]).is_file():
        meta["library_sha256"] = io.sha256_file(lib["path"])
    if lib.get("trunk"):  # the trunk its library was screened on (path, sha256): jg.sample(screen=True) compares
        meta["trunk"] = lib["trunk"]
    return meta


def library_mismatch(path, meta: dict) -> str | None:
    """Why checkpoint ``path`` (its ``meta``) does not belong to the library it would be used with, or ``None``.

    The one rule: the library is the file the checkpoint recorded (``library_path``, when that file exists) or
    else the shipped ``jgrounding/assets/library.npz``; its sha256 must be the one recorded. A checkpoint that recorded
    no library sha256 is not judged. :func:`restore_trained` refuses a mismatch unless
    ``allow_library_mismatch``."""
    digest = meta.get("library_sha256")
    lib_path = Path(meta.get("library_path") or DEFAULT_LIBRARY)
    if not digest or not lib_path.is_file():
        return None
    now = io.sha256_file(lib_path)
    if now == digest:
        return None
    try:
        current = json.loads(lib_path.with_suffix(".json").read_text()).get("library_version", "1 (unversioned)")
    except (OSError, ValueError):
        current = "unknown"
    retrain = f"--library {lib_path} " if meta.get("library_path") else ""
    was = meta.get("library_version", "1 (unversioned)")
    now_is = f"is library version {current}" if current != was else "has changed since (same version name)"
    return (
        f"checkpoint {path} was trained on library version {was} (sha256 {digest[:12]}...), but {lib_path} "
        f"{now_is} (sha256 {now[:12]}...); retrain it (python -m experiments.train {retrain}--out {path}) or pass "
        "allow_library_mismatch=True (--allow-library-mismatch) to use it anyway"
    )


def trained_tuples(meta: dict) -> tuple[tuple[int, int], ...] | None:
    """The (intent, intensity) tuples a checkpoint's library holds (``None``: all 64, or not recorded)."""
    tuples = meta.get("tuples")
    if not tuples:
        return None
    return tuple((intent_index(t.split("/")[0]), intensity_index(t.split("/")[1])) for t in tuples)


def restore_trained(path, method: str | None = None, *, allow_library_mismatch: bool = False) -> Trained:
    """A :class:`Trained` (every seed it holds, its sampling defaults and library identity) from a checkpoint
    directory written by the ablation, ``experiments.train`` or ``experiments.ship``; ``method`` (optional)
    must match. ``ValueError`` naming the directory for an unknown method, P, N_u or model sizes, a checkpoint
    trained on another library (:func:`library_mismatch`; unless ``allow_library_mismatch``), and whatever
    :func:`restore` refuses (vocabulary, shapes, NaN, digest). Checkpoints written before model sizes were
    recorded load with Table I's sizes (what they were trained with); one whose arrays do not fit them is
    refused by its shapes. ``meta.json`` is read once (:func:`read_meta`)."""
    meta = read_meta(path)
    why = None if allow_library_mismatch else library_mismatch(path, meta)
    if why:
        raise ValueError(why)
    name, num_controls, seeds = meta.get("method"), meta.get("num_controls", 4), meta.get("seeds", [0])
    num_tendons = meta.get("num_tendons", 4)
    if name not in methods.REGISTRY:
        raise ValueError(f"checkpoint {path} names unknown method {name!r}; valid: {', '.join(methods.ALL_METHODS)}")
    if method is not None and name != method:
        raise ValueError(f"checkpoint {path}: method is {name!r}, expected {method!r}")
    if isinstance(num_controls, bool) or not isinstance(num_controls, int) or not 2 <= num_controls <= 64:
        raise ValueError(f"checkpoint {path} has num_controls {num_controls!r}, expected an integer in 2..64")
    if isinstance(num_tendons, bool) or not isinstance(num_tendons, int) or not 1 <= num_tendons <= 64:
        raise ValueError(f"checkpoint {path} has num_tendons {num_tendons!r}, expected an integer in 1..64")
    try:
        model = model_config(meta)
        recorded = dict(meta.get("sample", {}))
        scale = recorded.pop("noise_scale", 1.0)  # one number, or {steps: number} chosen per step count
        scales = {int(k): float(v) for k, v in scale.items()} if isinstance(scale, dict) else {}
        sample = SampleConfig(**recorded, noise_scale=1.0 if scales else scale)
        for v in scales.values():
            SampleConfig(noise_scale=v)  # ValueError naming the valid range
    except (TypeError, ValueError) as e:
        raise ValueError(f"checkpoint {path}: {e}") from None
    graphdef, params = methods.init(name, tuple(seeds), num_controls, num_tendons, model, abstract=True)
    params, _ = restore(path, params)
    library = {
        "version": meta.get("library_version", "1 (unversioned)"),
        "sha256": meta.get("library_sha256"),
        "path": meta.get("library_path"),
        "tuples": trained_tuples(meta),
        "trunk": meta.get("trunk"),
    }
    return Trained(
        name,
        graphdef,
        params,
        tuple(int(x) for x in seeds),
        num_controls,
        num_tendons=num_tendons,
        model=model,
        sample_config=sample,
        library=library,
        noise_scales=scales,
    )
