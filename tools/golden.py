"""Golden outputs of ``jg.sample``: fixed keys, tuples and step counts, stored in tests/data/golden_sample.npz.

``tests/test_golden.py`` samples the same cases and compares them with the stored arrays, so a refactor that
changes what a user gets from ``jg.sample`` fails, and so does a new shipped model or library that nobody
meant to ship. When the model or the library changes on purpose (``make ship``, ``make library``,
``python -m experiments.ship``), regenerate the file with one command and commit it with the change::

    python -m tools.golden --write

``python -m tools.golden`` (no flag) compares and prints the largest difference per case.
"""

from __future__ import annotations

import argparse
import io as _io
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PATH = ROOT / "tests" / "data" / "golden_sample.npz"
COMMAND = "python -m tools.golden --write"
ATOL = 1e-5  # float32 sums may round differently on another CPU or thread count; a real change is far larger

# name -> (seed, jg.sample keyword arguments); every case runs through the public jg.sample.
CASES = {
    "one_tuple_default": (0, dict(intent="nodding", intensity="moderate")),
    "batch_current_none": (
        1,
        dict(intent=["greeting", "comforting"], intensity=["subtle", "emphatic"], num_samples=2, steps=8, current=None),
    ),
    "few_step_route": (2, dict(intent="greeting", intensity="emphatic", num_samples=3, steps=2)),
    "midpoint_indices": (3, dict(intent=5, intensity=1, num_samples=2, steps=6, sampler="midpoint")),
    "start_conditioned": (
        4,
        dict(intent="nodding", intensity="subtle", steps=10, current=[0.2, 0.1, 0.0, 0.3], start_conditioned=True),
    ),
}


def identity() -> dict[str, str]:
    """What the cases depend on besides the code: the digest of every shipped checkpoint's parameters, the
    shipped manifest, the library and the intent embeddings."""
    from jgrounding import io
    from jgrounding.policy import sampling
    from jgrounding.training import checkpoints

    assets = sampling.DEFAULT_CHECKPOINT.parent.parent
    out = {}
    for _, kwargs in CASES.values():
        path = sampling.shipped_checkpoint(int(kwargs.get("steps", 50)))
        out[f"checkpoint {path.name}"] = checkpoints.read_meta(path)["params_sha256"]
    for p in (sampling.SHIPPED, assets / "library.npz", assets / "intent_embeddings.npz"):
        if p.exists():
            out[p.name] = io.sha256_file(p)
    return dict(sorted(out.items()))


def compute() -> dict[str, np.ndarray]:
    import jax

    import jgrounding as jg

    return {
        name: np.asarray(jg.sample(jax.random.key(seed), **kwargs), np.float32)
        for name, (seed, kwargs) in CASES.items()
    }


def load(path: Path = PATH) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files if k != "identity"}
        return arrays, json.loads(str(f["identity"]))


def write(path: Path = PATH) -> Path:
    from jgrounding.io import write_atomic

    buf = _io.BytesIO()
    np.savez_compressed(buf, identity=np.array(json.dumps(identity())), **compute())
    return write_atomic(path, buf.getvalue())


def differences(path: Path = PATH) -> tuple[list[str], dict[str, float]]:
    """(what changed in the identity, largest absolute difference per case) against the stored file."""
    stored, stored_id = load(path)
    now_id = identity()
    changed = [
        f"{k}: {stored_id.get(k, '(absent)')[:12]} -> {now_id.get(k, '(absent)')[:12]}"
        for k in sorted(set(stored_id) | set(now_id))
        if stored_id.get(k) != now_id.get(k)
    ]
    got = compute()
    diff = {}
    for name in sorted(set(stored) | set(got)):
        if name not in stored or name not in got or stored[name].shape != got[name].shape:
            diff[name] = float("inf")
        else:
            diff[name] = float(np.max(np.abs(stored[name] - got[name])))
    return changed, diff


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--write", action="store_true", help=f"(re)write {PATH.relative_to(ROOT)} from the shipped model")
    args = p.parse_args(argv)
    if args.write:
        print(f"wrote {write()}")
        return 0
    changed, diff = differences()
    for line in changed:
        print("identity changed:", line)
    for name, d in diff.items():
        print(f"{name}: max |difference| {d:.3g}")
    return 0 if not changed and max(diff.values()) <= ATOL else 1


if __name__ == "__main__":
    sys.exit(main())
