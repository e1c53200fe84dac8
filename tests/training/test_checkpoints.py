"""Checkpoints refuse what they cannot vouch for (issue: reliability), naming the file.

``checkpoints.restore`` checks the vocabulary, the array shapes, a digest of the stored arrays and
finiteness; ``sampling.load`` adds a self-test sample before it accepts a model.
"""

import gc
import json
import shutil
import subprocess
import sys
import time

import jax
import numpy as np
import pytest

import jgrounding as jg
from jgrounding import safety
from jgrounding.generators import methods
from jgrounding.policy import sampling
from jgrounding.training import checkpoints


@pytest.fixture(scope="module")
def shipped():
    meta = checkpoints.read_meta(sampling.DEFAULT_CHECKPOINT)
    _, template = methods.init(meta["method"], (0,), meta["num_controls"])
    params, meta = checkpoints.restore(sampling.DEFAULT_CHECKPOINT, template)
    keep = {k: meta[k] for k in ("method", "seeds", "num_controls", "config", "library_sha256", "step")}
    return params, keep


def _write(path, tree, meta):
    checkpoints.save(path, tree, meta)
    return str(path)


def _map_leaves(tree, fn):
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    return jax.tree_util.tree_unflatten(treedef, [fn(i, np.asarray(x)) for i, x in enumerate(leaves)])


def _dead_pid() -> int:
    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    return int(proc.stdout)


def test_a_faithful_copy_loads_and_samples(tmp_path, shipped):
    params, meta = shipped
    path = _write(tmp_path / "copy", params, meta)
    assert "params_sha256" in checkpoints.read_meta(path)
    trained, emb = sampling.load(path)
    assert emb.shape == (16, 384)
    u = jg.sample(jax.random.key(0), "greeting", "subtle", checkpoint=path)
    assert u.shape == (150, 4) and safety.is_safe(u)


def test_nan_weights_are_refused_by_name(tmp_path, shipped):
    params, meta = shipped
    bad = _map_leaves(params, lambda i, x: np.full_like(x, np.nan) if i == 0 and x.dtype.kind == "f" else x)
    path = _write(tmp_path / "nan", bad, meta)
    with pytest.raises(ValueError, match=f"{path}.*NaN"):
        sampling.load(path)


def test_wrong_shapes_are_refused_by_name(tmp_path, shipped):
    _, meta = shipped
    _, six = methods.init("tuple_spline_rf", (0,), 6)  # a P = 6 model filed as P = 4
    path = _write(tmp_path / "p6", six, meta)
    with pytest.raises(ValueError, match=f"{path} has an array of shape"):
        sampling.load(path)


def test_another_vocabulary_size_is_refused_by_name(tmp_path, shipped):
    params, meta = shipped
    path = _write(tmp_path / "vocab", params, meta)
    full = checkpoints.read_meta(path)
    full["intents"] = full["intents"] + ["dancing"]  # trained for 17 intents
    (tmp_path / "vocab" / "meta.json").write_text(json.dumps(full))
    with pytest.raises(ValueError, match=f"{path} was trained for another vocabulary \\(17 intents"):
        sampling.load(path)
    # ... and an intensity table of another size fails the shape check, whatever the metadata says
    five = _map_leaves(params, lambda i, x: np.zeros((1, 5, 64), x.dtype) if x.shape == (1, 4, 64) else x)
    path = _write(tmp_path / "z5", five, meta)
    with pytest.raises(ValueError, match=f"{path} has an array of shape \\(1, 5, 64\\)"):
        sampling.load(path)


def test_a_model_that_fails_the_self_test_is_refused(tmp_path, shipped):
    params, meta = shipped  # finite weights whose outputs overflow to NaN
    huge = _map_leaves(params, lambda i, x: x * np.float32(1e20) if x.dtype.kind == "f" else x)
    path = _write(tmp_path / "huge", huge, meta)
    with pytest.raises(ValueError, match=f"{path} failed its load self-test"):
        sampling.load(path)
    with pytest.raises(ValueError, match="self-test"):
        jg.sample(jax.random.key(0), "greeting", "subtle", checkpoint=path)


def test_unknown_method_and_bad_argument(tmp_path, shipped):
    params, meta = shipped
    path = _write(tmp_path / "gan", params, {**meta, "method": "tuple_spline_gan"})
    with pytest.raises(ValueError, match=f"{path} names unknown method.*tuple_spline_rf"):
        sampling.load(path)
    with pytest.raises(TypeError, match="directory path"):
        sampling.load(5)
    with pytest.raises(ValueError, match=f"{tmp_path / 'none'}"):
        sampling.load(str(tmp_path / "none"))


def test_corrupt_arrays_are_refused_by_name(tmp_path, shipped):
    params, meta = shipped
    path = _write(tmp_path / "rot", params, meta)
    full = checkpoints.read_meta(path)
    full["params_sha256"] = "0" * 64  # the arrays no longer match their recorded digest
    (tmp_path / "rot" / "meta.json").write_text(json.dumps(full))
    with pytest.raises(ValueError, match=f"{path} is corrupt"):
        checkpoints.restore(path, params)
    (tmp_path / "nometa").mkdir()
    (tmp_path / "nometa" / "params").mkdir()
    with pytest.raises(ValueError, match="meta.json is missing or unreadable"):
        checkpoints.restore(tmp_path / "nometa", params)


# orbax's reader threads report the aborted read after their event loop closed; harmless here
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_truncated_array_files_are_refused_by_name(tmp_path, shipped):
    params, meta = shipped
    path = _write(tmp_path / "trunc", params, meta)
    for f in (tmp_path / "trunc" / "params").rglob("*"):
        if f.is_file() and f.parent.name == "d":
            f.write_bytes(f.read_bytes()[: len(f.read_bytes()) // 2])  # truncated data files
    with pytest.raises(ValueError, match=f"{path}"):
        checkpoints.restore(path, params)
    time.sleep(0.2)
    gc.collect()  # let the aborted reader report inside this test


def test_a_writer_killed_between_renames_loses_nothing(tmp_path):
    tree = {"w": np.arange(6, dtype=np.float32).reshape(2, 3)}
    checkpoints.save(tmp_path / "ck", tree, {"step": 1})
    dead = _dead_pid()
    # killed after moving the old checkpoint aside, before renaming the new one into place
    (tmp_path / "ck").rename(tmp_path / f"ck.old-{dead}")
    shutil.copytree(tmp_path / f"ck.old-{dead}", tmp_path / f"ck.tmp-{dead}")
    back, meta = checkpoints.restore(tmp_path / "ck", tree)
    np.testing.assert_array_equal(back["w"], tree["w"])
    assert meta["step"] == 1 and (tmp_path / "ck").exists()
    checkpoints.save(tmp_path / "ck", tree, {"step": 2})  # the next write clears the dead writer's copy
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ck"]
    assert checkpoints.read_meta(tmp_path / "ck")["step"] == 2


def test_a_checkpoint_of_another_library_version_is_refused_unless_allowed(tmp_path, shipped):
    params, meta = shipped
    path = _write(tmp_path / "old", params, {**meta, "library_sha256": "0" * 64, "library_version": "1"})
    with pytest.raises(ValueError, match="(?s)library version 1.*library version .*allow_library_mismatch"):
        checkpoints.restore_trained(path)
    assert checkpoints.restore_trained(path, allow_library_mismatch=True).method == meta["method"]


def test_the_shipped_checkpoint_matches_the_shipped_library():
    meta = checkpoints.read_meta(sampling.DEFAULT_CHECKPOINT)
    assert checkpoints.library_mismatch(sampling.DEFAULT_CHECKPOINT, meta) is None
