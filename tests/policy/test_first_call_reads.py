"""``jg.sample``'s first call in a fresh process reads each file once (issue #22: one load read the checkpoint's
meta.json five times). Python-level reads are seen through the ``open`` audit event; orbax's array files are
read by tensorstore in C++, which raises no event, and are left out."""

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

PROBE = r"""
import collections, json, os, sys
assets = os.path.realpath(sys.argv[1])
reads = collections.Counter()

def hook(event, args):
    if event != "open" or not isinstance(args[0], (str, bytes, os.PathLike)):
        return
    path, mode, flags = args
    writing = (mode and any(c in mode for c in "wax+")) or (flags and flags & (os.O_WRONLY | os.O_RDWR))
    p = os.path.realpath(os.fsdecode(path))
    if not writing and p.startswith(assets + os.sep):
        reads[os.path.relpath(p, assets)] += 1

sys.addaudithook(hook)
import jax
import jgrounding as jg

u = jg.sample(jax.random.key(0), "greeting", "moderate")
print("READS " + json.dumps({"shape": list(u.shape), "reads": reads}))
"""


def test_the_first_jg_sample_reads_each_file_once():
    env = {**os.environ, "PYTHONPATH": str(ROOT), "JAX_PLATFORMS": "cpu"}
    p = subprocess.run(
        [sys.executable, "-c", PROBE, str(ROOT / "jgrounding" / "assets")],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    assert p.returncode == 0, p.stderr[-3000:]
    out = json.loads(next(line for line in p.stdout.splitlines() if line.startswith("READS "))[6:])
    assert out["shape"] == [150, 4]
    reads = out["reads"]
    ck = os.path.join("checkpoints", "tuple_spline_rf")
    # what loading must read: the shipped-model manifest, the checkpoint's metadata, the intent embeddings and
    # the library it checks the checkpoint against (its sha256)
    for needed in ("checkpoints/shipped.json", f"{ck}/meta.json", "intent_embeddings.npz", "library.npz"):
        assert needed.replace("/", os.sep) in reads, (needed, reads)
    assert all(n == 1 for n in reads.values()), f"files read more than once: {reads}"
