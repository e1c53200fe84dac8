"""Write the trunk's MJCF model: ``python -m jgrounding.sim.model [--out FILE] [--segments N]``.

The model itself is built by :func:`jgrounding.sim.mjcf.build_xml` (geometry, tendons, actuators, the user; see
that module). This module is only the command: the package imports :mod:`jgrounding.sim.mjcf`, never this one,
so running it as a script does not import the module it runs a second time. The builder's names stay importable
from here (``from jgrounding.sim import model``) for code written when they lived in this module.
"""

from __future__ import annotations

import argparse

from jgrounding.sim.mjcf import *  # noqa: F403  (the builder's names, for code that imports them from here)
from jgrounding.sim.mjcf import DEFAULT_PATH, NUM_SEGMENTS, build_xml


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description="Write the trunk's MJCF model (jgrounding/assets/trunk.xml).")
    p.add_argument("--out", default=str(DEFAULT_PATH), help="where to write it (default: the shipped trunk.xml)")
    p.add_argument("--segments", type=int, default=NUM_SEGMENTS, help=f"capsules (default {NUM_SEGMENTS})")
    args = p.parse_args(argv)
    from jgrounding.io import write_atomic

    write_atomic(args.out, build_xml(args.segments))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
