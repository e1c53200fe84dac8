"""Export a study's database to CSV and Parquet (pyarrow), with its data dictionary.

``python -m jgrounding.study export DB --out DIR`` writes every table (``sessions.csv``, ``participants.csv``,
``condition_orders.csv``, ``episodes.csv``, ``executions.csv``, ``ratings.csv``) and the analysis' long table
(``ratings_long.csv``: the latest rating of each participant, block and dimension), each also as ``.parquet``,
and ``data_dictionary.md`` / ``data_dictionary.json``: every column with its type and meaning. Timestamps are
UTC in ISO 8601.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import json
from pathlib import Path

from jgrounding.io import write_atomic
from jgrounding.study.store import Store, metadata

# Every exported column: (type, meaning). The same text is in docs/study.md.
DICTIONARY: dict[str, dict[str, tuple[str, str]]] = {
    "sessions": {
        "id": ("integer", "session id"),
        "name": ("string", "the design's name"),
        "design_sha256": ("string", "sha256 of the design's canonical JSON"),
        "design_json": ("string", "the design as run (conditions, episodes, questionnaire, seed)"),
        "created_at": ("timestamp", "when the session was first opened (UTC)"),
    },
    "participants": {
        "id": ("string", "pseudonymous participant id (enrolment number + random tag; no names)"),
        "session_id": ("integer", "the session"),
        "number": ("integer", "enrolment number, 0-based"),
        "order_row": ("integer", "row of the Williams square that gave the condition order"),
        "status": ("string", "active, complete or withdrawn"),
        "created_at": ("timestamp", "enrolment time (UTC)"),
    },
    "condition_orders": {
        "participant_id": ("string", "the participant"),
        "position": ("integer", "block position, 0-based (0 = first condition seen)"),
        "condition": ("string", "av_only, trunk or scripted"),
    },
    "episodes": {
        "session_id": ("integer", "the session"),
        "episode": ("integer", "episode index within a block, 0-based"),
        "say": ("string", "what the robot says (the audiovisual channel)"),
        "text": ("string", "response text grounded by the server (empty for a tuple episode)"),
        "intent": ("string", "the episode's intent (tuple episodes)"),
        "intensity": ("string", "the episode's intensity (tuple episodes)"),
    },
    "executions": {
        "id": ("integer", "execution id"),
        "participant_id": ("string", "the participant"),
        "position": ("integer", "block position"),
        "condition": ("string", "the block's condition"),
        "episode": ("integer", "episode index"),
        "intent": ("string", "the tuple executed (after grounding a text)"),
        "intensity": ("string", "the tuple executed"),
        "confidence": ("float", "grounding confidence of a text episode (empty for tuples)"),
        "source": ("string", "model (jgrounding.sample), library (a demonstration) or hold (trunk still)"),
        "realization": ("integer", "index of the library demonstration among the tuple's training realizations"),
        "seed": ("integer", "seed of the sample (and of the realization choice)"),
        "num_steps": ("integer", "commands in the planned trajectory (150 at 30 Hz)"),
        "start_tick": ("integer", "stream tick at which the trajectory started"),
        "planned_sha256": ("string", "sha256 of the planned float32 (num_steps, N_u) trajectory, C order"),
        "executed_sha256": ("string", "sha256 of the float32 commands the stream executed (equal: as planned)"),
        "planned_at": ("timestamp", "when it was planned (UTC)"),
        "executed_at": ("timestamp", "when its last command went out (UTC; empty: not completed)"),
    },
    "ratings": {
        "id": ("integer", "rating id (append-only; a changed answer is a new row)"),
        "participant_id": ("string", "the participant"),
        "position": ("integer", "block position"),
        "condition": ("string", "the block's condition"),
        "dimension": ("string", "questionnaire item (naturalness, appropriateness, ...)"),
        "value": ("integer", "Likert rating, 1..scale (5: strongly agree)"),
        "rated_at": ("timestamp", "when it was given (UTC)"),
    },
    "ratings_long": {
        "session_id": ("integer", "the session"),
        "participant_id": ("string", "the participant"),
        "number": ("integer", "enrolment number"),
        "order_row": ("integer", "Williams row"),
        "status": ("string", "participant status at export"),
        "position": ("integer", "block position (the order effect's factor)"),
        "condition": ("string", "the block's condition"),
        "dimension": ("string", "questionnaire item"),
        "value": ("integer", "latest rating of that item in that block"),
        "rated_at": ("timestamp", "when that rating was given (UTC)"),
        "positive": ("integer", "1 if value >= 4 (the paper's positive rating), else 0"),
    },
}


def _cell(v):
    if isinstance(v, dt.datetime):
        return v.isoformat() + "Z"
    return v


def _arrow_table(name: str, rows: list[dict]):
    import pyarrow as pa

    kinds = {
        "integer": pa.int64(),
        "float": pa.float64(),
        "string": pa.string(),
        "timestamp": pa.timestamp("us", "UTC"),
    }
    schema = pa.schema([(col, kinds[kind]) for col, (kind, _) in DICTIONARY[name].items()])
    cols = {
        col: [r.get(col).replace(tzinfo=dt.UTC) if isinstance(r.get(col), dt.datetime) else r.get(col) for r in rows]
        for col in schema.names
    }
    return pa.table(cols, schema=schema)


def dictionary_markdown() -> str:
    out = ["# Data dictionary of a jgrounding study export", ""]
    for table, cols in DICTIONARY.items():
        out += [f"## {table}", "", "| column | type | meaning |", "|---|---|---|"]
        out += [f"| {c} | {k} | {m} |" for c, (k, m) in cols.items()]
        out.append("")
    return "\n".join(out)


def export(store: Store, out: str | Path, session_id: int | None = None) -> list[Path]:
    """Write every table and ``ratings_long`` as CSV and Parquet, and the data dictionary; the paths."""
    import pyarrow.parquet as pq

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tables = {name: store.table(name) for name in metadata.tables}
    tables["ratings_long"] = store.long_ratings(session_id)
    written = []
    for name, rows in tables.items():
        cols = list(DICTIONARY[name])
        assert name == "ratings_long" or cols == list(metadata.tables[name].columns.keys()), name
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols)
        w.writerows([[_cell(r.get(c)) for c in cols] for r in rows])
        written.append(write_atomic(out / f"{name}.csv", buf.getvalue()))
        pq.write_table(_arrow_table(name, rows), out / f"{name}.parquet")
        written.append(out / f"{name}.parquet")
    written.append(write_atomic(out / "data_dictionary.md", dictionary_markdown()))
    spec = {t: {c: {"type": k, "meaning": m} for c, (k, m) in cols.items()} for t, cols in DICTIONARY.items()}
    written.append(write_atomic(out / "data_dictionary.json", json.dumps(spec, indent=1)))
    return written
