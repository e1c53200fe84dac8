"""The demonstration library (SPEC §3) and the metrics that judge against it (SPEC §6)."""

import numpy as np
import pytest

import jgrounding as jg
from jgrounding import library, safety
from jgrounding.evaluation import metrics
from jgrounding.library import designs, primitives


@pytest.fixture(scope="module")
def lib():
    return jg.load_library()


def test_split_is_tuple_balanced(lib):
    assert len(lib.train) == 192 and len(lib.heldout) == 64
    for split, per in ((lib.train, 3), (lib.heldout, 1)):
        counts = np.bincount(split.intent * 4 + split.intensity, minlength=64)
        assert (counts == per).all()
    assert lib.train.u.shape == (192, 150, 4) and lib.train.controls.shape == (192, 4, 4)
    assert all(len(t) >= 3 and all(isinstance(s, str) and s for s in t) for t in lib.train.texts)


def test_expert_trajectories_are_safe_spline_reconstructions(lib):
    for split in (lib.train, lib.heldout):
        assert safety.is_safe(split.u)
        np.testing.assert_allclose(split.u, safety.make_safe(jg.splines.reconstruct(split.controls)), atol=1e-5)


def test_regeneration_is_byte_identical(tmp_path):
    arrays, card = library.build(library.BuildConfig(seed=0), progress=False)
    path = library.save(arrays, card, tmp_path / "lib.npz")
    assert path.read_bytes() == library.DEFAULT_PATH.read_bytes()
    assert (tmp_path / "lib.json").read_text() == library.DEFAULT_PATH.with_suffix(".json").read_text()


def test_another_seed_gives_another_library(tmp_path):
    # small (2 + 2 realizations per tuple, 4 candidates per screening round): only the seed matters here
    cfg = library.BuildConfig(seed=1, realizations=2, eval_realizations=2, candidates_per_round=4)
    arrays, _ = library.build(cfg, progress=False)
    with np.load(library.DEFAULT_PATH) as shipped:  # seed 0; the first record is the same tuple's first realization
        assert arrays["u"].shape[1:] == shipped["u"].shape[1:]
        assert not np.array_equal(arrays["u"][0], shipped["u"][0])


def test_load_errors_name_the_file_and_the_fix(tmp_path):
    with pytest.raises(FileNotFoundError, match="build_library"):
        jg.load_library(tmp_path / "missing.npz")
    bad = tmp_path / "lib.npz"
    bad.write_bytes(library.DEFAULT_PATH.read_bytes()[:1000])
    bad.with_suffix(".json").write_text(library.DEFAULT_PATH.with_suffix(".json").read_text())
    with pytest.raises(ValueError, match="sha256"):
        jg.load_library(bad)


def test_bracket_violations_name_what_is_out_of_range():
    b = {k: {0.35: 0.5} for k in ("oracle", "tuple_mean", "wrong_intent", "far_intensity", "adjacent_intensity")}
    b["heldout_4gram_overlap"] = 0.9
    bad = " ".join(library.bracket_violations(b, 0.35))
    assert "wrong_intent" in bad and "far_intensity" in bad and "overlap" in bad and "tuple mean" in bad


def test_library_records_version_and_content_hash():
    arrays = dict(np.load(library.DEFAULT_PATH))
    card = jg.load_library().meta
    assert str(arrays["library_version"]) == card["library_version"] == library.LIBRARY_VERSION
    assert str(arrays["content_sha256"]) == card["content_sha256"] == library.content_hash(arrays)


@pytest.mark.slow
def test_code_is_the_documented_design():
    from tools import design_signatures

    np.testing.assert_allclose(design_signatures.design(), primitives.CODE, atol=0.011)


def test_rms_success_diversity():
    a = np.zeros((3, 150, 4))
    b = np.full((3, 150, 4), 0.5)
    np.testing.assert_allclose(metrics.rms(a, b), 0.5)
    assert float(metrics.success_rate(np.array([0.1, 0.35, 0.36]))) == pytest.approx(2 / 3)
    same = np.broadcast_to(a[0], (5, 150, 4))
    assert float(metrics.pairwise_diversity(same)) == 0.0
    two = np.stack([a[0], b[0]])
    assert float(metrics.pairwise_diversity(two)) == pytest.approx(0.5)


def test_variant_midpoint_covers_every_one_to_many_tuple(lib):
    mid = library.variant_midpoint(lib)
    assert mid["tuples"] == 4 * int((designs.of_library(lib).num_variants > 1).sum()) == 32  # 32 split tuples in v5
    assert all(0.0 <= v <= 1.0 for v in mid["success"].values())
