"""``python -m jgrounding.serve``: the policy server (model and grounding loaded once; docs/serving.md).

Binds 127.0.0.1:8765 by default. Another address needs ``--token`` (or ``JGROUNDING_TOKEN``), which every
client must send. ``--checkpoint DIR`` serves a lab's own checkpoint (as ``jg.sample(..., checkpoint=DIR)``).
"""

from __future__ import annotations

import argparse
import os
import sys


def build_parser() -> argparse.ArgumentParser:
    from jgrounding.serving import DEFAULT_HOST, DEFAULT_PORT, Limits

    d = Limits()
    p = argparse.ArgumentParser(
        prog="python -m jgrounding.serve",
        description="Serve the grounding, the sampler and a live 30 Hz command stream over a WebSocket, "
        "and a page for people, from one process.",
    )
    p.add_argument("--host", default=DEFAULT_HOST, help="address to bind (default %(default)s: this machine only)")
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help="port (default %(default)s)")
    p.add_argument(
        "--token",
        default=os.environ.get("JGROUNDING_TOKEN"),
        help="secret clients must send (required for a non-loopback --host; default $JGROUNDING_TOKEN)",
    )
    p.add_argument("--checkpoint", default=None, help="a checkpoint directory (default: the shipped models)")
    p.add_argument("--allow-library-mismatch", action="store_true", help="serve a checkpoint of another library")
    p.add_argument("--trunk", default=None, help="the trunk MJCF simulated (a fitted one; default: the shipped trunk)")
    p.add_argument("--max-text", type=int, default=d.max_text, help="characters per text (%(default)s)")
    p.add_argument("--max-samples", type=int, default=d.max_samples, help="num_samples per request (%(default)s)")
    p.add_argument("--rate", type=float, default=d.rate, help="requests/s per connection (%(default)s)")
    p.add_argument("--burst", type=int, default=d.burst, help="requests in a burst per connection (%(default)s)")
    p.add_argument(
        "--stall", type=float, default=d.stall_s, help="seconds of client silence before a stream glides to rest"
    )
    p.add_argument("--log-level", default="info", choices=("critical", "error", "warning", "info", "debug"))
    return p


def main(argv: list[str] | None = None) -> int:
    from jgrounding import serving

    args = build_parser().parse_args(argv)
    if not 0 <= args.port <= 65535:
        print(f"error: --port must be in 0..65535, got {args.port}", file=sys.stderr)
        return 2
    try:  # Limits checks its own ranges; its message names the option
        limits = serving.Limits(
            max_text=args.max_text,
            max_samples=args.max_samples,
            rate=args.rate,
            burst=args.burst,
            stall_s=args.stall,
        )
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    try:
        serving.serve(
            args.host,
            args.port,
            checkpoint=args.checkpoint,
            token=args.token,
            limits=limits,
            allow_library_mismatch=args.allow_library_mismatch,
            log_level=args.log_level,
            trunk=args.trunk,
        )
    except (ValueError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
