"""Own models in the apps (issue #26): a checkpoint trained on an imported library drives the trunk from text.

- :func:`restrict`: grounding chooses among the checkpoint's tuples. A text grounded to a tuple the
  checkpoint never learned is moved to its nearest learned tuple, and the returned note says so: the same
  intent at the nearest recorded intensity keeps the grounding's confidence; another intent is never
  confident (the apps then hold still unless forced).
- :func:`import_info`: the channel names and per-tendon limits of the import the checkpoint's library came
  from (its card, ``my_library.json`` beside ``my_library.npz``), for command streams in the lab's own
  names and units.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from jgrounding.vocabulary import INTENSITIES, INTENTS


def checkpoint_tuples(checkpoint) -> tuple[tuple[int, int], ...] | None:
    """The (intent, intensity) index pairs a checkpoint was trained on (None: every tuple)."""
    if checkpoint is None:
        return None
    from jgrounding.training import checkpoints

    return checkpoints.trained_tuples(checkpoints.read_meta(checkpoint))


def _names(tuples) -> str:
    return ", ".join(f"{INTENTS[m]}/{INTENSITIES[z]}" for m, z in sorted(tuples))


def restrict(g, checkpoint):
    """``(grounding, note)``: ``g`` moved onto the checkpoint's tuples, and what was changed (None: nothing).

    The same intent at another intensity: the recorded intensity nearest to the asked one (the lower on a
    tie) replaces it and the grounding stays as confident as it was. An intent the checkpoint never learned:
    the learned intent with the highest score in ``g.scores`` (the first learned one when the backend gives
    no scores) at its intensity nearest to the asked one, ``confident=False``: the text asked for something
    this model cannot do, so the apps hold still unless forced.
    """
    tuples = checkpoint_tuples(checkpoint)
    if tuples is None or (g.intent_index, g.intensity_index) in tuples:
        return g, None
    asked = f"({g.intent}, {g.intensity})"
    same = sorted((abs(z - g.intensity_index), z) for m, z in tuples if m == g.intent_index)
    if same:
        z = same[0][1]
        note = (
            f"the text asked for {asked}; checkpoint {checkpoint} learned {g.intent} only at "
            f"{', '.join(INTENSITIES[b] for _, b in sorted(same, key=lambda s: s[1]))}: using the nearest, "
            f"({g.intent}, {INTENSITIES[z]})"
        )
        return dataclasses.replace(g, intensity=INTENSITIES[z]), note
    intents = sorted({m for m, _ in tuples})
    scores = list(g.scores) if len(g.scores) == len(INTENTS) else None
    m = max(intents, key=lambda i: scores[i]) if scores else intents[0]
    z = min((abs(b - g.intensity_index), b) for a, b in tuples if a == m)[1]
    score = f" (score {scores[m]:.2f})" if scores else ""
    note = (
        f"the text asked for {asked}, outside the tuples checkpoint {checkpoint} was trained on "
        f"({_names(tuples)}); its nearest is ({INTENTS[m]}, {INTENSITIES[z]}){score}"
    )
    reason = f"asked for {asked}, which this checkpoint never learned"
    return (
        dataclasses.replace(
            g,
            intent=INTENTS[m],
            intensity=INTENSITIES[z],
            confidence=float(scores[m]) if scores else 0.0,
            confident=False,
            reason=reason,
        ),
        note,
    )


def import_info(checkpoint) -> dict | None:
    """``{"channels", "limits", "card"}`` of the import behind ``checkpoint``'s library, or None.

    None for the shipped checkpoints (the built-in trunk's layout applies) and for a library that was not
    imported (no ``limits`` in its card). Raises ``ValueError`` naming the files when the checkpoint
    records a library whose card is gone.
    """
    if checkpoint is None:
        return None
    from jgrounding.training import checkpoints

    meta = checkpoints.read_meta(checkpoint)
    lib = meta.get("library_path")
    if not lib:
        return None
    card_path = Path(lib).with_suffix(".json")
    try:
        card = json.loads(card_path.read_text())
    except (OSError, ValueError) as e:
        raise ValueError(
            f"checkpoint {checkpoint} was trained on {lib}, but its card {card_path} cannot be read ({e}); "
            "the lab's channel names and limits come from it"
        ) from None
    limits = (card.get("config") or {}).get("limits")
    if card.get("source") != "import" or not limits:
        return None
    n = len(limits)
    channels = card.get("channels") or [f"tendon_{j}" for j in range(n)]
    return {"channels": list(channels), "limits": [tuple(map(float, p)) for p in limits], "card": str(card_path)}
