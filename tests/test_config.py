"""Configs (issue #12): Table I defaults, model sizes that reach the networks and every checkpoint."""

import dataclasses
import json

import jax
import numpy as np
import pytest

import jgrounding as jg
from jgrounding import config, training
from jgrounding.generators import methods
from jgrounding.policy.sampling import DEFAULT_CHECKPOINT
from jgrounding.training import checkpoints, trainer


def test_defaults_are_table_one():
    m, t, s = config.get("paper").model, config.get("paper").train, config.get("paper").sample
    assert (m.width, m.depth, m.time_dim, m.cnn_channels) == (256, 4, 128, 64)
    assert (t.steps, t.batch_size, t.learning_rate) == (10_000, 8, 1e-3)
    assert (s.sampler, s.steps, s.guidance) == (None, 50, 0.0)  # None: each generator's default sampler
    assert (t.ema_decay, t.time_sampler, t.condition_dropout) == (0.0, "uniform", 0.0)  # options off


def test_unknown_names_and_bad_sizes_are_refused_with_the_choices():
    with pytest.raises(ValueError, match="valid: paper"):
        config.get("papr")
    with pytest.raises(ValueError, match="ModelConfig.width"):
        config.ModelConfig(width=0)
    with pytest.raises(ValueError, match="euler, midpoint, rk4, ancestral, ddim, none"):
        config.SampleConfig(sampler="heun")


def test_model_sizes_reach_the_network():
    small = config.ModelConfig(width=32, depth=3, time_dim=16)
    model = methods.build_model("tuple_spline_rf", 4, jax.random.key(0), 4, small)
    assert model.l1.kernel.value.shape == (16 + 16 + 384 + 64, 32) and model.l3.kernel.value.shape == (32, 16)
    assert not hasattr(model, "l4")
    cnn = methods.build_model(
        "tuple_dense_cnn", 4, jax.random.key(0), 4, dataclasses.replace(small, dense_cnn_channels=8)
    )
    assert cnn.c1.w.value.shape == (5, 8, 8)


def test_checkpoint_records_model_sizes_and_restores_them(tmp_path):
    small = config.ModelConfig(width=32, depth=3)
    tr = trainer.fit(
        "tuple_spline_rf", jg.load_library(), (0,), training.TrainConfig(steps=2, chunk=2), progress=False, model=small
    )
    checkpoints.save(tmp_path / "ck", tr.params, checkpoints.meta_of(tr))
    assert json.loads((tmp_path / "ck" / "meta.json").read_text())["model"]["width"] == 32
    back = checkpoints.restore_trained(tmp_path / "ck")
    assert back.model == small
    same = jax.tree.map(lambda a, b: bool(np.array_equal(a, b)), back.params, tr.params)
    assert all(jax.tree.leaves(same))


def test_a_checkpoint_without_sizes_loads_with_table_one_sizes_or_is_refused(tmp_path):
    meta = checkpoints.read_meta(DEFAULT_CHECKPOINT)
    old = checkpoints.restore_trained(DEFAULT_CHECKPOINT)  # written before sizes were recorded
    assert "model" in meta or old.model == config.ModelConfig()
    tr = trainer.fit(
        "tuple_spline_rf",
        jg.load_library(),
        (0,),
        training.TrainConfig(steps=1, chunk=1),
        progress=False,
        model=config.ModelConfig(width=32),
    )
    checkpoints.save(tmp_path / "old", tr.params, {k: v for k, v in checkpoints.meta_of(tr).items() if k != "model"})
    with pytest.raises(ValueError, match="shape"):  # its arrays do not fit Table I's sizes
        checkpoints.restore_trained(tmp_path / "old")
    checkpoints.save(tmp_path / "odd", tr.params, {**checkpoints.meta_of(tr), "model": {"width": 32, "heads": 2}})
    with pytest.raises(ValueError, match="not a ModelConfig"):
        checkpoints.restore_trained(tmp_path / "odd")


def test_named_entries_open_with_their_command_and_overrides_name_the_choices():
    for name, entry in config.CONFIGS.items():
        assert entry.__doc__.startswith("``python -m experiments.ablation"), name  # the command it serves
        assert "Gives" in entry.__doc__, name  # ... and the result it should give
    quick = config.get("quick", ["train.steps=20", "eval.seeds=0,3", "eval.library=none", "sample.guidance=0.5"])
    assert (quick.train.steps, quick.eval.seeds, quick.eval.library, quick.sample.guidance) == (20, (0, 3), None, 0.5)
    assert quick.eval.num_samples == config.quick().eval.num_samples  # the rest of the entry is kept
    assert config.from_dict(json.loads(json.dumps(config.to_dict(quick)))) == quick  # what results record
    for bad, why in (
        ("train.stepz=3", "no field 'stepz'; valid: steps, batch_size"),
        ("trian.steps=3", "no field 'trian'; valid: model, train, sample, physics, eval"),
        ("train=3", "is a section; set one of its fields: train.steps"),
        ("train.steps=many", "TrainConfig.steps must be an integer"),
        ("sample.sampler=heun", "SampleConfig.sampler must be one of euler"),
        ("steps", "section.field=value"),
    ):
        with pytest.raises(ValueError, match=why):
            config.get("paper", [bad])


def test_the_sampler_default_is_each_generators_own_and_a_foreign_one_is_refused():
    rf = trainer.fit("tuple_spline_rf", jg.load_library(), (0,), training.TrainConfig(steps=1, chunk=1), progress=False)
    assert rf.resolve(config.SampleConfig()).sampler == "euler"
    ddpm = dataclasses.replace(rf, method="tuple_spline_ddpm")  # resolve reads only the registry entry
    assert ddpm.resolve(config.SampleConfig()).sampler == "ancestral"
    with pytest.raises(ValueError, match="unknown sampler 'euler' for tuple_spline_ddpm; valid: ancestral, ddim"):
        ddpm.resolve(config.SampleConfig(sampler="euler"))  # was silently replaced by ancestral
