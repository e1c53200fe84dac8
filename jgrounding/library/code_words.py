"""The library designs' code words, stored as data: ``jgrounding/assets/designs/code_v<version>.json``.

A design's code gives every (intent, variant, intensity) its key poses: 4 tendons (toward, left, away, right) x 4 key
moments (rest first), 0 slack .. 1 the largest safe pull, rounded to two decimals. Version 3's code holds each
variant's two ends (subtle, emphatic; ``python -m tools.design_signatures`` writes it, and
:data:`jgrounding.library.primitives.CODE` reads it); versions 4 and 5 hold every intensity of up to three variants,
with how many variants each intent has (``python -m tools.design_library [--version 5]`` writes them, and
:mod:`jgrounding.library.designs` reads them). :func:`render` is the one writer and :func:`load` the one reader; a
file holds the two-decimal numbers its tool printed, so a design regenerates it byte for byte.
"""

from __future__ import annotations

import dataclasses
import functools
import json

import numpy as np

from jgrounding.io import asset
from jgrounding.vocabulary import INTENTS

VERSIONS = (3, 4, 5)
WRITERS = {
    3: "python -m tools.design_signatures --write",
    4: "python -m tools.design_library --write",
    5: "python -m tools.design_library --version 5 --write",
}
AXES = {
    3: "code[intent][variant][end][tendon][key moment]: end 0 = subtle, 1 = emphatic",
    4: "code[intent][variant][intensity][tendon][key moment]: variants an intent does not have are zero",
    5: "code[intent][variant][intensity][tendon][key moment]: variants an intent does not have are zero",
}


@dataclasses.dataclass(frozen=True)
class CodeWords:
    """One design's code ``(16, V, E, 4, 4)`` and, for versions 4 and 5, each intent's number of valid variants."""

    version: int
    code: np.ndarray
    num_variants: dict[str, int] | None


def path(version: int):
    if version not in VERSIONS:
        raise ValueError(f"no stored code for library version {version!r}; valid: {VERSIONS}")
    return asset("designs", f"code_v{version}.json")


@functools.lru_cache(maxsize=len(VERSIONS))
def load(version: int) -> CodeWords:
    """The stored code of library ``version`` (one of :data:`VERSIONS`)."""
    data = json.loads(path(version).read_text())
    if data.get("version") != version or data.get("intents") != list(INTENTS):
        raise ValueError(f"{path(version)} holds version {data.get('version')}'s code or other intents; regenerate it")
    code = np.array(data["code"], dtype=np.float64)
    code.setflags(write=False)
    return CodeWords(version, code, data.get("num_variants"))


def render(version: int, code: np.ndarray, num_variants: dict[str, int] | None = None) -> str:
    """The JSON text of a design's code: one line per key-pose matrix (``code[m][v][e]``, 4 tendons x 4 moments),
    numbers with two decimals, so that the file reads as the tool printed it."""
    code = np.asarray(code)
    if code.shape[0] != len(INTENTS) or code.shape[-2:] != (4, 4):
        raise ValueError(f"a code is ({len(INTENTS)}, variants, intensities, 4, 4), got {code.shape}")
    head = [
        "{",
        f'  "version": {version},',
        f'  "written_by": {json.dumps(WRITERS[version])},',
        f'  "axes": {json.dumps(AXES[version])},',
        f'  "intents": {json.dumps(list(INTENTS))},',
    ]
    if num_variants is not None:
        head.append(f'  "num_variants": {json.dumps({m: int(num_variants[m]) for m in INTENTS})},')
    intents = []
    for m in range(code.shape[0]):
        variants = []
        for v in range(code.shape[1]):
            poses = [
                "[" + ", ".join("[" + ", ".join(f"{x:.2f}" for x in row) + "]" for row in code[m, v, e]) + "]"
                for e in range(code.shape[2])
            ]
            variants.append("      [\n" + ",\n".join(f"        {p}" for p in poses) + "\n      ]")
        intents.append("    [\n" + ",\n".join(variants) + "\n    ]")
    return "\n".join(head) + '\n  "code": [\n' + ",\n".join(intents) + "\n  ]\n}\n"
