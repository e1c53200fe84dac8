"""The PyTorch peer of our JAX all-MiniLM-L6-v2 encoder (run by ``python -m experiments.bench_semantics`` in
.venv-peer; imports only torch, numpy and the standard library, never the package).

``python experiments/peer_torch_encoder.py WEIGHTS.npz OUT.json [--modes eager,eager_padded] [--reps 3]``: rebuilds
the encoder jg.ground runs from the arrays experiments/bench_semantics.py exported (``bench_semantics.export_peer``:
the JAX parameter tree flattened with ``/``, the six layers stacked on a leading axis, matrices ``(in, out)``) as
Hugging Face's ``BertModel`` is built (``nn.Embedding``, ``nn.Linear``, ``nn.LayerNorm`` with eps 1e-12, exact GELU,
``scaled_dot_product_attention`` with no mask when every token is real, as its default "sdpa" attention does), then
mean pooling over the attention mask and L2 normalisation, as sentence-transformers' ``Pooling`` and ``Normalize``
modules do. It is timed as a user of sentence-transformers runs it: ``model.eval()``, ``torch.inference_mode()``, one
text per call, the tensors made before the timing. Tokenization is not included: the torch environment has no
tokenizer, so the token ids and masks come from our tokenizer (in the .npz).

Modes (each the texts once to warm up, then ``reps`` passes; per text the median of its passes):

- ``eager``: each text at its own token count (no padding, as ``SentenceTransformer.encode`` pads one text);
- ``eager_padded``: each text padded to our token bucket with its mask (the shapes our encoder runs);
- ``compile``: ``torch.compile(model, dynamic=True)`` at the texts' own token counts (one graph for every length;
  the first call's compile time is reported).

Writes OUT.json: per mode the per-text milliseconds, their median, the embeddings (the parity check), and the
torch version and thread counts.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch
import torch.nn.functional as F


class MiniLM(torch.nn.Module):
    """BERT (embeddings + LayerNorm, ``layers`` x (self-attention + FFN with GELU)), mean pooling, L2 norm."""

    def __init__(self, w: dict, num_heads: int, eps: float):
        super().__init__()
        vocab, hidden = w["word"].shape
        self.num_heads, self.hidden = num_heads, hidden
        self.word = torch.nn.Embedding(vocab, hidden)
        self.pos = torch.nn.Embedding(w["pos"].shape[0], hidden)
        self.token_type = torch.nn.Embedding(w["type"].shape[0], hidden)
        self.ln = torch.nn.LayerNorm(hidden, eps=eps)
        num_layers = w["layers/ff1/w"].shape[0]

        def linear(prefix, i):
            kernel = w[f"layers/{prefix}/w"][i]
            lin = torch.nn.Linear(*kernel.shape)
            lin.weight.data = torch.from_numpy(np.ascontiguousarray(kernel.T))  # (out, in), as nn.Linear keeps it
            lin.bias.data = torch.from_numpy(np.ascontiguousarray(w[f"layers/{prefix}/b"][i]))
            return lin

        def norm(prefix, i):
            ln = torch.nn.LayerNorm(hidden, eps=eps)
            ln.weight.data = torch.from_numpy(np.ascontiguousarray(w[f"layers/{prefix}/g"][i]))
            ln.bias.data = torch.from_numpy(np.ascontiguousarray(w[f"layers/{prefix}/b"][i]))
            return ln

        self.layers = torch.nn.ModuleList()
        for i in range(num_layers):
            layer = torch.nn.Module()
            for name in ("q", "k", "v", "o", "ff1", "ff2"):
                setattr(layer, name, linear(name, i))
            layer.ln1, layer.ln2 = norm("ln1", i), norm("ln2", i)
            self.layers.append(layer)
        for emb, key in ((self.word, "word"), (self.pos, "pos"), (self.token_type, "type")):
            emb.weight.data = torch.from_numpy(np.ascontiguousarray(w[key]))
        self.ln.weight.data = torch.from_numpy(np.ascontiguousarray(w["ln/g"]))
        self.ln.bias.data = torch.from_numpy(np.ascontiguousarray(w["ln/b"]))
        self.register_buffer("position_ids", torch.arange(w["pos"].shape[0])[None], persistent=False)

    def forward(self, ids: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        b, t = ids.shape
        h, d = self.num_heads, self.hidden // self.num_heads
        x = self.word(ids) + self.token_type(torch.zeros_like(ids)) + self.pos(self.position_ids[:, :t])
        x = self.ln(x)
        # Hugging Face's sdpa path drops an all-ones mask in eager mode (and keeps it when compiled).
        if not torch.compiler.is_compiling() and bool(mask.all()):
            bias = None
        else:
            bias = (1.0 - mask[:, None, None, :].to(x.dtype)) * torch.finfo(x.dtype).min
        for layer in self.layers:

            def heads(y):
                return y.view(b, t, h, d).transpose(1, 2)

            q, k, v = heads(layer.q(x)), heads(layer.k(x)), heads(layer.v(x))
            ctx = F.scaled_dot_product_attention(q, k, v, attn_mask=bias)
            ctx = ctx.transpose(1, 2).reshape(b, t, self.hidden)
            x = layer.ln1(x + layer.o(ctx))
            x = layer.ln2(x + layer.ff2(F.gelu(layer.ff1(x))))
        m = mask[..., None].to(x.dtype)
        pooled = (x * m).sum(1) / m.sum(1).clamp(min=1e-9)
        return F.normalize(pooled, p=2, dim=1)


def inputs(w: dict, padded: bool) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """One ``(ids, mask)`` pair of shape ``(1, L)`` per exported text: L its token count, or with ``padded`` its
    bucket (what our encoder runs)."""
    out = []
    for i, (n, bucket) in enumerate(zip(w["lengths"], w["buckets"])):
        length = int(bucket if padded else n)
        ids = torch.from_numpy(np.ascontiguousarray(w["ids"][i : i + 1, :length], np.int64))
        mask = torch.from_numpy(np.ascontiguousarray(w["mask"][i : i + 1, :length], np.int64))
        out.append((ids, mask))
    return out


def time_model(model, pairs, reps: int) -> tuple[list[float], np.ndarray]:
    """Per text: the median milliseconds of ``reps`` calls (after one warm-up pass), and the embeddings."""
    with torch.inference_mode():
        emb = np.stack([model(ids, mask)[0].numpy() for ids, mask in pairs])  # warm-up pass, and the parity output
    times = np.zeros((reps, len(pairs)))
    for r in range(reps):
        for j, (ids, mask) in enumerate(pairs):
            t0 = time.perf_counter()
            with torch.inference_mode():
                model(ids, mask)
            times[r, j] = time.perf_counter() - t0
    return (1e3 * np.median(times, axis=0)).tolist(), emb


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("weights")
    p.add_argument("out")
    p.add_argument("--modes", default="eager,eager_padded", help="comma-separated: eager, eager_padded, compile")
    p.add_argument("--reps", type=int, default=3)
    args = p.parse_args(argv)
    with np.load(args.weights) as f:
        w = {k: f[k] for k in f.files}
    torch.manual_seed(0)
    model = MiniLM(w, int(w["num_heads"]), float(w["ln_eps"])).eval()
    result = {
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
        "interop_threads": torch.get_num_interop_threads(),
        "cpu_capability": torch.backends.cpu.get_cpu_capability(),  # the ISA ATen's kernels dispatch to
        "n": len(w["lengths"]),
        "tokenization": "not included (token ids and masks from our tokenizer, exported by the JAX side)",
        "modes": {},
    }
    for mode in args.modes.split(","):
        pairs = inputs(w, padded=mode == "eager_padded")
        fn, info = model, {}
        if mode == "compile":
            fn = torch.compile(model, dynamic=True)
            t0 = time.perf_counter()
            with torch.inference_mode():
                fn(*pairs[0])
            info["compile_s"] = time.perf_counter() - t0
        elif mode not in ("eager", "eager_padded"):
            raise SystemExit(f"unknown mode {mode!r}")
        t0 = time.perf_counter()
        ms, emb = time_model(fn, pairs, args.reps)
        info |= {
            "ms": ms,
            "ms_median": float(np.median(ms)),
            "seconds": time.perf_counter() - t0,
            "embeddings": emb.tolist(),
        }
        result["modes"][mode] = info
        extra = f" (compile {info['compile_s']:.1f} s)" if "compile_s" in info else ""
        print(f"torch {mode}: {info['ms_median']:.2f} ms median over {len(ms)} texts{extra}", flush=True)
    with open(args.out, "w") as f:
        json.dump(result, f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
