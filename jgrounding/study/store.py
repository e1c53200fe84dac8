"""The study's database, through SQLAlchemy Core: SQLite by default (one file, WAL journal, every rating in
its own transaction, synchronous=FULL so a committed rating survives a power cut), PostgreSQL given a
``postgresql+psycopg://`` URL. The code is the same for both.

Tables (docs/study.md has the data dictionary, :data:`DICTIONARY` the same text):

- ``sessions``: one run of one design (its name and sha256, the design as JSON);
- ``participants``: pseudonymous ids only (``P007-3fa2``: enrolment number and a random tag), their row of the
  Williams square, their status;
- ``condition_orders``: each participant's condition at each block position;
- ``episodes``: the design's episodes as run;
- ``executions``: what the trunk was sent for each episode: the tuple, the seed, the source (model, library
  realization, hold), the sha256 of the planned float32 ``(150, N_u)`` trajectory and of the commands the
  stream actually executed (filled in when the last one has gone out);
- ``ratings``: every rating as given, with its UTC timestamp (append-only: a changed answer is a new row; the
  analysis reads the latest one).

Nothing lives only in the server's memory: where a participant is (:meth:`Store.progress`) is read back from
these tables, so a server, browser or machine that stops mid-session resumes where the last commit left it.
"""

from __future__ import annotations

import datetime as dt
import json
import secrets
from pathlib import Path

import sqlalchemy as sa

from jgrounding.study.design import POSITIVE_FROM, Design
from jgrounding.study.latin import order_for

metadata = sa.MetaData()

sessions = sa.Table(
    "sessions",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("name", sa.String(100), nullable=False),
    sa.Column("design_sha256", sa.String(64), nullable=False),
    sa.Column("design_json", sa.Text, nullable=False),
    sa.Column("created_at", sa.DateTime, nullable=False),
    sa.UniqueConstraint("name", "design_sha256"),
)
participants = sa.Table(
    "participants",
    metadata,
    sa.Column("id", sa.String(16), primary_key=True),
    sa.Column("session_id", sa.Integer, sa.ForeignKey("sessions.id"), nullable=False),
    sa.Column("number", sa.Integer, nullable=False),
    sa.Column("order_row", sa.Integer, nullable=False),
    sa.Column("status", sa.String(16), nullable=False),
    sa.Column("created_at", sa.DateTime, nullable=False),
    sa.UniqueConstraint("session_id", "number"),
)
condition_orders = sa.Table(
    "condition_orders",
    metadata,
    sa.Column("participant_id", sa.String(16), sa.ForeignKey("participants.id"), primary_key=True),
    sa.Column("position", sa.Integer, primary_key=True),
    sa.Column("condition", sa.String(16), nullable=False),
)
episodes = sa.Table(
    "episodes",
    metadata,
    sa.Column("session_id", sa.Integer, sa.ForeignKey("sessions.id"), primary_key=True),
    sa.Column("episode", sa.Integer, primary_key=True),
    sa.Column("say", sa.Text, nullable=False),
    sa.Column("text", sa.Text),
    sa.Column("intent", sa.String(32)),
    sa.Column("intensity", sa.String(16)),
)
executions = sa.Table(
    "executions",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("participant_id", sa.String(16), sa.ForeignKey("participants.id"), nullable=False),
    sa.Column("position", sa.Integer, nullable=False),
    sa.Column("condition", sa.String(16), nullable=False),
    sa.Column("episode", sa.Integer, nullable=False),
    sa.Column("intent", sa.String(32)),
    sa.Column("intensity", sa.String(16)),
    sa.Column("confidence", sa.Float),
    sa.Column("source", sa.String(16), nullable=False),
    sa.Column("realization", sa.Integer),
    sa.Column("seed", sa.BigInteger, nullable=False),
    sa.Column("num_steps", sa.Integer, nullable=False),
    sa.Column("start_tick", sa.Integer, nullable=False),
    sa.Column("planned_sha256", sa.String(64), nullable=False),
    sa.Column("executed_sha256", sa.String(64)),
    sa.Column("planned_at", sa.DateTime, nullable=False),
    sa.Column("executed_at", sa.DateTime),
)
ratings = sa.Table(
    "ratings",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("participant_id", sa.String(16), sa.ForeignKey("participants.id"), nullable=False),
    sa.Column("position", sa.Integer, nullable=False),
    sa.Column("condition", sa.String(16), nullable=False),
    sa.Column("dimension", sa.String(40), nullable=False),
    sa.Column("value", sa.Integer, nullable=False),
    sa.Column("rated_at", sa.DateTime, nullable=False),
)

STATUSES = ("active", "complete", "withdrawn")


class StudyError(ValueError):
    """A request the study refuses (a rating out of turn, an unknown participant); the message says why."""


def now() -> dt.datetime:
    """UTC, without a zone (every timestamp in the database is UTC)."""
    return dt.datetime.now(dt.UTC).replace(tzinfo=None)


def database_url(db: str | Path) -> str:
    """A SQLAlchemy URL: a URL as given, a path as a SQLite file."""
    db = str(db)
    return db if "://" in db else f"sqlite:///{Path(db).resolve()}"


def _sqlite_pragmas(dbapi_connection, connection_record):
    cur = dbapi_connection.cursor()
    cur.execute("PRAGMA journal_mode=WAL")  # readers never block the writer; a crash keeps every commit
    cur.execute("PRAGMA synchronous=FULL")  # a commit is on disk when it returns (power cuts included)
    cur.execute("PRAGMA foreign_keys=ON")
    cur.execute("PRAGMA busy_timeout=10000")
    cur.close()


class Store:
    """The study's tables in the database at ``url`` (created if missing)."""

    def __init__(self, db: str | Path):
        self.url = database_url(db)
        self.engine = sa.create_engine(self.url, pool_pre_ping=True)
        if self.engine.dialect.name == "sqlite":
            sa.event.listen(self.engine, "connect", _sqlite_pragmas)
        metadata.create_all(self.engine)

    def close(self) -> None:
        self.engine.dispose()

    # -- sessions and participants --

    def open_session(self, design: Design) -> int:
        """The session of this design (its name and sha256), created the first time: a design that changed
        is a new session, so no data is ever mixed across designs."""
        sha = design.digest()
        with self.engine.begin() as c:
            row = c.execute(
                sa.select(sessions.c.id).where(sessions.c.name == design.name, sessions.c.design_sha256 == sha)
            ).first()
            if row is not None:
                return row.id
            sid = c.execute(
                sessions.insert().values(
                    name=design.name, design_sha256=sha, design_json=json.dumps(design.to_dict()), created_at=now()
                )
            ).inserted_primary_key[0]
            c.execute(
                episodes.insert(),
                [
                    dict(session_id=sid, episode=i, say=e.say, text=e.text, intent=e.intent, intensity=e.intensity)
                    for i, e in enumerate(design.episodes)
                ],
            )
            return sid

    def design(self, session_id: int) -> Design:
        with self.engine.connect() as c:
            raw = c.execute(sa.select(sessions.c.design_json).where(sessions.c.id == session_id)).scalar_one()
        return _design_from_json(raw)

    def sessions(self) -> list[dict]:
        with self.engine.connect() as c:
            return [dict(r._mapping) for r in c.execute(sa.select(sessions).order_by(sessions.c.id))]

    def enrol(self, session_id: int) -> dict:
        """A new participant: the next enrolment number, its Williams row and condition order, a pseudonym."""
        design = self.design(session_id)
        for _ in range(5):  # two operators enrolling at once: the unique number decides, the loser retries
            try:
                with self.engine.begin() as c:
                    number = c.execute(
                        sa.select(sa.func.count())
                        .select_from(participants)
                        .where(participants.c.session_id == session_id)
                    ).scalar_one()
                    row, order = order_for(number, design.conditions)
                    pid = f"P{number + 1:03d}-{secrets.token_hex(2)}"
                    c.execute(
                        participants.insert().values(
                            id=pid,
                            session_id=session_id,
                            number=number,
                            order_row=row,
                            status="active",
                            created_at=now(),
                        )
                    )
                    c.execute(
                        condition_orders.insert(),
                        [dict(participant_id=pid, position=i, condition=cond) for i, cond in enumerate(order)],
                    )
                return {"participant": pid, "number": number, "order_row": row, "order": list(order)}
            except sa.exc.IntegrityError:
                continue
        raise StudyError("could not enrol a participant (concurrent enrolments); try again")

    def participant(self, pid: str) -> dict:
        with self.engine.connect() as c:
            row = c.execute(sa.select(participants).where(participants.c.id == pid)).first()
            if row is None:
                raise StudyError(f"no participant {pid!r}")
            order = c.execute(
                sa.select(condition_orders.c.condition)
                .where(condition_orders.c.participant_id == pid)
                .order_by(condition_orders.c.position)
            ).scalars()
            return {**dict(row._mapping), "order": list(order)}

    def participants(self, session_id: int) -> list[dict]:
        with self.engine.connect() as c:
            ids = c.execute(
                sa.select(participants.c.id)
                .where(participants.c.session_id == session_id)
                .order_by(participants.c.number)
            ).scalars()
            ids = list(ids)
        return [{**self.participant(p), "progress": self.progress(p)} for p in ids]

    def set_status(self, pid: str, status: str) -> None:
        if status not in STATUSES:
            raise StudyError(f"status must be one of {', '.join(STATUSES)}")
        with self.engine.begin() as c:
            if c.execute(participants.update().where(participants.c.id == pid).values(status=status)).rowcount != 1:
                raise StudyError(f"no participant {pid!r}")

    # -- where a participant is --

    def progress(self, pid: str) -> dict:
        """Where participant ``pid`` is, from the committed rows alone: ``phase`` is ``episode`` (the next
        ``episode`` of block ``position`` to play), ``questionnaire`` (the block's ``missing`` dimensions),
        ``done`` or ``withdrawn``. An episode counts once its commands were executed as planned."""
        p = self.participant(pid)
        design = self.design(p["session_id"])
        with self.engine.connect() as c:
            done = c.execute(
                sa.select(executions.c.position, executions.c.episode).where(
                    executions.c.participant_id == pid, executions.c.executed_sha256 == executions.c.planned_sha256
                )
            ).all()
            rated = c.execute(
                sa.select(ratings.c.position, ratings.c.dimension).where(ratings.c.participant_id == pid)
            ).all()
        base = {"participant": pid, "blocks": len(p["order"]), "episodes": len(design.episodes)}
        if p["status"] == "withdrawn":
            return {**base, "phase": "withdrawn"}
        for pos, cond in enumerate(p["order"]):
            played = {e for b, e in done if b == pos}
            todo = [e for e in range(len(design.episodes)) if e not in played]
            if todo:
                return {**base, "phase": "episode", "position": pos, "condition": cond, "episode": todo[0]}
            missing = [d for d in design.dimensions if (pos, d) not in set(rated)]
            if missing:
                return {**base, "phase": "questionnaire", "position": pos, "condition": cond, "missing": missing}
        return {**base, "phase": "done"}

    # -- what happened --

    def record_execution(self, pid: str, position: int, condition: str, episode: int, **fields) -> int:
        """An episode's planned trajectory (``planned_sha256``, ``seed``, ``source``, ...); its id."""
        with self.engine.begin() as c:
            return c.execute(
                executions.insert().values(
                    participant_id=pid,
                    position=position,
                    condition=condition,
                    episode=episode,
                    planned_at=now(),
                    **fields,
                )
            ).inserted_primary_key[0]

    def complete_execution(self, execution_id: int, executed_sha256: str) -> None:
        """The sha256 of the commands the stream executed for it, once the last one has gone out."""
        with self.engine.begin() as c:
            c.execute(
                executions.update()
                .where(executions.c.id == execution_id)
                .values(executed_sha256=executed_sha256, executed_at=now())
            )

    def add_rating(self, pid: str, position: int, dimension: str, value: int) -> dict:
        """One rating, in its own transaction, checked against where the participant is."""
        if isinstance(value, bool) or not isinstance(value, int):
            raise StudyError(f"a rating is an integer, got {value!r}")
        prog = self.progress(pid)
        design = self.design(self.participant(pid)["session_id"])
        if not 1 <= value <= design.scale:
            raise StudyError(f"a rating is 1..{design.scale}, got {value}")
        if dimension not in design.dimensions:
            raise StudyError(f"unknown dimension {dimension!r}; the questionnaire has {', '.join(design.dimensions)}")
        # the block being rated, or a change to an answer of it before the next block has started
        current = prog.get("position")
        if prog["phase"] == "questionnaire" and position == current:
            condition = prog["condition"]
        elif prog["phase"] in ("episode", "done") and self._rated_block(pid, position):
            condition = self.participant(pid)["order"][position]
        else:
            raise StudyError(f"block {position} is not open for ratings (participant {pid} is at {prog['phase']})")
        at = now()
        with self.engine.begin() as c:
            rid = c.execute(
                ratings.insert().values(
                    participant_id=pid,
                    position=position,
                    condition=condition,
                    dimension=dimension,
                    value=value,
                    rated_at=at,
                )
            ).inserted_primary_key[0]
        after = self.progress(pid)
        if after["phase"] == "done" and self.participant(pid)["status"] == "active":
            self.set_status(pid, "complete")
        return {"id": rid, "rated_at": at.isoformat() + "Z", "progress": after}

    def _rated_block(self, pid: str, position: int) -> bool:
        """Whether block ``position`` is fully rated and no episode of a later block has been played."""
        with self.engine.connect() as c:
            later = c.execute(
                sa.select(sa.func.count())
                .select_from(executions)
                .where(executions.c.participant_id == pid, executions.c.position > position)
            ).scalar_one()
            dims = c.execute(
                sa.select(sa.func.count(sa.distinct(ratings.c.dimension))).where(
                    ratings.c.participant_id == pid, ratings.c.position == position
                )
            ).scalar_one()
        return later == 0 and dims > 0

    # -- reading it back --

    def table(self, name: str) -> list[dict]:
        t = metadata.tables[name]
        with self.engine.connect() as c:
            return [dict(r._mapping) for r in c.execute(sa.select(t).order_by(*t.primary_key.columns))]

    def long_ratings(self, session_id: int | None = None) -> list[dict]:
        """The analysis' table: the latest rating of each (participant, block, dimension), one row each, with
        the session, the participant's status and order row, and whether the rating is positive (>= 4)."""
        latest = (
            sa.select(sa.func.max(ratings.c.id).label("id"))
            .group_by(ratings.c.participant_id, ratings.c.position, ratings.c.dimension)
            .subquery()
        )
        q = (
            sa.select(
                participants.c.session_id,
                ratings.c.participant_id,
                participants.c.number,
                participants.c.order_row,
                participants.c.status,
                ratings.c.position,
                ratings.c.condition,
                ratings.c.dimension,
                ratings.c.value,
                ratings.c.rated_at,
            )
            .join(latest, latest.c.id == ratings.c.id)
            .join(participants, participants.c.id == ratings.c.participant_id)
            .order_by(participants.c.number, ratings.c.position, ratings.c.dimension)
        )
        if session_id is not None:
            q = q.where(participants.c.session_id == session_id)
        with self.engine.connect() as c:
            rows = [dict(r._mapping) for r in c.execute(q)]
        for r in rows:
            r["positive"] = int(r["value"] >= POSITIVE_FROM)
        return rows


def _design_from_json(raw: str) -> Design:
    d = json.loads(raw)
    return Design.from_dict(
        {
            "name": d["name"],
            "conditions": d["conditions"],
            "episodes": [{k: v for k, v in e.items() if v is not None} for e in d["episodes"]],
            "questions": d["questions"],
            "labels": d["labels"],
            "seed": d["seed"],
            "sim": d["sim"],
            "stall_s": d["stall_s"],
            **({"steps": d["steps"]} if d.get("steps") is not None else {}),
        }
    )
