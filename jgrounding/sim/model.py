"""Write the trunk's MJCF model: ``python -m jgrounding.sim.model [--config TRUNK.toml] [--out FILE] [--segments N]``.

The model itself is built by :func:`jgrounding.sim.mjcf.build_xml` from a :class:`jgrounding.sim.mjcf.TrunkParams`
(geometry, routing, stiffness and damping tapers, tendon force, slides, density, delay; see that module). This
module is only the command: the package imports :mod:`jgrounding.sim.mjcf`, never this one, so running it as a
script does not import the module it runs a second time. The builder's names stay importable from here.
"""

from __future__ import annotations

import argparse

from jgrounding.sim.mjcf import *  # noqa: F403  (the builder's names, for code that imports them from here)
from jgrounding.sim.mjcf import DEFAULT_PATH, PARAMETER_NAMES, TrunkParams, build_xml, load_config, to_toml


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        epilog="Without --config, the shipped trunk (jgrounding/assets/trunk.xml). A TOML description names any of: "
        + ", ".join(PARAMETER_NAMES),
    )
    p.add_argument("--out", default=str(DEFAULT_PATH), help="the MJCF to write")
    p.add_argument("--config", help="TOML description of the trunk (name = value lines; see --write-config)")
    p.add_argument("--segments", type=int, help="number of segments (overrides the description)")
    p.add_argument("--exact", action="store_true", help="hinge stiffness and damping in full precision")
    p.add_argument("--write-config", metavar="TOML", help="also write the full description (every parameter) here")
    args = p.parse_args(argv)
    from jgrounding.io import write_atomic

    try:
        params = load_config(args.config) if args.config else TrunkParams()
        if args.segments is not None:
            params = params.replace(segments=args.segments)
    except (ValueError, FileNotFoundError) as e:
        p.error(str(e))
    write_atomic(args.out, build_xml(params=params, exact=args.exact))
    print(f"wrote {args.out}")
    if args.write_config:
        write_atomic(args.write_config, to_toml(params))
        print(f"wrote {args.write_config}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
