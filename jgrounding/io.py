"""Small shared utilities with no dependency on the rest of the package: atomic writes, hashes, the folder
where compiled programs persist, and where the package's own run-time files are (:func:`asset`)."""

from __future__ import annotations

import functools
import hashlib
import importlib.resources
import os
import stat
import tempfile
import tomllib
from pathlib import Path


@functools.lru_cache(maxsize=1)
def _package_root() -> Path:
    root = importlib.resources.files("jgrounding")
    if not isinstance(root, Path):  # a zip import or a namespace package: orbax and MuJoCo need real files
        raise RuntimeError(f"jgrounding must be installed as files on disk (found {root!r}); pip install the wheel")
    return root.resolve()


def package_file(*parts: str) -> Path:
    """A file shipped inside the package, ``jgrounding/<parts>`` (the server's page: ``package_file("apps",
    "static")``), found through ``importlib.resources``: the same in a git checkout, an editable install and an
    installed wheel."""
    return _package_root().joinpath(*parts)


def asset(*parts: str) -> Path:
    """The one place run-time data is found: ``jgrounding/assets/<parts>``, package data of the wheel. It holds
    the shipped checkpoints and ``checkpoints/shipped.json``, the semantic head and its nearest-neighbour table,
    the intent embeddings and cue prototypes, the demonstration library (``library.npz`` + ``library.json``), the
    library designs' code words (``designs/``) and ``trunk.xml``; ``asset()`` is the folder. Development data
    (training corpora, evaluation sets, examples) stays in the repository's top-level ``assets/``."""
    return package_file("assets", *parts)


def write_atomic(path: str | os.PathLike, data: bytes | str, *, mode: int | None = None) -> Path:
    """Write ``data`` to ``path`` via a temporary file in the same folder and ``os.replace``.

    A reader never sees a half-written file. The file gets ``mode`` if given, else the mode of the
    file it replaces, else the user's default (``0o666 & ~umask``), not ``mkstemp``'s private 0600, so a
    controller running as another user can read what we write.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if mode is None:
        try:
            mode = stat.S_IMODE(path.stat().st_mode)
        except FileNotFoundError:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb" if isinstance(data, bytes) else "w") as f:
            f.write(data)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def sha256_bytes(data: bytes) -> str:
    """Hex SHA-256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's contents, read in chunks; a file is hashed once per version (cached by its
    path, size and modification time), so checking several checkpoints against one library reads it once."""
    st = os.stat(path)
    return _sha256(os.path.realpath(path), st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=64)
def _sha256(path: str, mtime_ns: int, size: int, chunk: int = 1 << 20) -> str:
    del mtime_ns, size  # cache keys
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(chunk), b""):
            h.update(block)
    return h.hexdigest()


def cache_dir() -> Path | None:
    """Where compiled XLA programs persist between processes (and between clones of the repository on one
    machine): ``$JGROUNDING_CACHE/jax``, else ``$XDG_CACHE_HOME/jgrounding/jax`` (``~/.cache/jgrounding/jax``);
    ``JGROUNDING_CACHE=off`` turns it off (None). JAX keys every entry by the program and compiler, so clones
    with different code never share a wrong program."""
    root = os.environ.get("JGROUNDING_CACHE")
    if root and root.lower() in ("off", "0", "none", "false"):
        return None
    base = Path(root) if root else Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "jgrounding"
    return base / "jax"


def data_cache_dir() -> Path | None:
    """Where results that are pure functions of their inputs persist between runs (the benchmark's reference
    samples, keyed by a content hash of everything they depend on): ``$JGROUNDING_CACHE/data``, else
    ``$XDG_CACHE_HOME/jgrounding/data``; None with ``JGROUNDING_CACHE=off`` (compute every time)."""
    jax_dir = cache_dir()
    return None if jax_dir is None else jax_dir.parent / "data"


def content_key(*parts: str | bytes | os.PathLike) -> str:
    """SHA-256 over ``parts`` in order: a ``Path`` contributes its file's contents (hashed), bytes and strings
    themselves. The one key of :func:`data_cache_dir` entries: a change to any input file or value is a new key."""
    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, os.PathLike):
            h.update(sha256_file(part).encode())
        else:
            h.update(part if isinstance(part, bytes) else str(part).encode())
        h.update(b"\0")
    return h.hexdigest()


def enable_compilation_cache(path: str | Path | None = None, *, min_compile_secs: float = 0.0) -> str | None:
    """Turn on JAX's persistent compilation cache, so compiled programs survive the process: in ``path`` when given
    (it replaces any folder set before), else in :func:`cache_dir` unless a folder is already set (the user's own
    wins) or ``JGROUNDING_CACHE=off``. Programs that compiled in under ``min_compile_secs`` are not stored.
    Returns the folder in use, or None (off, or a folder that cannot be created: compile every time, as before)."""
    import jax

    if path is None:
        if jax.config.jax_compilation_cache_dir:
            return jax.config.jax_compilation_cache_dir
        path = cache_dir()
        if path is None:
            return None
    try:
        Path(path).mkdir(parents=True, exist_ok=True)
    except OSError:  # a read-only home
        return None
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", min_compile_secs)
    try:  # a cache already initialised (disabled) by an earlier compile in this process is re-read
        from jax._src import compilation_cache

        compilation_cache.reset_cache()
    except Exception:  # pragma: no cover - private API; without it the cache starts with the next process
        pass
    return str(path)


def read_toml(path: str | os.PathLike, what: str) -> dict:
    """A TOML file's tables: ``FileNotFoundError`` naming ``what`` when it is missing, ``ValueError`` naming the file
    when it is not valid TOML (the trunk description and the calibration settings read this way)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} {path} not found")
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{path}: not valid TOML: {e}") from None
