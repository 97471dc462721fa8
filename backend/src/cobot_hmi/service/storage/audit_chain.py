"""Layer: service. The audit trail's hash chain: every final audit row sealed with a SHA-256 over
its content and the previous seal, so a row changed, inserted or deleted in the database file
shows (IEC 62443-3-3 SR 3.9); imports nothing of the project.

**Seal a row when it is final.** A write's or a control request's row is inserted as
``pending`` before the robot is commanded and gets its outcome a few milliseconds later
(``store.finish_audit``), or, when the disk is full, whenever the disk has room again
(``audit_backlog``), or, after a crash, ``interrupted`` when the store next opens. Sealing the
pending row and chaining the outcome as a record of its own would split one row in two places;
sealing it only when its outcome is written keeps one row, one seal. So a row is sealed in the
transaction that makes it final: an insert whose outcome is not ``pending`` (``keep_audit``,
refusals, logins), the outcome's update, the ``interrupted`` update at open. The chain's order
is therefore the order in which rows became final (``seal_seq`` 1, 2, 3 …), not always their
ids' order. A ``pending`` row is not sealed yet: ``verify`` lists it and does not count it as
tampering (the service may be running, or a crash left it until the next start). The outcome
of a sealed row cannot be written again (``finish``).

**The seal.** ``seal_hash = sha256(previous seal_hash + "\\n" + canonical)``, where canonical
is the JSON array (orjson, compact) of the seal's number and the row's columns ``SEALED`` as
stored (the JSON columns as their text, the time as SQLite's REAL). The first seal's previous
is ``GENESIS``. The table ``audit_chain`` (one row) keeps the head: the last seal's number,
hash and row, so deleting the newest rows shows too; the head goes to the log and to
``/metrics`` at intervals, where a copy outside this file is kept.

**Rows from before the chain** (a database of schema version 4 or older): migration step 5
records the last row id then (``legacy_last_id``); the store, when it opens, seals those rows
in id order, once, in one transaction, and notes the time (``legacy_sealed_at``). ``verify``
says which rows were sealed then: their content before that time is not proven.

**What it does not prove**: anyone who can write the file and knows this algorithm can append
rows with valid seals, or recompute every seal after a change together with the head. Only a
copy of the head kept elsewhere (the log, a Prometheus server's scrape of ``/metrics``)
shows that; docs/operations.md "Audit verify".
"""

from __future__ import annotations

import hashlib
import sqlite3
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Final, Literal

import orjson

GENESIS: Final = "0" * 64
"""The previous seal of the first row."""
SEALED: Final = (
    "id",
    "time",
    "robot",
    "user",
    "client",
    "origin",
    "action",
    "fields",
    "before",
    "requested",
    "outcome",
    "reason",
    "summary",
    "tags",
)
"""The audit columns a seal covers: every column of the table but the seal's own two."""
PENDING: Final = "pending"
_SELECT: Final = ", ".join(f'"{name}"' for name in SEALED)


@dataclass(frozen=True, slots=True)
class ChainHead:
    """The newest seal: its number, hash and row (``seq`` 0: nothing sealed yet)."""

    seq: int
    hash: str
    row_id: int | None

    def describe(self) -> str:
        if self.seq == 0:
            return "no row sealed yet"
        return f"seal #{self.seq}, row {self.row_id}, sha256 {self.hash[:16]}"


def _blob(value: object) -> object:
    """A value JSON has no form for (a BLOB a hand edit put in a column): its bytes in hex."""
    if isinstance(value, bytes):
        return {"blob": value.hex()}
    raise TypeError(type(value).__name__)


def seal_hash(previous: str, seq: int, row: Sequence[object]) -> str:
    """The seal of a row whose ``SEALED`` columns are ``row``, number ``seq`` after
    ``previous``."""
    canonical = orjson.dumps([seq, *row], default=_blob)
    return hashlib.sha256(previous.encode("ascii") + b"\n" + canonical).hexdigest()


def head(db: sqlite3.Connection) -> ChainHead:
    seq, digest, row_id = db.execute(
        "SELECT seal_seq, seal_hash, row_id FROM audit_chain WHERE id = 1"
    ).fetchone()
    return ChainHead(int(seq), str(digest), row_id)


def seal(db: sqlite3.Connection, row_id: int) -> ChainHead:
    """Seal row ``row_id`` as the next link, in the caller's transaction; the new head."""
    last = head(db)
    row = db.execute(f"SELECT {_SELECT} FROM audit WHERE id = ?", (row_id,)).fetchone()
    seq = last.seq + 1
    digest = seal_hash(last.hash, seq, row)
    db.execute("UPDATE audit SET seal_seq = ?, seal_hash = ? WHERE id = ?", (seq, digest, row_id))
    db.execute(
        "UPDATE audit_chain SET seal_seq = ?, seal_hash = ?, row_id = ? WHERE id = 1",
        (seq, digest, row_id),
    )
    return ChainHead(seq, digest, row_id)


def finish(db: sqlite3.Connection, row_id: int, outcome: str, reason: str | None) -> bool:
    """Write a ``pending`` row's outcome and seal it; ``False``: the row is not pending (sealed
    already, or gone), nothing changed."""
    changed = db.execute(
        "UPDATE audit SET outcome = ?, reason = ? WHERE id = ? AND seal_seq IS NULL",
        (outcome, reason, row_id),
    ).rowcount
    if changed:
        seal(db, row_id)
    return bool(changed)


def seal_at_open(db: sqlite3.Connection, interrupted: Iterable[int], now_s: float) -> int:
    """When the store opens, in its transaction: the rows from before the chain (once), then
    the rows a crash left pending and the store just marked ``interrupted``; how many rows
    from before the chain were sealed now."""
    legacy_last_id, sealed_at = db.execute(
        "SELECT legacy_last_id, legacy_sealed_at FROM audit_chain WHERE id = 1"
    ).fetchone()
    sealed_legacy = 0
    if sealed_at is None:
        for (row_id,) in db.execute(
            "SELECT id FROM audit WHERE id <= ? AND seal_seq IS NULL ORDER BY id",
            (legacy_last_id,),
        ).fetchall():
            seal(db, row_id)
            sealed_legacy += 1
        db.execute("UPDATE audit_chain SET legacy_sealed_at = ? WHERE id = 1", (now_s,))
    for row_id in sorted(interrupted):
        unsealed = db.execute(
            "SELECT 1 FROM audit WHERE id = ? AND seal_seq IS NULL", (row_id,)
        ).fetchone()
        if unsealed:
            seal(db, row_id)
    return sealed_legacy


# ----------------------------------------------------------------- verify

Kind = Literal["changed", "inserted", "deleted"]


@dataclass(frozen=True, slots=True)
class Finding:
    """One place where the chain shows tampering."""

    kind: Kind
    row_id: int | None
    """The row (``None``: a deleted row, known only by its neighbours)."""
    text: str


@dataclass(slots=True)
class Verdict:
    """What ``verify`` found."""

    rows: int
    sealed: int
    head: ChainHead
    """The head as the ``audit_chain`` table keeps it."""
    pending: list[int] = field(default_factory=list)
    findings: list[Finding] = field(default_factory=list)
    legacy_last_id: int = 0
    legacy_sealed_at: float | None = None

    @property
    def intact(self) -> bool:
        return not self.findings


def verify(db: sqlite3.Connection) -> Verdict:
    """Walk the chain from its first seal: the findings in chain order (the first row changed,
    inserted or deleted first), then rows without a seal that are not pending."""
    stored, legacy_last_id, legacy_sealed_at, rows = _read_audit(db)
    chain = [row for row in rows if row[0] is not None]
    verdict = Verdict(
        rows=len(rows),
        sealed=len(chain),
        head=stored,
        legacy_last_id=int(legacy_last_id or 0),
        legacy_sealed_at=legacy_sealed_at,
    )
    last_seq, last_hash, last_id = _walk_chain(chain, stored, verdict.findings)
    _check_head(stored, last_seq, last_hash, last_id, verdict.findings)
    for _, _, *content in rows[len(chain) :]:
        row_id, outcome = content[0], content[SEALED.index("outcome")]
        if outcome == PENDING:
            verdict.pending.append(row_id)
        else:
            text = (
                f"row {row_id} inserted: it carries no seal (outcome {outcome!r}; only pending "
                "rows are not sealed yet)"
            )
            verdict.findings.append(Finding("inserted", row_id, text))
    return verdict


def _read_audit(db: sqlite3.Connection) -> tuple[ChainHead, Any, Any, list[Any]]:
    """The head, the legacy seal's row and time, and every audit row (sealed ones in chain
    order first), read in one transaction: one moment, while the service seals more."""
    own = not db.in_transaction
    if own:
        db.execute("BEGIN")
    try:
        stored = head(db)
        legacy_last_id, legacy_sealed_at = db.execute(
            "SELECT legacy_last_id, legacy_sealed_at FROM audit_chain WHERE id = 1"
        ).fetchone()
        rows = db.execute(
            f"SELECT seal_seq, seal_hash, {_SELECT} FROM audit"
            " ORDER BY seal_seq IS NULL, seal_seq, id"
        ).fetchall()
    finally:
        if own:
            db.rollback()
    return stored, legacy_last_id, legacy_sealed_at, rows


def _walk_chain(
    chain: list[Any], stored: ChainHead, findings: list[Finding]
) -> tuple[int, str, int | None]:
    """Each sealed row against the one before it: what was inserted, deleted or changed into
    ``findings``; the last seal's number and hash and its row."""
    previous, expected, previous_id = GENESIS, 1, None
    by_seq: dict[int, int] = {}
    for seq, digest, *content in chain:
        row_id = content[0]
        if not isinstance(seq, int) or seq < expected:
            owner = by_seq.get(seq) if isinstance(seq, int) else None
            has = f"row {owner}" if owner else "an earlier row"
            text = f"row {row_id} inserted: it carries seal #{seq}, which {has} has"
            findings.append(Finding("inserted", row_id, text))
            continue
        if seq > stored.seq:
            text = (
                f"row {row_id} inserted: its seal #{seq} is beyond the chain's head #{stored.seq}"
            )
            findings.append(Finding("inserted", row_id, text))
            continue
        if seq > expected:
            missing = f"#{expected}" if seq == expected + 1 else f"#{expected}–#{seq - 1}"
            where = f"between {_row(previous_id)} and row {row_id}"
            text = f"{seq - expected} row(s) deleted: seal {missing} missing, {where}"
            findings.append(Finding("deleted", None, text))
        elif seal_hash(previous, seq, content) != digest:
            text = (
                f"row {row_id} changed: its content does not match its seal #{seq} (or the "
                "seal itself was rewritten)"
            )
            findings.append(Finding("changed", row_id, text))
        by_seq[seq] = row_id
        previous, expected, previous_id = str(digest), seq + 1, row_id
    return expected - 1, previous, previous_id


def _check_head(
    stored: ChainHead,
    last_seq: int,
    last_hash: str,
    last_id: int | None,
    findings: list[Finding],
) -> None:
    """The chain's last seal against the stored head: newest rows deleted, or rows appended
    (or the head rewritten)."""
    if stored.seq > last_seq:
        first = last_seq + 1
        missing = f"#{first}" if stored.seq == first else f"#{first}–#{stored.seq}"
        text = (
            f"{stored.seq - last_seq} newest row(s) deleted: seal {missing} missing after "
            f"{_row(last_id)} (the head is seal #{stored.seq})"
        )
        findings.append(Finding("deleted", None, text))
    elif stored.seq < last_seq or (last_seq and stored.hash != last_hash):
        text = (
            f"{_row(last_id)} (seal #{last_seq}) is not the chain's head "
            f"({stored.describe()}): rows appended or the head rewritten"
        )
        findings.append(Finding("inserted", last_id, text))


def _row(row_id: int | None) -> str:
    return "the first row" if row_id is None else f"row {row_id}"
