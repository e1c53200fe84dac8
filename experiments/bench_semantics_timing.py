"""Where a warm ``jg.ground`` of one text spends its time, for ``python -m experiments.bench_semantics``: the
inputs prepared in Python against the compiled program per token bucket, the encoder by how its matrices are stored,
the latency of a process pinned to one core, and the first call of a fresh process."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import jax
import numpy as np

from jgrounding.semantics import encoder, features
from jgrounding.semantics import head as semantic_head

ROOT = Path(__file__).resolve().parent.parent
TIMING_PASSES = 3  # per reducer, in rotated order (experiments.bench_semantics.main)
FIRST_CALL = (
    "import time; t = time.perf_counter(); import jgrounding as jg; "
    "jg.ground('The user looks sad; comfort them gently.'); print(time.perf_counter() - t)"
)


def breakdown(texts: list[str]) -> dict:
    """Where a warm single-text ``jg.ground`` spends its time (the shipped tuned head): preparing the inputs in
    Python (structure rules, tokenizer, span pools, named actions and degree cues) and the one compiled program
    (encoder, head and nearest-neighbour vote: :meth:`Head.run_tuned`), per token bucket. Milliseconds."""
    from jgrounding.semantics import structure

    head = semantic_head.load()
    if not head.config.features.one_program:
        return {}
    prep, program, buckets = [], [], []
    for text in texts:
        t0 = time.perf_counter()
        st = structure.analyse(text)
        extras = features.tuned_extras(text, st)[None]
        (_, ids, mask, pools), *_ = list(features.encoder_batches([text], [st]))
        t1 = time.perf_counter()
        out = head.run_tuned(ids, mask, pools, extras)  # the program jg.ground runs, the vote included
        np.asarray(out[0])
        t2 = time.perf_counter()
        prep.append(t1 - t0)
        program.append(t2 - t1)
        buckets.append(ids.shape[1])
    prep, program, buckets = np.array(prep) * 1e3, np.array(program) * 1e3, np.array(buckets)
    by_bucket = {}
    for b in map(int, np.unique(buckets)):
        ms = float(np.median(program[buckets == b]))
        flops = encoder.matmul_flops(b, layers=head.config.num_encoder_layers)
        by_bucket[b] = {"n": int((buckets == b).sum()), "program_ms_median": ms, "gflop": flops / 1e9}
        by_bucket[b]["gflops"] = flops / 1e6 / ms
    return {
        "encoder_layers": head.config.num_encoder_layers,
        "prep_ms_median": float(np.median(prep)),
        "program_ms_median": float(np.median(program)),
        "program_ms_p99": float(np.percentile(program, 99)),
        "by_bucket": by_bucket,
    }


def matrix_precision(texts: list[str]) -> dict:
    """The encoder alone (:func:`jgrounding.semantics.encoder.pool_ids`, one text at a time) with the dense matrices
    stored in each of :data:`jgrounding.semantics.encoder.STORAGES` (grounding keeps
    :data:`~jgrounding.semantics.encoder.MATRIX_STORAGE`), all from the weights jg.ground runs, rotating text by
    text so all see the machine in the same state. Milliseconds (medians) by storage, and each one's speed-up over
    float32."""
    from jgrounding.semantics import structure

    head = semantic_head.load()
    values = encoder.float_matrices(jax.tree.map(np.asarray, head.encoder_params()))
    kinds = {k: jax.device_put(encoder.stored_matrices(values, k)) for k in encoder.STORAGES}
    times = {k: [] for k in kinds}
    for i, text in enumerate(texts):
        (_, ids, mask, pools), *_ = list(features.encoder_batches([text], [structure.analyse(text)]))
        order = list(kinds)[i % len(kinds) :] + list(kinds)[: i % len(kinds)]
        for kind in order:
            encoder.pool_ids(kinds[kind], ids, mask, pools).block_until_ready()  # compiled outside the timing
        for kind in order:
            t0 = time.perf_counter()
            encoder.pool_ids(kinds[kind], ids, mask, pools).block_until_ready()
            times[kind].append(time.perf_counter() - t0)
    med = {k: float(np.median(v) * 1e3) for k, v in times.items()}
    return {"ms": med, "speedup": {k: med["float32"] / med[k] for k in med}, "shipped": encoder.MATRIX_STORAGE}


ONE_CORE = """
import json, os, sys, time
os.sched_setaffinity(0, {int(sys.argv[1])})  # before JAX starts: its thread pools get one thread
import numpy as np
import jgrounding as jg
from jgrounding import semantics
semantics.warmup(256)
texts = json.loads(sys.stdin.read())
jg.ground(texts[0])
t = []
for text in texts:
    t0 = time.perf_counter()
    jg.ground(text)
    t.append(time.perf_counter() - t0)
t = np.array(t) * 1e3
print(json.dumps({"ms_median": float(np.median(t)), "ms_p99": float(np.percentile(t, 99)), "n": len(t)}))
"""


def one_core_latency(texts: list[str]) -> dict | None:
    """Warm latency of ``jg.ground`` in a process pinned to one CPU core (``taskset -c N`` does the same): JAX then
    runs each program in one thread, so it never waits for a second thread on a core another process holds.
    None where CPU affinity cannot be set (not Linux)."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    core = min(os.sched_getaffinity(0))
    out = subprocess.run(
        [sys.executable, "-c", ONE_CORE, str(core)], input=json.dumps(texts), cwd=ROOT, capture_output=True, text=True
    )
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1]) | {"core": core}


def first_call_seconds(cache: str | None) -> float:
    """The first ``jg.ground`` in a fresh process (import included); ``cache``: a compilation-cache folder."""
    env = dict(os.environ)
    if cache is not None:
        env["JGROUNDING_CACHE"] = cache
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], env=env, cwd=ROOT, capture_output=True, text=True)
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    return float(out.stdout.strip().splitlines()[-1])
