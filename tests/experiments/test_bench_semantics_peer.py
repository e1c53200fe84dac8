"""bench semantics' PyTorch peer, without torch: the exported weights, the FLOP count, the parity check and the
results file's peer block (experiments/bench_semantics.py; the peer itself runs in .venv-peer, not on CI)."""

import json

import jax
import numpy as np
import pytest

from experiments import bench_semantics_peer as bench
from jgrounding.semantics import encoder


def test_export_writes_every_encoder_weight_with_its_shape_and_our_tokens(tmp_path):
    params = encoder.stored_matrices(encoder.load_numpy())  # as grounding keeps them: int8 matrices and scales
    texts = ["Wave hello.", "The user looks sad; comfort them gently and slowly, please, right now."]
    path = tmp_path / "w.npz"
    tokens = bench.export_peer(params, texts, path)
    with np.load(path) as f:
        saved = {k: f[k] for k in f.files}
    leaves = jax.tree_util.tree_leaves_with_path(params)
    assert len(leaves) == 27  # word, pos, type, the LayerNorm's two, the layers' 16 stacked arrays, 6 scales
    values = encoder.float_matrices(params)
    for keys, leaf in jax.tree_util.tree_leaves_with_path(values):
        name = "/".join(k.key for k in keys)
        assert saved[name].shape == leaf.shape and saved[name].dtype == np.float32, name
        np.testing.assert_array_equal(saved[name], np.asarray(leaf, np.float32))  # widened, scales applied
    assert not any(k.endswith("/s") for k in saved)  # the peer reads plain float32 matrices
    assert saved["layers/ff1/w"].shape == (encoder.NUM_LAYERS, encoder.HIDDEN, encoder.INTERMEDIATE)
    assert int(saved["num_heads"]) == encoder.NUM_HEADS and float(saved["ln_eps"]) == encoder.LN_EPS
    for i, text in enumerate(texts):
        ids, mask, n = bench.tokenize_one(text)
        assert saved["lengths"][i] == n and saved["buckets"][i] == ids.shape[1] == encoder.bucket_length(n)
        np.testing.assert_array_equal(saved["ids"][i, : ids.shape[1]], ids[0])
        assert saved["mask"][i].sum() == n and not saved["ids"][i, n:].any()
    assert saved["lengths"][0] < saved["lengths"][1] and tokens["ids"].shape == saved["ids"].shape


def test_flop_count_of_a_tiny_encoder_and_of_minilm():
    # hidden 4, FFN 8, 2 layers, 3 tokens: per token 4 * 4 * 4 + 2 * 4 * 8 = 128 multiply-adds in the dense
    # products, attention 2 * 3 * 3 * 4 = 72 per text and layer: 2 * (3 * 128 + 72) = 912 FLOPs a layer.
    assert bench.encoder_flops(3, hidden=4, intermediate=8, layers=2) == 1824
    assert bench.encoder_flops(1, hidden=1, intermediate=1, layers=1) == 2 * (6 + 2)
    for length in (8, 20, 256):
        assert bench.encoder_flops(length) == encoder.matmul_flops(length)


def test_parity_passes_on_equal_embeddings_and_raises_on_a_mismatch():
    rng = np.random.default_rng(0)
    emb = rng.standard_normal((5, 384)).astype(np.float32)
    emb /= np.linalg.norm(emb, axis=1, keepdims=True)
    assert bench.check_parity(emb, emb.copy()) == pytest.approx(1.0)
    assert bench.check_parity(emb, 3.0 * emb) == pytest.approx(1.0)  # a cosine, not a distance
    noisy = emb + 1e-3 * rng.standard_normal(emb.shape)
    assert 0.999 < bench.check_parity(emb, noisy) < 1.0
    bad = emb.copy()
    bad[3] = rng.standard_normal(384)
    with pytest.raises(bench.ParityError, match=r"1 of 5 texts .*text 3"):
        bench.check_parity(emb, bad)
    nan = emb.copy()
    nan[1, 0] = np.nan
    with pytest.raises(bench.ParityError, match="text 1"):
        bench.check_parity(emb, nan)
    with pytest.raises(bench.ParityError, match="shape"):
        bench.check_parity(emb, emb[:4])


def test_the_peer_section_is_replaced_or_added_and_the_rest_of_the_results_kept(tmp_path):
    md, js = tmp_path / "bench_semantics.md", tmp_path / "bench_semantics.json"
    head, tail = "#### v2 test\n\n| a | b |\n|---|---|\n| 1 | 2 |\n", "\nRisk-coverage curves: x.png\n"
    md.write_text(head + tail)
    js.write_text(json.dumps({"metrics": {"new|v2 test|all": {"intent": 0.9}}, "latency": {"new": 1.0}}))

    def block(x):
        return f"{bench.PEER_START}\n\npeer {x} ms\n\n{bench.PEER_END}"

    bench.write_peer_section(md, js, block(1), {"ms": 1})
    assert md.read_text() == head + tail + "\n" + block(1) + "\n"
    bench.write_peer_section(md, js, block(2), {"ms": 2})  # replaced in place, once
    text = md.read_text()
    assert text == head + tail + "\n" + block(2) + "\n" and text.count(bench.PEER_START) == 1
    data = json.loads(js.read_text())
    assert data == {"metrics": {"new|v2 test|all": {"intent": 0.9}}, "latency": {"new": 1.0}, "peer": {"ms": 2}}
    assert bench.kept_peer(md, js) == (block(2), {"ms": 2})
    # A block in the middle of the file (a full run writes its tables, then the block) stays where it is.
    md.write_text(head + block(3) + tail)
    bench.write_peer_section(md, js, block(4), {"ms": 4})
    assert md.read_text() == head + block(4) + tail
    # A full run keeps a previous block in the text it writes; no block, no markers.
    assert bench.with_peer_block(head, block(5)) == head + "\n" + block(5) + "\n"
    assert bench.kept_peer(tmp_path / "none.md", tmp_path / "none.json") == (None, None)


def test_the_peer_sample_is_spread_over_both_splits_and_fixed():
    splits = {"a": [{"text": f"a{i}"} for i in range(10)], "b": [{"text": f"b{i}"} for i in range(10)]}
    sample = bench.peer_sample(splits, 5)
    assert sample == ["a0", "a5", "b0", "b4", "b9"] and bench.peer_sample(splits, 5) == sample
    assert bench.peer_sample(splits, 50) == [*(f"a{i}" for i in range(10)), *(f"b{i}" for i in range(10))]


def test_the_speed_goal_is_judged_on_avx2_or_on_the_ratio_to_the_same_weights(monkeypatch):
    rows = {"jg_ground": {"ms_median": 4.0}, "torch_eager": {"ms_median": 9.0}}
    monkeypatch.setattr(bench, "cpu_isa", lambda: "avx512f")
    monkeypatch.delenv("XLA_FLAGS", raising=False)
    line = bench.speed_goal_line(rows)
    assert "5 ms goal not met" in line and "2.25x (goal 2x: met)" in line and "Goal met" in line
    rows["torch_eager"]["ms_median"] = 6.0
    assert "Goal not met" in bench.speed_goal_line(rows)
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_max_isa=AVX2")
    assert "5 ms goal met" in bench.speed_goal_line(rows)
    rows["torch_eager_minilm6"] = {"ms_median": 12.0}
    assert "six-layer MiniLM a user would run instead 3.00x" in bench.speed_goal_line(rows)


def test_the_peer_is_limited_to_the_isa_xla_is_limited_to():
    """With XLA_FLAGS --xla_cpu_max_isa=AVX2 the peer's ATen kernels, oneDNN and MKL are held to AVX2 too (an
    AVX-512 machine would otherwise compare its AVX-512 PyTorch with our AVX2); unlimited, nothing is set."""
    env = bench.peer_isa_env("--xla_force_host_platform_device_count=1 --xla_cpu_max_isa=AVX2")
    assert env == {"ATEN_CPU_CAPABILITY": "avx2", "ONEDNN_MAX_CPU_ISA": "AVX2", "MKL_ENABLE_INSTRUCTIONS": "AVX2"}
    assert bench.peer_isa_env("") == {} and bench.peer_isa_env("--xla_cpu_multi_thread_eigen=false") == {}
