"""The PyTorch peer of ``jg.sample`` at S = 50 (run by experiments/bench_peer.py in .venv-peer; imports only
torch and numpy, never the package).

``python experiments/peer_torch.py WEIGHTS.npz OUT.json``: rebuilds the shipped rectified flow from the
exported arrays (the velocity MLP of Table I, the condition's and time's shares of its first layer
computed once per call as jg.sample does, classifier-free guidance w with the null condition in the same
batch, Euler over S steps, decode, Catmull-Rom reconstruction, clamp to [0, 1]) and times it eager and
under ``torch.compile``: one trajectory per call (median of ``reps``) and 1,920 per call (64 tuples x 30).
The slew-limit part of the gate is left out of the peer (it would only slow it). Writes the times, and
its output for the exported noise (the parity check against JAX), to OUT.json.
"""

from __future__ import annotations

import json
import math
import sys
import time

import numpy as np
import torch


class Peer(torch.nn.Module):
    def __init__(self, w: dict):
        super().__init__()
        t = {k: torch.from_numpy(np.ascontiguousarray(v)) for k, v in w.items()}
        self.intent_emb, self.intensity_emb = t["intent_emb"], t["intensity_emb"]
        self.w_x, self.w_t, self.w_c, self.b1 = t["w_x"], t["w_t"], t["w_c"], t["b1"]
        self.hidden = [(t[f"w{i}"], t[f"b{i}"]) for i in range(2, int(w["depth"]) + 1)]
        self.basis = t["basis"]  # (T, P)
        self.steps, self.guidance = int(w["steps"]), float(w["guidance"])
        self.num_tendons, self.time_dim = int(w["num_tendons"]), self.w_t.shape[0]

    def time_context(self) -> torch.Tensor:
        t = torch.arange(self.steps, dtype=torch.float32) / self.steps
        half = self.time_dim // 2
        freqs = torch.exp(-math.log(10_000.0) * torch.arange(half, dtype=torch.float32) / half)
        ang = 1000.0 * t[:, None] * freqs
        return torch.cat([torch.sin(ang), torch.cos(ang)], dim=-1) @ self.w_t  # (S, W)

    def head(self, h: torch.Tensor) -> torch.Tensor:
        h = torch.nn.functional.silu(h)
        for i, (w, b) in enumerate(self.hidden):
            h = h @ w + b
            if i < len(self.hidden) - 1:
                h = torch.nn.functional.silu(h)
        return h

    def forward(self, intent: torch.Tensor, intensity: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
        b = eps.shape[0]
        cond = torch.cat([self.intent_emb[intent], self.intensity_emb[intensity]], dim=-1)
        ctx = cond @ self.w_c + self.b1
        w = self.guidance
        if w:
            ctx = torch.cat([ctx, self.b1.expand(b, -1)])  # the null condition's rows
        tctx = self.time_context()
        x, dt = eps, 1.0 / self.steps
        for k in range(self.steps):
            xin = torch.cat([x, x]) if w else x
            v = self.head(xin @ self.w_x + tctx[k] + ctx)
            if w:
                v = v[:b] + w * (v[:b] - v[b:])
            x = x + dt * v
        c = (0.5 * (x + 1.0)).reshape(b, self.num_tendons, -1)  # (B, N_u, P)
        u = torch.einsum("tp,bjp->btj", self.basis, c)
        return u.clamp(0.0, 1.0)


def _median_ms(call, reps: int) -> float:
    call()
    call()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def main(argv) -> int:
    weights, out = argv[0], argv[1]
    reps, batch_reps = int(argv[2]) if len(argv) > 2 else 200, int(argv[3]) if len(argv) > 3 else 5
    w = dict(np.load(weights))
    torch.manual_seed(0)
    peer = Peer(w).eval()
    intent, intensity = torch.from_numpy(w["intent"]).long(), torch.from_numpy(w["intensity"]).long()
    dim = w["w_x"].shape[0]
    k = int(w["per_tuple"])
    rows_m, rows_z = intent.repeat_interleave(k), intensity.repeat_interleave(k)
    result = {"torch": torch.__version__, "threads": torch.get_num_threads()}
    with torch.no_grad():
        result["parity_u"] = peer(intent[:4], intensity[:4], torch.from_numpy(w["parity_eps"])).numpy().tolist()

        def run(fn, tag):
            i = iter(range(10**9))

            def single():
                j = next(i) % len(intent)
                return fn(intent[j : j + 1], intensity[j : j + 1], torch.randn(1, dim))

            result[f"{tag}_single_ms"] = _median_ms(single, reps)
            result[f"{tag}_batch_ms"] = _median_ms(
                lambda: fn(rows_m, rows_z, torch.randn(len(rows_m), dim)), batch_reps
            )
            print(
                f"torch {tag}: single {result[f'{tag}_single_ms']:.3f} ms, {len(rows_m)}: "
                f"{result[f'{tag}_batch_ms']:.1f} ms",
                flush=True,
            )

        run(peer, "eager")
        t0 = time.perf_counter()
        compiled = torch.compile(peer, dynamic=False)
        compiled(intent[:1], intensity[:1], torch.randn(1, dim))
        compiled(rows_m, rows_z, torch.randn(len(rows_m), dim))
        result["compile_s"] = time.perf_counter() - t0
        run(compiled, "compiled")
    with open(out, "w") as f:
        json.dump(result, f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
