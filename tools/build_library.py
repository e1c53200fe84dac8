"""Regenerate the demonstration library: ``python -m tools.build_library [--seed N]``.

Writes jgrounding/assets/library.npz + jgrounding/assets/library.json (byte-identical for a seed), the library card
docs/library_card.md and its figures under docs/library/.
"""

from __future__ import annotations

import argparse
import time

from jgrounding import library


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(library.DEFAULT_PATH))
    p.add_argument(
        "--version", type=int, default=library.designs.DEFAULT_VERSION, help="the design (3, 4 or 5; see designs.py)"
    )
    p.add_argument("--no-card", action="store_true", help="skip the Markdown card and figures")
    p.add_argument("--trunk", help="screen on this trunk MJCF (a fitted one); default: the shipped trunk")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    arrays, card = library.build(library.BuildConfig(seed=args.seed, version=args.version), trunk=args.trunk)
    path = library.save(arrays, card, args.out)
    print(
        f"wrote {path} ({card['num_train']} train / {card['num_heldout']} held-out; "
        f"{card['candidates_accepted']}/{card['candidates_tried']} candidates accepted) "
        f"in {time.perf_counter() - t0:.1f} s"
    )
    if not args.no_card:
        from tools import library_card

        library_card.write(library.load_library(path))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
