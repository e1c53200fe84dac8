"""The imported library's arrays and its card (what was imported, split, rejected, dropped, clipped and
noted, and the hashes of the sources), for :func:`jgrounding.library.save`."""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path

import numpy as np

from jgrounding.config import NUM_STEPS  # T of Table I
from jgrounding.library.build import FORMAT_VERSION, content_hash
from jgrounding.library.importer.manifest import tuple_name
from jgrounding.vocabulary import describe

LIBRARY_VERSION = "imported-1"  # an imported library's content version (the built-in one has its own)
TRUNK_TENDONS = 4  # the built-in simulator's trunk


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _texts(kept: list, order: list[int]) -> tuple[list[list[str]], list[str]]:
    """(``(N, n_texts)`` response texts, each list cycled to the longest; the files that gave none and so
    get their tuple's description)."""
    n_texts = max([len(kept[i].texts) for i in order] + [1])
    texts, described = [], []
    for i in order:
        t = kept[i].texts or (describe(kept[i].intent, kept[i].intensity),)
        if not kept[i].texts:
            described.append(kept[i].file)
        texts.append([t[k % len(t)] for k in range(n_texts)])
    return texts, described


def arrays(kept, order, heldout, realization, u, controls, intent) -> dict:
    """The library's record arrays, in ``order``, with its version and content hash."""
    out = {
        "u": u[order].astype(np.float32),
        "controls": controls[order].astype(np.float32),
        "intent": intent[order],
        "intensity": np.array([kept[i].intensity for i in order], np.int32),
        "realization": np.array([realization[i] for i in order], np.int32),
        "heldout": np.array(heldout, bool),
        "texts": np.asarray(_texts(kept, order)[0], dtype=np.str_),
        "source": np.asarray([kept[i].file for i in order], dtype=np.str_),
    }
    out["library_version"] = np.asarray(LIBRARY_VERSION)
    out["content_sha256"] = np.asarray(content_hash(out))
    return out


def _physics_note(config) -> list[str]:
    if config.simulate:
        return []
    if config.num_tendons == TRUNK_TENDONS:
        why = "pass --simulate if these are recordings of the built-in trunk model"
    else:
        why = f"the built-in simulator is the {TRUNK_TENDONS}-tendon trunk, these data have N_u = {config.num_tendons}"
    return [f"physics skipped: {why}"]


def card(
    arrays,
    *,
    config,
    kept,
    recs,
    order,
    screening_names,
    rejected,
    dropped,
    num_dropped,
    folder,
    manifest,
    marker_map=None,
) -> dict:
    """The card of an imported library (``dropped``: every problem left out; ``num_dropped``: the files;
    ``markers``: the motion-capture markers the recordings hold, checked but not part of the library's arrays)."""
    counts = {}
    for k, i in enumerate(order):
        c = counts.setdefault(tuple_name(kept[i].intent, kept[i].intensity), {"train": 0, "heldout": 0})
        c["heldout" if arrays["heldout"][k] else "train"] += 1
    return {
        "format_version": FORMAT_VERSION,
        "library_version": LIBRARY_VERSION,
        "content_sha256": str(arrays["content_sha256"]),
        "source": "import",
        "config": {**dataclasses.asdict(config), "limits": [list(p) for p in config.limits]},
        "num_tendons": config.num_tendons,
        "channels": list(recs[0].columns),  # the tendon columns' names, in the order of the limits
        "num_steps": NUM_STEPS,
        "num_controls": int(arrays["controls"].shape[-1]),
        "reduced": config.num_controls is not None,
        "screening": screening_names + _physics_note(config),
        "num_records": len(order),
        "num_train": int((~arrays["heldout"]).sum()),
        "num_heldout": int(arrays["heldout"].sum()),
        "counts_per_tuple": counts,
        "rejected": rejected,
        "dropped": [p.as_dict() for p in dropped],
        "num_dropped": num_dropped,
        "tolerance": config.tolerance,
        "clipped": {kept[i].file: recs[i].clipped for i in order if recs[i].clipped},
        "notes": {kept[i].file: list(recs[i].notes) for i in range(len(kept)) if recs[i].notes},
        "texts_default_description": _texts(kept, order)[1],
        "durations_s": {kept[i].file: round(float(recs[i].time[-1] - recs[i].time[0]), 6) for i in range(len(kept))},
        "markers": None
        if marker_map is None
        else {
            "names": list(marker_map.names),
            "s_m": [float(x) for x in marker_map.s],
            "units": marker_map.units,
            "max_gap_s": marker_map.max_gap_s,
        },
        "manifest": {"file": manifest.name, "sha256": _sha256(manifest)},
        "sources_sha256": {e.file: _sha256(folder / e.file) for e in kept},
    }
