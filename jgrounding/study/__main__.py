"""``python -m jgrounding.study serve|analyze|export|simulate`` (docs/study.md).

- ``serve --design study.toml [--db study.db | --db postgresql+psycopg://...]``: the study server (the
  operator's page at ``/study/operator``); a session stopped at any point resumes on the next start.
- ``analyze DB [--session ID] [--out DIR] [--exclude-withdrawn]``: the report (Markdown on stdout,
  ``report.md``, ``report.json``) and the figure (``positive_ratio.png``); withdrawn participants' ratings
  count unless ``--exclude-withdrawn``.
- ``export DB --out DIR``: every table as CSV and Parquet, and the data dictionary.
- ``simulate URL [--participants N] [--seed S] [--dropout P] [--token T]``: simulated participants through a
  running study server (:mod:`jgrounding.study.visit`): enrolled, their episodes played on the live stream,
  their ratings drawn from known distributions and stored like anyone's; then ``analyze`` reads them.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

DEFAULT_PORT = 8766


def serve(
    design_path, db="study.db", host="127.0.0.1", port=DEFAULT_PORT, token=None, checkpoint=None, trunk=None
) -> None:
    """Serve a study until interrupted (``python -m jgrounding.study serve``); ``trunk``: the MJCF the episodes'
    simulated trunk runs on (a fitted one; None: the shipped trunk)."""
    import uvicorn

    from jgrounding.serving import WS_MAX_SIZE, Policy, check_bind
    from jgrounding.study.app import StudyServer
    from jgrounding.study.design import load_design
    from jgrounding.study.store import Store

    check_bind(host, token)
    design = load_design(design_path)
    store = Store(db)
    policy = None
    if design.needs_model:
        t0 = time.perf_counter()
        policy = Policy(checkpoint, trunk=trunk)
        print(f"jgrounding study: model loaded and compiled in {time.perf_counter() - t0:.1f} s", flush=True)
    server = StudyServer(design, store, policy, token)
    n = len(store.participants(server.session_id))
    print(f"jgrounding study {design.name!r}: session {server.session_id} in {store.url} ({n} participants so far)")
    shown = "localhost" if host == "127.0.0.1" else host
    print(f"  operator:  http://{shown}:{port}/study/operator" + ("?token=..." if token else ""), flush=True)
    uvicorn.run(server.app(), host=host, port=port, log_level="warning", ws_max_size=WS_MAX_SIZE, lifespan="off")


def _session(store, session: int | None) -> int:
    ids = [s["id"] for s in store.sessions()]
    if not ids:
        raise SystemExit("the database holds no study session")
    if session is None:
        return ids[-1]
    if session not in ids:
        raise SystemExit(f"no session {session}; the database holds {ids}")
    return session


def analyze(db, out="study_analysis", session: int | None = None, exclude_withdrawn: bool = False) -> dict:
    """Analyse a study's database: the report (also returned) and the figure, written to ``out``;
    ``exclude_withdrawn`` leaves out the participants withdrawn by the operator (default: they count)."""
    from jgrounding.io import write_atomic
    from jgrounding.study import analysis
    from jgrounding.study.store import Store

    store = Store(db)
    sid = _session(store, session)
    design = store.design(sid)
    rows = store.long_ratings(sid)
    report = analysis.analyze(rows, design.conditions, design.dimensions, exclude_withdrawn=exclude_withdrawn)
    report.update(session=sid, design=design.name)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    text = analysis.markdown(report)
    write_atomic(out / "report.md", text)
    write_atomic(out / "report.json", json.dumps(report, indent=1, default=str))
    analysis.figure(report, out / "positive_ratio.png")
    print(text)
    print(f"wrote {out / 'report.md'}, {out / 'report.json'}, {out / 'positive_ratio.png'}")
    return report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m jgrounding.study", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    s = sub.add_parser("serve", help="serve a study: the operator's and the participant's pages")
    s.add_argument("--design", required=True, help="the study's TOML design (examples/study.toml)")
    s.add_argument("--db", default="study.db", help="SQLite file (default study.db) or a SQLAlchemy URL")
    s.add_argument("--host", default="127.0.0.1")
    s.add_argument("--port", type=int, default=DEFAULT_PORT)
    s.add_argument("--token", default=None, help="a token pages and clients must send (needed beyond loopback)")
    s.add_argument("--checkpoint", default=None, help="a lab's checkpoint instead of the shipped model")
    s.add_argument("--trunk", default=None, help="the trunk MJCF simulated (a fitted one; default: the shipped trunk)")
    a = sub.add_parser("analyze", help="analyse a study's database")
    a.add_argument("db", help="SQLite file or SQLAlchemy URL")
    a.add_argument("--out", default="study_analysis", help="folder for report.md, report.json, the figure")
    a.add_argument("--session", type=int, default=None, help="session id (default: the newest)")
    a.add_argument(
        "--exclude-withdrawn",
        action="store_true",
        help="leave out participants the operator withdrew (default: their ratings count)",
    )
    e = sub.add_parser("export", help="export a study's database to CSV and Parquet with a data dictionary")
    e.add_argument("db")
    e.add_argument("--out", required=True)
    e.add_argument("--session", type=int, default=None, help="session of ratings_long (default: the newest)")
    m = sub.add_parser(
        "simulate",
        help="run simulated participants through a running study server (each episode plays in real time, 5 s)",
    )
    m.add_argument("url", help=f"the study server, e.g. http://localhost:{DEFAULT_PORT}")
    m.add_argument("--participants", type=int, default=4, help="how many to enrol (default 4)")
    m.add_argument("--seed", type=int, default=0, help="seed of their ratings (default 0)")
    m.add_argument("--dropout", type=float, default=0.0, help="chance of leaving after each block (default 0)")
    m.add_argument("--token", default=None, help="the server's token, if it has one")
    args = parser.parse_args(argv)
    from jgrounding.study.design import DesignError

    try:
        if args.command == "serve":
            serve(args.design, args.db, args.host, args.port, args.token, args.checkpoint, args.trunk)
        elif args.command == "analyze":
            analyze(args.db, args.out, args.session, args.exclude_withdrawn)
        elif args.command == "simulate":
            from jgrounding.study import visit

            ids = visit.run(args.url, args.participants, args.seed, args.dropout, args.token)
            print(f"{len(ids)} simulated participants rated; analyse with: python -m jgrounding.study analyze DB")
        else:
            from jgrounding.study.export import export
            from jgrounding.study.store import Store

            store = Store(args.db)
            paths = export(store, args.out, _session(store, args.session))
            print("\n".join(str(p) for p in paths))
    except (DesignError, ValueError, RuntimeError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
