"""Layer: entry point. The ``audit verify`` verb: walk the audit trail's hash chain in a state
directory's database (``service/storage/audit_chain.py``) and say whether it is intact. Read
only: the service may be running. Exit 0 intact, 1 tampered, 2 cannot be verified. Imports
lazily, inside the handler.
"""

from __future__ import annotations

import argparse
import sqlite3
import sys

MAX_FINDINGS_SHOWN = 20
"""Findings listed after the first (the count says how many there are)."""


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from cobot_hmi.cli.hmi_settings import add_hmi_arguments

    parser = subparsers.add_parser(
        "audit",
        help="the audit trail: verify its hash chain",
        description="Work on the audit trail of a state directory's database.",
    )
    verbs = parser.add_subparsers(dest="audit_verb", required=True, metavar="VERB")
    verify = verbs.add_parser(
        "verify",
        help="walk the hash chain; name the first row changed, inserted or deleted",
        description="Walk the audit trail's hash chain from its first row. Exit 0 and the "
        "row count when intact; exit 1 naming the first row changed, inserted or deleted; "
        "exit 2 when the database cannot be read or has no chain yet. Read only.",
    )
    add_hmi_arguments(verify, only=("state_dir", "database"))
    verify.set_defaults(handler=_verify)


def _fail(message: str) -> int:
    print(f"cobot-hmi audit verify: {message}", file=sys.stderr)
    return 2


def _verify(args: argparse.Namespace) -> int:
    import contextlib

    from cobot_hmi.cli.hmi_settings import hmi_settings
    from cobot_hmi.service.service_settings import SettingsError

    try:
        settings = hmi_settings(args)
    except SettingsError as error:
        return _fail(str(error))
    path = settings.web.database_path
    if not path.is_file():
        return _fail(f"{path}: no such database")
    try:
        with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as db:
            return _report(db, str(path))
    except sqlite3.Error as error:
        return _fail(f"{path}: {error}")


def _report(db: sqlite3.Connection, path: str) -> int:
    from cobot_hmi.service.storage import audit_chain
    from cobot_hmi.service.storage.store import iso8601

    present = db.execute(
        "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'audit_chain'"
    ).fetchone()
    if not present:
        return _fail(
            f"{path}: its audit trail has no hash chain yet (a database from before it); the "
            "service seals its rows when it next opens it"
        )
    verdict = audit_chain.verify(db)
    lines = []
    if verdict.legacy_last_id and verdict.legacy_sealed_at is not None:
        lines.append(
            f"rows up to id {verdict.legacy_last_id} were written before the hash chain and "
            f"sealed when the database was migrated, {iso8601(verdict.legacy_sealed_at)}: "
            "what they said before then is not proven"
        )
    if verdict.pending:
        shown = ", ".join(str(row_id) for row_id in verdict.pending[:MAX_FINDINGS_SHOWN])
        lines.append(
            f"{len(verdict.pending)} pending row(s) not sealed yet (sealed with their outcome, "
            f"or as interrupted when the service next starts): {shown}"
        )
    if verdict.intact:
        print(
            f"{path}: audit trail intact: {verdict.rows} rows, {verdict.sealed} sealed; head "
            f"{verdict.head.describe()}"
        )
        for line in lines:
            print(line)
        return 0
    first, *others = verdict.findings
    print(f"{path}: audit trail TAMPERED: {first.text}")
    for finding in others[:MAX_FINDINGS_SHOWN]:
        print(f"  also: {finding.text}")
    if len(others) > MAX_FINDINGS_SHOWN:
        print(f"  … {len(others) - MAX_FINDINGS_SHOWN} more")
    print(
        f"{len(verdict.findings)} finding(s) in {verdict.rows} rows ({verdict.sealed} sealed); "
        f"head {verdict.head.describe()}"
    )
    for line in lines:
        print(line)
    return 1
