"""The fast grounding path (#24): bucketed padding, the one-program tuned head, its warm-up."""

import jax
import numpy as np
import pytest

from jgrounding import semantics
from jgrounding.semantics import embedded, encoder, features, structure
from jgrounding.semantics import head as semantic_head
from jgrounding.vocabulary import INTENSITIES, INTENTS

TEXTS = [
    "Nod.",
    "The user looks sad; comfort them gently.",
    "Rather than waving wildly, just give a small nod to show you heard them.",
    'She said "give me a hug" to her brother, not to the robot.',
]


def test_bucketed_padding_gives_the_full_length_result(head):
    params = head.encoder_params()
    structs = [structure.analyse(t) for t in TEXTS]
    (idx, ids, mask, pools), *_ = list(features.encoder_batches(TEXTS[:1], structs[:1]))
    assert ids.shape == (1, encoder.BUCKETS[0])  # a short text alone runs the shortest bucket
    for i, text in enumerate(TEXTS):
        (_, ids, mask, pools), *_ = list(features.encoder_batches([text], [structs[i]]))
        length = ids.shape[1]
        assert length == encoder.bucket_length(int(mask.sum()))
        full = encoder.MAX_TOKENS
        pad = full - length
        ids_f, mask_f = np.pad(ids, ((0, 0), (0, pad))), np.pad(mask, ((0, 0), (0, pad)))
        pools_f = np.pad(pools, ((0, 0), (0, 0), (0, pad)))
        short = np.asarray(encoder.pool_ids(params, ids, mask, pools))
        long = np.asarray(encoder.pool_ids(params, ids_f, mask_f, pools_f))
        np.testing.assert_allclose(short, long, atol=1e-5)


@pytest.mark.parametrize("which", ["head", "head_with_vote"])
def test_one_program_equals_the_encoder_then_the_head(which, request):
    head = request.getfixturevalue(which)  # the shipped head, and with a vote table made for it
    assert (head.knn is not None) or which == "head"
    x = features.head_inputs(head, TEXTS)  # the two-step path the head was trained and calibrated with
    two_step = [np.asarray(a) for a in semantic_head.predict_all(head.params, x, head.temperature)]
    if head.knn is not None:  # then the nearest-neighbour vote, as tools.semantics_knn compared it on dev
        dim = features.EMBED_DIM
        query = x[:, head.knn_pool * dim : (head.knn_pool + 1) * dim]
        vote = semantic_head.knn_blend(
            head.knn["arrays"], two_step[0], two_step[1], query, x[:, features.POOLED_FEATURES :], head.knn_k
        )
        two_step[0], two_step[1] = (np.asarray(a) for a in vote)
    batched = embedded.predict_tuned_many(head, TEXTS)
    alone = [embedded.predict_tuned_many(head, [t]) for t in TEXTS]
    for k in range(3):
        np.testing.assert_allclose(batched[k], two_step[k], atol=1e-5)
        np.testing.assert_allclose(np.concatenate([a[k] for a in alone]), two_step[k], atol=1e-5)
    g = embedded.ground_embedded_many(TEXTS, head=head)
    m, z, _ = semantic_head.decide(two_step[0], two_step[1])
    assert [(x.intent, x.intensity) for x in g] == [(INTENTS[a], INTENSITIES[b]) for a, b in zip(m, z)]


def test_warmup_compiles_every_bucket_a_text_alone_can_use(head):
    semantics.warmup(24)
    before = semantic_head.predict_tuned._cache_size()
    for text in ["Nod.", "Give them a warm, slow hug now because they are upset and alone."]:
        semantics.ground(text, escalate=False)
    assert semantic_head.predict_tuned._cache_size() == before  # nothing traced after the warm-up


def test_grounding_reads_the_stored_matrices(head):
    """The grounding path keeps the layers' dense matrices as encoder.MATRIX_STORAGE says (int8 with a float32
    scale per output column) and widens them inside the program."""
    layers = head.encoder_params()["layers"]
    assert encoder.MATRIX_STORAGE == "int8"
    assert {n: layers[n]["w"].dtype for n in encoder.DENSE} == {n: np.dtype(np.int8) for n in encoder.DENSE}
    assert layers["q"]["s"].dtype == np.float32 and layers["q"]["s"].shape == (head.config.num_encoder_layers, 1, 384)
    assert layers["q"]["b"].dtype == np.float32 and layers["ln1"]["g"].dtype == np.float32


@pytest.mark.parametrize("storage, bound", [("float16", 1e-3), ("int8", 2e-2), ("float32", 1e-6)])
def test_each_storage_gives_the_float32_encoders_vectors_within_its_rounding(storage, bound):
    """Pooled vectors within ``bound`` of the float32 encoder's (int8: a scale per output column, so a column's
    largest weight is exact and the rest round to 1/254 of it); and the stored values widen back to the float32
    weights within the same rounding (encoder.float_matrices, what the PyTorch peer reads)."""
    weights = encoder.load_numpy()
    full = encoder.load_params()
    stored = encoder.stored_matrices(weights, storage)
    back = encoder.float_matrices(stored)
    w, wb = weights["layers"]["ff1"]["w"], back["layers"]["ff1"]["w"]
    step = np.abs(w).max(-2, keepdims=True) / 127.0
    assert np.all(np.abs(wb - w) <= (step / 2 + 1e-7 if storage == "int8" else np.abs(w) * 1e-3 + 1e-7))
    dev = jax.device_put(stored)
    structs = [structure.analyse(t) for t in TEXTS]
    for idx, ids, mask, pools in features.encoder_batches(TEXTS, structs):
        a = np.asarray(encoder.pool_ids(full, ids, mask, pools))
        b = np.asarray(encoder.pool_ids(dev, ids, mask, pools))
        assert np.abs(a - b).max() < bound
        if storage != "float32":
            assert np.abs(a - b).max() > 0  # rounded, and only by rounding


def test_an_unknown_storage_names_the_valid_ones():
    with pytest.raises(ValueError, match="int8, float16, float32"):
        encoder.stored_matrices(encoder.load_numpy(), "bfloat16")


@pytest.mark.parametrize("length", [8, 40])
def test_matmul_flops_counts_what_xla_counts_in_a_layer(head, length):
    # bench semantics divides by encoder.matmul_flops to print the program's arithmetic rate; XLA's own count of
    # one layer (elementwise work included, so a little above ours) must agree with a sixth of it.
    layer = jax.tree.map(lambda a: np.asarray(a[0], np.float32), head.encoder_params()["layers"])
    x = np.zeros((1, length, encoder.HIDDEN), np.float32)
    bias = np.zeros((1, 1, 1, length), np.float32)
    cost = jax.jit(encoder.block).lower(x, bias, layer).compile().cost_analysis()
    cost = cost[0] if isinstance(cost, list) else cost
    ours = encoder.matmul_flops(length) / encoder.NUM_LAYERS
    assert ours <= cost["flops"] <= 1.1 * ours
