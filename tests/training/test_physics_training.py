"""Physics-aware fine-tuning: screened candidates refill rejected slots; the fine-tuned RF keeps its shapes."""

import jax
import numpy as np
import pytest

from jgrounding.generators.trained import Trained
from jgrounding.training import physics as pt
from jgrounding.training import trainer


def test_refill_keeps_tuples_balanced_and_drops_every_rejected_candidate():
    controls = np.arange(2 * 3 * 1, dtype=np.float32).reshape(2, 3, 1)  # tuple 0: 0, 1, 2; tuple 1: 3, 4, 5
    keep = np.array([[True, False, True], [False, False, False]])
    lib = {0: np.array([[10.0]]), 1: np.array([[20.0], [21.0]])}
    out = pt.refill(keep, controls, lib, np.random.default_rng(0))
    assert out[0, 0, 0] == 0 and out[0, 2, 0] == 2 and out[0, 1, 0] in (0, 2)  # a kept sample of tuple 0
    assert set(out[1, :, 0]) <= {20.0, 21.0}  # none kept: the tuple's library realizations


@pytest.mark.slow
def test_finetune_runs_every_seed_and_reports_the_screen():
    from jgrounding import load_library, semantics
    from jgrounding.training import TrainConfig

    lib, emb = load_library(), semantics.intent_embeddings()
    rf = trainer.fit("tuple_spline_rf", lib, (0, 1), TrainConfig(steps=20, chunk=20), intent_emb=emb, progress=False)
    cfg = pt.PhysicsConfig(rounds=1, candidates=2, steps=5)
    ft, report = pt.finetune(rf, lib, jax.random.key(0), intent_emb=emb, physics=cfg)
    assert jax.tree.structure(ft.params) == jax.tree.structure(rf.params) and ft.seeds == (0, 1)
    assert report[0]["simulated"] == 2 * 64 * 2 and 0 <= report[0]["kept"] <= report[0]["feasible"] <= 1
    changed = jax.tree.leaves(jax.tree.map(lambda a, b: bool(np.any(a != b)), ft.params, rf.params))
    assert any(changed)
    with pytest.raises(ValueError, match="tuple_spline_rf"):
        pt.finetune(Trained("tuple_spline_cnn", None, None, (0,), 4), lib, jax.random.key(0), intent_emb=emb)
