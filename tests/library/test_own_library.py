"""Training and sampling on an imported library (issue #18): N_u from the data, checkpoint refusals."""

import jax
import numpy as np
import pytest
from test_importer import write_folder

import jgrounding as jg
from jgrounding import library
from jgrounding.evaluation import generate
from jgrounding.library import importer
from jgrounding.policy import sampling
from jgrounding.training import TrainConfig, trainer


@pytest.fixture(scope="module")
def three_tendon_library(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("own")
    out = tmp / "my_library.npz"
    assert (
        importer.main(
            [
                "import",
                str(write_folder(tmp / "rec", num_tendons=3)),
                "--out",
                str(out),
                "--limits",
                "2:12",
                "--tendons",
                "3",
                "--controls",
                "4",
            ]
        )
        == 0
    )
    return out


@pytest.mark.parametrize("method", ["tuple_spline_cnn", "tuple_dense_cnn", "tuple_spline_rf"])
def test_three_tendons_train_and_generate(three_tendon_library, method):
    lib = jg.load_library(three_tendon_library)
    trained = trainer.fit(method, lib, seeds=(0,), config=TrainConfig(steps=5, chunk=5), progress=False)
    assert trained.num_tendons == 3
    u = generate.generate(trained, np.zeros((2, 384), np.float32), np.array([1, 3]), jax.random.key(0), num_samples=2)
    assert u.shape == (1, 2, 2, 150, 3) and 0.0 <= u.min() and u.max() <= 1.0


def test_train_cli_and_sample_three_tendons(three_tendon_library, tmp_path):
    from experiments import train

    out = tmp_path / "mine"
    assert (
        train.main(["--library", str(three_tendon_library), "--out", str(out), "--steps", "10", "--chunk", "10"]) == 0
    )
    u = jg.sample(jax.random.key(0), "nodding", "moderate", num_samples=3, checkpoint=str(out))
    assert u.shape == (3, 150, 3) and 0.0 <= u.min() and u.max() <= 1.0
    with pytest.raises(
        ValueError,
        match=r"trained on a library without \(comforting, subtle\); its tuples: "
        r"greeting/emphatic, nodding/moderate",
    ):
        jg.sample(jax.random.key(0), "comforting", "subtle", checkpoint=str(out))
    arrays = dict(np.load(three_tendon_library))  # the library changes after training: the checkpoint is refused
    arrays["u"] = arrays["u"] * 0.5
    library.save(arrays, jg.load_library(three_tendon_library).meta, three_tendon_library)
    sampling.load.cache_clear()  # a new process would load it afresh
    with pytest.raises(
        ValueError,
        match=r"(?s)trained on library version .*my_library.npz has changed since .*"
        r"--library .*my_library.npz .*allow_library_mismatch=True",
    ):
        jg.sample(jax.random.key(0), "nodding", "moderate", checkpoint=str(out))
    # the one rule has the one documented opt-out, for a checkpoint trained with --library too (issue #22: a
    # second check ran first and ignored it)
    u = jg.sample(jax.random.key(0), "nodding", "moderate", checkpoint=str(out), allow_library_mismatch=True)
    assert u.shape == (150, 3)


@pytest.mark.slow
def test_ablation_runs_on_a_three_tendon_library_without_physics(three_tendon_library, tmp_path, capsys):
    from experiments import ablation

    out = tmp_path / "abl"
    assert (
        ablation.main(
            [
                "--quick",
                "--steps",
                "5",
                "--seeds",
                "0",
                "--methods",
                "tuple_spline_cnn",
                "--library",
                str(three_tendon_library),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert (
        "physics-aware row skipped: the built-in simulator is the 4-tendon trunk, this library has N_u = 3" in printed
    )
    table = (out / "ablation.md").read_text()
    assert "Tuple + Spline + CNN" in table and "Oracle" in table
    assert "Wrong intent" in table  # two intents in the library: the wrong-intent reference exists


def test_references_a_partial_library_cannot_replay_are_left_out(three_tendon_library):
    from jgrounding.evaluation import metrics

    refs = metrics.reference_baselines(jg.load_library(three_tendon_library), draws=2)
    assert "oracle" in refs and "wrong_intent_any_intensity" in refs
    assert "adjacent_intensity" not in refs  # nodding/moderate and greeting/emphatic: no neighbour level
