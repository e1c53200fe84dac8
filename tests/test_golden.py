"""The refactor changes no output (issue #22): ``jg.sample`` for fixed keys, tuples and step counts equals the
arrays stored in tests/data/golden_sample.npz, which are regenerated only when the shipped model or library
changes on purpose (``python -m tools.golden --write``)."""

import numpy as np
import pytest

from tools import golden

HOW = (
    f"If the shipped model, the library or the intent embeddings changed on purpose, regenerate the golden file "
    f"with `{golden.COMMAND}` and commit it with that change; otherwise jg.sample's output changed by accident."
)


@pytest.fixture(scope="module")
def stored():
    return golden.load()


def test_golden_file_was_made_from_the_shipped_model_and_library(stored):
    _, stored_id = stored
    now = golden.identity()
    changed = [k for k in sorted(set(stored_id) | set(now)) if stored_id.get(k) != now.get(k)]
    assert not changed, f"the files jg.sample depends on changed since the golden file was written: {changed}. {HOW}"


def test_jg_sample_matches_the_golden_arrays(stored):
    arrays, _ = stored
    got = golden.compute()
    assert set(got) == set(arrays) == set(golden.CASES), f"the cases changed. {HOW}"
    for name, want in arrays.items():
        assert got[name].shape == want.shape, f"{name}: shape {got[name].shape} != stored {want.shape}. {HOW}"
        err = float(np.max(np.abs(got[name] - want)))
        assert err <= golden.ATOL, f"{name}: jg.sample differs from the golden array by up to {err:.3g}. {HOW}"


def test_the_golden_check_catches_a_changed_output_and_a_changed_model(stored, tmp_path):
    """The comparison is not vacuous: a stored file off by 1e-3 in one case, with another checkpoint digest,
    is reported as both."""
    import io
    import json

    arrays, stored_id = stored
    assert all(np.ptp(a) > 0.05 for a in arrays.values())  # real motions, not constants
    name = next(iter(arrays))
    other = {**arrays, name: arrays[name] + 1e-3}
    key = next(k for k in stored_id if k.startswith("checkpoint "))
    buf = io.BytesIO()
    np.savez(buf, identity=np.array(json.dumps({**stored_id, key: "0" * 64})), **other)
    (tmp_path / "g.npz").write_bytes(buf.getvalue())
    changed, diff = golden.differences(tmp_path / "g.npz")
    assert [c.split(":")[0] for c in changed] == [key]
    assert abs(diff[name] - 1e-3) < 1e-5 and all(d <= golden.ATOL for n, d in diff.items() if n != name)
