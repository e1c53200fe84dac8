"""Validation at the public boundary (issue: reliability): every invalid input raises a ValueError or
TypeError that names what is accepted. (Vocabulary, jg.sample and trunk cases live beside their
modules' tests and in tests/test_fuzz.py.)"""

import contextlib
import dataclasses
import io

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jgrounding as jg
from jgrounding import library, semantics, training
from jgrounding.actuation import splines
from jgrounding.apps import cli
from jgrounding.generators import methods
from jgrounding.policy import sampling
from jgrounding.training import checkpoints


@pytest.mark.parametrize(
    "call, exc, match",
    [
        (lambda: splines.fit(np.zeros((150, 4), complex)), TypeError, r"real numeric array \(float, integer or bool\)"),
        (lambda: splines.fit(np.full((150, 4), "a")), TypeError, r"actuation must be a real numeric array of shape"),
        (lambda: splines.fit([[0.0, 1.0], [0.5]]), ValueError, r"shape \(\.\.\., T, N_u\)"),
        (lambda: splines.fit(None), ValueError, "actuation must be a real numeric array"),
        (lambda: splines.reconstruct(np.zeros((4, 4), complex)), TypeError, r"controls must be a real numeric array"),
        (lambda: splines.reconstruct("controls"), TypeError, r"shape \(\.\.\., N_u, P\)"),
        (lambda: splines.fit(np.zeros((150, 4)), num_controls=True), ValueError, "integer >= 2"),
        (lambda: splines.reconstruct(np.zeros((4, 4)), num_steps=True), ValueError, "num_steps"),
        (lambda: splines.reconstruct(np.zeros((4, 4)), num_steps=4.0), ValueError, "num_steps"),
    ],
)
def test_splines_refuse_non_real_or_ragged_input(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


def test_splines_accept_integer_and_bool_arrays_and_stay_jittable():
    assert splines.fit(np.ones((150, 4), int)).dtype == jnp.float32
    assert splines.reconstruct(np.ones((4, 4), bool)).shape == (150, 4)
    c = jax.jit(jax.vmap(splines.fit))(jnp.zeros((2, 150, 4)))
    assert c.shape == (2, 4, 4)


@pytest.mark.parametrize(
    "key, exc, got",
    [
        (7, TypeError, "got int"),
        (np.zeros(2, np.int32), TypeError, r"got int32\[2\] array"),
        (np.zeros(3, np.uint32), TypeError, r"got uint32\[3\] array"),
        (jax.random.split(jax.random.key(0), 2), ValueError, r"key array of shape \(2,\)"),
    ],
)
def test_sample_key_errors_name_both_accepted_kinds(key, exc, got):
    with pytest.raises(exc, match=got) as info:
        jg.sample(key, "greeting", "moderate")
    assert "jax.random.key(seed)" in str(info.value) and "jax.random.PRNGKey(seed)" in str(info.value)


def test_ground_refuses_unencodable_text_and_bounds_long_text():
    with pytest.raises(ValueError, match="not valid Unicode: unpaired surrogate '\\\\ud800' at position 6"):
        jg.ground("hello \ud800 there")
    g = jg.ground("please wave hello to the user " * 1000)  # 30,000 characters: the first 4,000 are read
    assert g.intent in jg.INTENTS and not g.confident and "tokens were read" in g.reason
    # a surrogate past the characters that are read does not matter
    assert jg.ground("wave hello " * 400 + "\ud800").intent in jg.INTENTS
    assert semantics.MAX_CHARS == cli.MAX_TEXT_CHARS  # the command line refuses what ground() would not read


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("steps", -1, "steps must be an integer >= 0"),
        ("chunk", 0, "chunk must be an integer >= 1"),
        ("batch_size", 2.5, "batch_size must be an integer >= 1"),
        ("learning_rate", float("nan"), "finite number"),
        ("weight_decay", -1.0, "finite number >= 0"),
        ("chunk", True, "chunk must be an integer"),
    ],
)
def test_train_config_refuses_bad_values(field, value, match):
    with pytest.raises(ValueError, match=match):
        training.TrainConfig(**{field: value})


def _cli(argv, main=cli.main):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        with pytest.raises(SystemExit) as info:
            main(argv)
    return info.value.code, err.getvalue()


def test_cli_refuses_unusable_out_folders_and_undecodable_text(tmp_path):
    (tmp_path / "file").write_text("x")
    code, err = _cli(["--intent", "nodding", "--no-render", "--out", str(tmp_path / "file")])
    assert code == 2 and "cannot be used as the output folder" in err
    code, err = _cli(["--intent", "nodding", "--no-render", "--out", " "])
    assert code == 2 and "--out needs a folder name" in err
    code, err = _cli(["hello \udcff", "--no-render", "--out", str(tmp_path / "o")])  # surrogateescape'd byte
    assert code == 2 and "not valid UTF-8" in err


@pytest.mark.parametrize(
    "argv, match",
    [
        (["--seeds", "0,x"], "--seeds must be distinct non-negative integers"),
        (["--seeds", "1,1"], "--seeds must be distinct"),
        (["--seeds", "-2"], "--seeds must be distinct non-negative"),
        (["--chunk", "0"], "TrainConfig.chunk must be an integer >= 1"),
        (["--steps", "-5"], "TrainConfig.steps must be an integer >= 0"),
        (["--set", "train.ema=0.9"], "TrainConfig has no field 'ema'; valid: steps"),
        (["--set", "train.time_sampler=gauss"], "TrainConfig.time_sampler must be one of uniform, logit_normal, beta"),
        (["--devices", "99"], "--devices must be in 0.."),
    ],
)
def test_train_script_usage_errors(tmp_path, argv, match):
    from experiments import train

    code, err = _cli(["--out", str(tmp_path / "ck")] + argv, main=train.main)
    assert code == 2 and match in err


def test_train_script_refuses_to_resume_a_different_run(tmp_path):
    from experiments import train

    seeds, config = (0,), training.TrainConfig(steps=20, chunk=10)
    _, params = methods.init("tuple_spline_rf", seeds, 4)
    keys = jnp.stack([jax.random.fold_in(jax.random.key(0), 1)])
    states = jax.vmap(lambda p, k: training.init_state(p, k, config))(params, keys)
    tree = dataclasses.replace(states, key=jax.random.key_data(states.key))
    out = tmp_path / "ck"
    checkpoints.save(
        str(out) + ".run",
        tree,
        {
            "method": "tuple_spline_rf",
            "seeds": [0],
            "num_controls": 4,
            "config": dataclasses.asdict(config),
            "step": 10,
            "library_sha256": "another library",
        },
    )
    with pytest.raises(SystemExit, match="(?s)cannot resume.*library_sha256.*delete .*ck.run"):
        train.main(["--out", str(out), "--steps", "20", "--chunk", "10"])
    assert library.file_hash() != "another library"


def test_load_library_names_a_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="build_library"):
        jg.load_library(tmp_path / "none.npz")
    assert sampling.MAX_SAMPLES >= 30  # K_div = 30 fits in one public call


@pytest.mark.parametrize("bad", [np.full((150, 4), "a"), np.zeros((150, 4), complex), [[object()] * 4] * 150])
def test_rollout_refuses_non_real_commands(bad):
    from jgrounding import sim

    with pytest.raises(TypeError, match="real-valued"):
        sim.rollout(bad)


def test_load_library_refuses_a_non_path():
    with pytest.raises(TypeError, match="str or pathlib.Path"):
        jg.load_library(5)
