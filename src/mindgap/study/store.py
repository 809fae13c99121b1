"""The study store: SQLite in WAL mode, a versioned schema, one row per answer.

Written on the standard library's ``sqlite3`` rather than an ORM because what matters
here is a handful of exact guarantees, each one a line of SQL:

* **Nothing acknowledged is lost.** Every write is one ``BEGIN IMMEDIATE`` transaction
  committed before the server answers; WAL with ``synchronous=FULL`` keeps a committed
  transaction through a killed process (and a power cut).
* **Idempotent submits.** A submit carries a client-made ``submission_id`` (unique), and
  ``(participant, item)`` is unique too: a double click, a retried request or a second
  tab records one answer; the first answer stands.
* **Versioned schema.** ``schema_version`` holds the version; :data:`MIGRATIONS` are
  applied in order inside one transaction when a store is opened, and a store written
  by a newer mindgap is refused instead of being misread.
* **One study per store.** The study's fingerprint and its items (exactly what was
  shown) are stored at creation; opening the store with another study file is refused.

Connections are per thread (the web server answers from a thread pool; a training run
polls from its own process), each waiting up to ``timeout`` seconds for the write lock.

A live batch is shown only while its run is alive: the run's every poll marks the batch seen
(:meth:`Store.live_counts` with ``touch``), and a batch not seen for :data:`STALE_AFTER`
seconds is withdrawn before any participant is given a query (:meth:`Store.claim_live`), so
a run killed while it waits leaves no question behind; restarted, it resumes from its last
checkpoint and posts the round again.
"""

from __future__ import annotations

import contextlib
import json
import random
import secrets
import sqlite3
import threading
import time
from pathlib import Path

MIGRATIONS: tuple[tuple[str, ...], ...] = (
    (  # 1: participants, questionnaire answers, item answers, first views
        "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
        """CREATE TABLE participants (
            id INTEGER PRIMARY KEY,
            token TEXT NOT NULL UNIQUE,
            label TEXT NOT NULL UNIQUE,
            condition TEXT NOT NULL,
            item_order TEXT NOT NULL,
            completion_code TEXT NOT NULL,
            created_at REAL NOT NULL,
            consent_at REAL, declined_at REAL, instructions_at REAL, questionnaire_at REAL, completed_at REAL)""",
        """CREATE TABLE questionnaire (
            participant_id INTEGER NOT NULL REFERENCES participants(id),
            question TEXT NOT NULL,
            value INTEGER NOT NULL,
            answered_at REAL NOT NULL,
            PRIMARY KEY (participant_id, question))""",
        """CREATE TABLE answers (
            id INTEGER PRIMARY KEY,
            participant_id INTEGER NOT NULL REFERENCES participants(id),
            item_id TEXT NOT NULL,
            value REAL NOT NULL,
            choice TEXT,
            seconds REAL,
            submission_id TEXT NOT NULL UNIQUE,
            created_at REAL NOT NULL,
            UNIQUE (participant_id, item_id))""",
        """CREATE TABLE views (
            participant_id INTEGER NOT NULL REFERENCES participants(id),
            item_id TEXT NOT NULL,
            first_shown REAL NOT NULL,
            PRIMARY KEY (participant_id, item_id))""",
    ),
    (  # 2: queries posted by a training run (live mode)
        """CREATE TABLE live_batches (
            id INTEGER PRIMARY KEY, run TEXT NOT NULL, size INTEGER NOT NULL,
            created_at REAL NOT NULL, closed_at REAL)""",
        """CREATE TABLE live_queries (
            id INTEGER PRIMARY KEY,
            batch_id INTEGER NOT NULL REFERENCES live_batches(id),
            idx INTEGER NOT NULL,
            data TEXT NOT NULL,
            status TEXT NOT NULL DEFAULT 'open' CHECK (status IN ('open', 'answered', 'expired')),
            claimed_by INTEGER REFERENCES participants(id),
            claimed_at REAL,
            UNIQUE (batch_id, idx))""",
        "CREATE INDEX live_open ON live_queries (status, id)",
    ),
    (  # 3: a live batch's last sign of life from its run (a run killed mid-wait leaves its batch open)
        "ALTER TABLE live_batches ADD COLUMN seen_at REAL",
        "UPDATE live_batches SET seen_at = created_at",
    ),
)
SCHEMA_VERSION = len(MIGRATIONS)
STALE_AFTER = 30.0
"""Seconds without a poll from its run after which a live batch's open queries are withdrawn
(a waiting run polls every half second)."""
LIVE_PREFIX = "live-"


class StoreError(RuntimeError):
    """A store that cannot be used as asked (newer schema, another study, no study yet)."""


class Store:
    """One SQLite study store; safe to share between threads (each gets its own connection)."""

    def __init__(self, path, *, timeout: float = 30.0, migrate: bool = True, upto: int | None = None):
        self.path = Path(path)
        self.timeout = timeout
        self._local = threading.local()
        if migrate:
            self.migrate(upto)

    # -- connections and transactions -------------------------------------------------
    def conn(self) -> sqlite3.Connection:
        c = getattr(self._local, "conn", None)
        if c is None:
            c = sqlite3.connect(self.path, timeout=self.timeout, isolation_level=None, check_same_thread=False)
            c.row_factory = sqlite3.Row
            c.execute("PRAGMA journal_mode=WAL")
            c.execute("PRAGMA synchronous=FULL")
            c.execute("PRAGMA foreign_keys=ON")
            c.execute(f"PRAGMA busy_timeout={int(self.timeout * 1000)}")
            self._local.conn = c
        return c

    @contextlib.contextmanager
    def write(self):
        """One write transaction: ``BEGIN IMMEDIATE`` takes the write lock up front (no upgrade deadlocks)."""
        c = self.conn()
        c.execute("BEGIN IMMEDIATE")
        try:
            yield c
        except BaseException:
            c.execute("ROLLBACK")
            raise
        c.execute("COMMIT")

    def close(self) -> None:
        c = getattr(self._local, "conn", None)
        if c is not None:
            c.close()
            self._local.conn = None

    # -- schema -------------------------------------------------------------------------
    def version(self) -> int:
        c = self.conn()
        if not c.execute("SELECT 1 FROM sqlite_master WHERE name = 'schema_version'").fetchone():
            return 0
        return int(c.execute("SELECT version FROM schema_version").fetchone()[0])

    def migrate(self, upto: int | None = None) -> int:
        """Apply the missing migrations (up to ``upto``, default all); returns the version reached.

        Raises:
            StoreError: the store was written by a newer mindgap.
        """
        target = SCHEMA_VERSION if upto is None else upto
        with self.write() as c:
            c.execute("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)")
            row = c.execute("SELECT version FROM schema_version").fetchone()
            current = 0 if row is None else int(row[0])
            if row is None:
                c.execute("INSERT INTO schema_version VALUES (0)")
            if current > SCHEMA_VERSION:
                raise StoreError(
                    f"{self.path}: schema version {current} is newer than this mindgap's ({SCHEMA_VERSION}); upgrade mindgap"
                )
            for v in range(current, target):
                for stmt in MIGRATIONS[v]:
                    c.execute(stmt)
            if target > current:
                c.execute("UPDATE schema_version SET version = ?", (target,))
        return max(current, target)

    # -- study binding ------------------------------------------------------------------
    def meta(self, key: str, default: str | None = None) -> str | None:
        row = self.conn().execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        return default if row is None else row[0]

    def bind_study(self, study, items: list[dict], admin_token: str | None = None) -> bool:
        """Store the study and its items on first use; check the fingerprint afterwards.

        Returns:
            True when the store was new (the participants of the study file were created).
        Raises:
            StoreError: the store belongs to another study.
        """
        with self.write() as c:
            row = c.execute("SELECT value FROM meta WHERE key = 'fingerprint'").fetchone()
            if row is not None:
                if row[0] != study.fingerprint():
                    name = self.meta("study_name")
                    raise StoreError(
                        f"{self.path} holds the answers of another study ({name!r}, or this one edited since); "
                        "use another --db for a changed study file"
                    )
                if admin_token:
                    c.execute("UPDATE meta SET value = ? WHERE key = 'admin_token'", (admin_token,))
                return False
            meta = {
                "fingerprint": study.fingerprint(),
                "study_name": study.name,
                "study": study.to_json(),
                "items": json.dumps(items),
                "secret": secrets.token_hex(32),
                "admin_token": admin_token or secrets.token_urlsafe(24),
                "created_at": repr(time.time()),
            }
            c.executemany("INSERT INTO meta VALUES (?, ?)", list(meta.items()))
            self._add_participants(c, study, [it["id"] for it in items], study.participants)
        return True

    def items(self) -> list[dict]:
        raw = self.meta("items")
        if raw is None:
            raise StoreError(
                f"{self.path} holds no study yet: start it with mindgap study serve --config FILE --db FILE"
            )
        return json.loads(raw)

    def study_json(self) -> dict:
        raw = self.meta("study")
        if raw is None:
            raise StoreError(
                f"{self.path} holds no study yet: start it with mindgap study serve --config FILE --db FILE"
            )
        return json.loads(raw)

    # -- participants ---------------------------------------------------------------------
    def add_participants(self, study, n: int) -> list[str]:
        with self.write() as c:
            return self._add_participants(c, study, [it["id"] for it in json.loads(self.meta("items"))], n)

    def _add_participants(self, c, study, item_ids: list[str], n: int) -> list[str]:
        conditions = study.conditions()
        start = c.execute("SELECT COALESCE(MAX(id), 0) FROM participants").fetchone()[0]
        tokens = []
        for pid in range(start + 1, start + 1 + n):
            order = list(item_ids)
            if study.shuffle:
                random.Random(f"{study.fingerprint()}:{pid}").shuffle(order)
            token = secrets.token_urlsafe(18)
            c.execute(
                "INSERT INTO participants (id, token, label, condition, item_order, completion_code, created_at)"
                " VALUES (?, ?, ?, ?, ?, ?, ?)",
                (
                    pid,
                    token,
                    f"p-{pid:03d}",
                    conditions[(pid - 1) % len(conditions)],
                    json.dumps(order),
                    secrets.token_hex(4).upper(),
                    time.time(),
                ),
            )
            tokens.append(token)
        return tokens

    def participant(self, token: str) -> sqlite3.Row | None:
        return self.conn().execute("SELECT * FROM participants WHERE token = ?", (token,)).fetchone()

    def participants(self) -> list[sqlite3.Row]:
        return self.conn().execute("SELECT * FROM participants ORDER BY id").fetchall()

    def mark(self, pid: int, stage: str) -> None:
        """Set a stage's timestamp once (consent, declined, instructions, questionnaire, completed)."""
        if stage not in ("consent", "declined", "instructions", "questionnaire", "completed"):
            raise ValueError(f"unknown stage {stage!r}")
        with self.write() as c:
            c.execute(f"UPDATE participants SET {stage}_at = ? WHERE id = ? AND {stage}_at IS NULL", (time.time(), pid))

    def save_questionnaire(self, pid: int, answers: dict[str, int]) -> None:
        now = time.time()
        with self.write() as c:
            c.executemany(
                "INSERT OR IGNORE INTO questionnaire VALUES (?, ?, ?, ?)",
                [(pid, q, v, now) for q, v in answers.items()],
            )
            c.execute(
                "UPDATE participants SET questionnaire_at = ? WHERE id = ? AND questionnaire_at IS NULL", (now, pid)
            )

    def questionnaire(self, pid: int | None = None) -> list[sqlite3.Row]:
        sql = "SELECT * FROM questionnaire" + (" WHERE participant_id = ?" if pid is not None else "")
        return self.conn().execute(sql, () if pid is None else (pid,)).fetchall()

    # -- items and answers ----------------------------------------------------------------
    def first_view(self, pid: int, item_id: str) -> float:
        """When ``item_id`` was first shown to the participant (recorded now if never)."""
        c = self.conn()
        row = c.execute(
            "SELECT first_shown FROM views WHERE participant_id = ? AND item_id = ?", (pid, item_id)
        ).fetchone()
        if row is not None:
            return row[0]
        with self.write() as w:
            w.execute("INSERT OR IGNORE INTO views VALUES (?, ?, ?)", (pid, item_id, time.time()))
        return self.first_view(pid, item_id)

    def shown_at(self, pid: int, item_id: str) -> float | None:
        row = (
            self.conn()
            .execute("SELECT first_shown FROM views WHERE participant_id = ? AND item_id = ?", (pid, item_id))
            .fetchone()
        )
        return None if row is None else row[0]

    def answered_ids(self, pid: int) -> set[str]:
        return {r[0] for r in self.conn().execute("SELECT item_id FROM answers WHERE participant_id = ?", (pid,))}

    def record_answer(
        self,
        pid: int,
        item_id: str,
        value: float,
        choice: str | None,
        submission_id: str,
        *,
        order: list[str] | None = None,
        min_seconds: float | None = None,
    ) -> str:
        """Store one answer exactly once; every check runs inside the write transaction.

        A resubmission of a stored answer is recognised before anything else, so copies of
        one form sent at once all get the first one's outcome, whichever commits first.

        Args:
            order: the participant's item order; an answer to any item but the first
                unanswered one is refused (``out-of-order``). None for a live query.
            min_seconds: the least time between the item's first view and its answer; with
                it, an item never shown is refused (``not-shown``). None: no view needed.

        Returns:
            ``stored`` (new), ``duplicate`` (this submission was stored before), ``answered``
            (the item already has an earlier answer, which stands) or ``conflict`` (the
            submission id was used for another item or participant); refused without a
            write: ``out-of-order``, ``not-shown`` (never shown to this participant) or
            ``too-fast``. For a live query also ``closed`` (the run stopped waiting), ``taken``
            (someone else answered it first) or ``not-yours`` (never shown to this participant;
            one shown to them stays theirs to answer after its lease passed to another).
        """
        now = time.time()
        with self.write() as c:
            row = c.execute(
                "SELECT participant_id, item_id FROM answers WHERE submission_id = ?", (submission_id,)
            ).fetchone()
            if row is not None:
                return "duplicate" if (row[0], row[1]) == (pid, item_id) else "conflict"
            answered = {r[0] for r in c.execute("SELECT item_id FROM answers WHERE participant_id = ?", (pid,))}
            if item_id in answered:
                return "answered"
            if order is not None and item_id != next((i for i in order if i not in answered), None):
                return "out-of-order"
            shown = c.execute(
                "SELECT first_shown FROM views WHERE participant_id = ? AND item_id = ?", (pid, item_id)
            ).fetchone()
            if item_id.startswith(LIVE_PREFIX):
                q = c.execute(
                    "SELECT status, claimed_by FROM live_queries WHERE id = ?", (int(item_id[len(LIVE_PREFIX) :]),)
                ).fetchone()
                if q is None or (q["claimed_by"] != pid and shown is None):
                    return "not-yours"
                if q["status"] != "open":
                    return "closed" if q["status"] == "expired" else "taken"
            if min_seconds is not None:
                if shown is None:
                    return "not-shown"
                if now - shown[0] < min_seconds:
                    return "too-fast"
            if item_id.startswith(LIVE_PREFIX):
                c.execute(
                    "UPDATE live_queries SET status = 'answered' WHERE id = ?", (int(item_id[len(LIVE_PREFIX) :]),)
                )
            c.execute(
                "INSERT INTO answers (participant_id, item_id, value, choice, seconds, submission_id, created_at)"
                " VALUES (?, ?, ?, ?, ?, ?, ?)",
                (pid, item_id, float(value), choice, None if shown is None else now - shown[0], submission_id, now),
            )
        return "stored"

    def answers(self) -> list[sqlite3.Row]:
        return (
            self.conn()
            .execute(
                "SELECT a.*, p.label AS participant, p.condition FROM answers a JOIN participants p ON p.id = a.participant_id"
                " ORDER BY a.id"
            )
            .fetchall()
        )

    # -- live queries ---------------------------------------------------------------------
    def post_live_batch(self, run: str, datas: list[dict]) -> int:
        with self.write() as c:
            cur = c.execute(
                "INSERT INTO live_batches (run, size, created_at, seen_at) VALUES (?, ?, ?, ?)",
                (run, len(datas), time.time(), time.time()),
            )
            batch = cur.lastrowid
            c.executemany(
                "INSERT INTO live_queries (batch_id, idx, data) VALUES (?, ?, ?)",
                [(batch, i, json.dumps(d)) for i, d in enumerate(datas)],
            )
        return batch

    def claim_live(self, pid: int, lease: float = 120.0, stale_after: float = STALE_AFTER) -> int | None:
        """The open live query this participant should answer (kept for ``lease`` seconds), or None.

        First withdraws the open queries of batches whose run has not polled for ``stale_after``
        seconds (the run died while it waited)."""
        now = time.time()
        with self.write() as c:
            stale = "SELECT id FROM live_batches WHERE closed_at IS NULL AND seen_at < ?"
            c.execute(
                f"UPDATE live_queries SET status = 'expired' WHERE status = 'open' AND batch_id IN ({stale})",
                (now - stale_after,),
            )
            c.execute(f"UPDATE live_batches SET closed_at = ? WHERE id IN ({stale})", (now, now - stale_after))
            row = c.execute(
                "SELECT id FROM live_queries WHERE status = 'open' AND claimed_by = ? ORDER BY id LIMIT 1", (pid,)
            ).fetchone()
            if row is None:
                row = c.execute(
                    "SELECT id FROM live_queries WHERE status = 'open' AND (claimed_by IS NULL OR claimed_at < ?)"
                    " ORDER BY id LIMIT 1",
                    (now - lease,),
                ).fetchone()
            if row is None:
                return None
            c.execute("UPDATE live_queries SET claimed_by = ?, claimed_at = ? WHERE id = ?", (pid, now, row[0]))
            return int(row[0])

    def live_query(self, qid: int) -> sqlite3.Row | None:
        return self.conn().execute("SELECT * FROM live_queries WHERE id = ?", (qid,)).fetchone()

    def live_counts(self, batch: int | None = None, touch: bool = False) -> dict[str, int]:
        """Queries by status (of one batch, or all); ``touch``: the batch's run is alive (it polls)."""
        if touch and batch is not None:
            with self.write() as c:
                c.execute("UPDATE live_batches SET seen_at = ? WHERE id = ?", (time.time(), batch))
        sql = "SELECT status, COUNT(*) FROM live_queries" + (" WHERE batch_id = ?" if batch is not None else "")
        rows = self.conn().execute(sql + " GROUP BY status", () if batch is None else (batch,)).fetchall()
        out = {"open": 0, "answered": 0, "expired": 0}
        out.update({r[0]: r[1] for r in rows})
        return out

    def close_batch(self, batch: int) -> None:
        """Stop showing a batch's unanswered queries (an answer committed before this stands)."""
        with self.write() as c:
            c.execute("UPDATE live_queries SET status = 'expired' WHERE batch_id = ? AND status = 'open'", (batch,))
            c.execute("UPDATE live_batches SET closed_at = ? WHERE id = ?", (time.time(), batch))

    def batch_answers(self, batch: int) -> dict[int, str]:
        """``{query index: choice}`` of a batch's answered queries (not those of a participant who declined)."""
        rows = (
            self.conn()
            .execute(
                "SELECT q.idx, a.choice FROM live_queries q JOIN answers a ON a.item_id = ? || q.id"
                " JOIN participants p ON p.id = a.participant_id"
                " WHERE q.batch_id = ? AND q.status = 'answered' AND p.declined_at IS NULL",
                (LIVE_PREFIX, batch),
            )
            .fetchall()
        )
        return {int(r[0]): r[1] for r in rows}
