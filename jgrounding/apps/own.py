"""Own models in the apps: a checkpoint trained on an imported library drives the trunk from text.

- :func:`restrict`: grounding chooses among the checkpoint's tuples. A text grounded to a tuple the
  checkpoint never learned is moved to its nearest learned tuple, and the returned note says so: the same
  intent at the nearest recorded intensity keeps the grounding's confidence; another intent is never
  confident (the apps then hold still unless forced).
- :func:`import_info`: the channel names and per-tendon limits of the import the checkpoint's library came
  from (its card, ``my_library.json`` beside ``my_library.npz``), for command streams in the lab's own
  names and units.
"""

from __future__ import annotations

import json
from pathlib import Path

from jgrounding.vocabulary import INTENTS  # noqa: F401  (re-exported: the names restrict's groundings use)


def checkpoint_tuples(checkpoint) -> tuple[tuple[int, int], ...] | None:
    """The (intent, intensity) index pairs a checkpoint was trained on (None: every tuple)."""
    if checkpoint is None:
        return None
    from jgrounding.training import checkpoints

    return checkpoints.trained_tuples(checkpoints.read_meta(checkpoint))


def restrict(g, checkpoint):
    """``(grounding, note)``: ``g`` moved onto the checkpoint's tuples, and what was changed (None: nothing);
    :func:`jgrounding.policy.respond.snap` on the tuples of ``checkpoint`` (the one copy of the rule)."""
    from jgrounding.policy.respond import snap

    return snap(g, checkpoint_tuples(checkpoint), checkpoint)


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
