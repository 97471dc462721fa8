"""Make the fixtures of ``test_migrations.py`` and ``test_metrics_exposition.py`` with the code of
older commits: databases as those versions wrote them, and the ``/metrics`` of 58f13a2.

The committed fixtures are what this script wrote; run it again only to regenerate them
(it needs the repository's history and Debian's ``mosquitto``)::

    .venv/bin/python backend/tests/legacy/make_legacy.py

For each commit it checks the tree out with ``git worktree add --detach`` into a temporary
directory and runs THAT tree's code (``PYTHONPATH=<tree>/backend/src``) with this venv's
interpreter, then removes the worktree:

- ``58f13a2`` (the last commit without schema versions): the whole service as processes, its
  emulator, ``cobot-hmi users add`` and ``cobot-hmi serve`` with the recorder and a Sparkplug
  edge node on a Mosquitto of its own, driven over HTTP as people would (log in, take control,
  write DO 3, name tags, an emergency stop raised on the emulator, acknowledged, a protective
  stop shelved, reset, a login that fails). Its ``/metrics`` shape then goes to
  ``metrics-58f13a2.json``; after a clean stop (SIGINT) its database goes to
  ``hmi-58f13a2.sql``.
- ``5606929`` (robot and origin columns, before summaries, tags and alarms) and ``3dfff02`` (the
  first release's audit and events): that tree's ``Store`` writes a few rows; ``hmi-<commit>.sql``.

A database is committed as the SQL text ``sqlite3``'s ``iterdump`` writes (the schema's
statements as SQLite keeps them, then every row): readable in a review, and the test rebuilds the
same file from it. The metrics shape keeps, per family, its type, help and the label names of
its samples (values, robot names and counts are the run's own).

Everything runs on loopback (127.0.21.0/24). Imports nothing of the project: the code under
test is the old tree's.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
from prometheus_client.parser import text_string_to_metric_families

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parents[2]
SERVICE_COMMIT = "58f13a2"
STORE_COMMITS = ("5606929", "3dfff02")
ROBOT = "m1013"
ROBOT_HOST = "127.0.21.2"
PLC_HOST = "127.0.21.1"
OPERATOR = ("olivia", "olivia-password")
ADMIN = ("ada", "ada-password-1")
DEADLINE_S = 30.0


def free_port(host: str) -> int:
    with socket.socket() as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


def wait_for(what: str, check: Callable[[], bool], timeout_s: float = DEADLINE_S) -> None:
    end = time.monotonic() + timeout_s
    while not check():
        if time.monotonic() > end:
            raise SystemExit(f"make_legacy: {what} not reached in {timeout_s} s")
        time.sleep(0.1)


@contextlib.contextmanager
def worktree(commit: str) -> Iterator[Path]:
    """The tree of ``commit`` in a temporary directory (removed afterwards)."""
    with tempfile.TemporaryDirectory(prefix=f"cobot-hmi-{commit}-") as parent:
        tree = Path(parent) / "tree"
        git = ["git", "-C", str(REPOSITORY), "worktree"]
        subprocess.run([*git, "add", "--detach", str(tree), commit], check=True)
        try:
            # The cyclic pump's C extension is built in place, never committed: the one of this
            # checkout (the same source at the commits this script uses).
            native = REPOSITORY / "backend/src/cobot_hmi/native"
            if (tree / "backend/src/cobot_hmi/native").is_dir():
                for built in native.glob("_cyclic_pump*.so"):
                    shutil.copy(built, tree / "backend/src/cobot_hmi/native")
            yield tree
        finally:
            subprocess.run([*git, "remove", "--force", str(tree)], check=True)


def old_env(tree: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(tree / "backend/src")}


def dump(database: Path, out: Path, commit: str) -> None:
    """The database as SQL text (``iterdump``), headed by where it came from."""
    with contextlib.closing(sqlite3.connect(database)) as db:
        version = db.execute("PRAGMA user_version").fetchone()[0]
        assert version == 0, f"{commit}'s database has user_version {version}"
        lines = list(db.iterdump())
    header = (
        f"-- The service's database as the code at {commit} wrote it "
        "(backend/tests/legacy/make_legacy.py; sqlite3 iterdump).\n"
    )
    out.write_text(header + "\n".join(lines) + "\n")
    print(f"make_legacy: wrote {out.relative_to(REPOSITORY)}")


# --------------------------------------------------------------------------- 58f13a2


def metrics_shape(text: str) -> dict[str, dict[str, object]]:
    """Per family, in the order of the text: type, help, and by sample name the label names of
    its samples (``"robot,state"``; ``""``: none), sorted."""
    shape: dict[str, dict[str, object]] = {}
    for family in text_string_to_metric_families(text):
        samples: dict[str, set[str]] = {}
        for sample in family.samples:
            samples.setdefault(sample.name, set()).add(",".join(sorted(sample.labels)))
        shape[family.name] = {
            "type": family.type,
            "help": family.documentation,
            "samples": {name: sorted(sets) for name, sets in sorted(samples.items())},
        }
    return shape


def histogram_bounds(text: str) -> list[str]:
    """The ``le`` label values of the frame interval histogram (its first robot's), as
    written."""
    for family in text_string_to_metric_families(text):
        if family.name == "cobot_hmi_frame_receive_interval_seconds":
            buckets = [s.labels for s in family.samples if "le" in s.labels]
            return [labels["le"] for labels in buckets if labels["robot"] == buckets[0]["robot"]]
    raise SystemExit("make_legacy: no frame interval histogram in /metrics")


def run_service(tree: Path, work: Path) -> None:
    env = old_env(tree)
    python = [sys.executable, "-m", "cobot_hmi.cli"]
    state = work / "state"
    broker_port = free_port(PLC_HOST)
    http_port = free_port(PLC_HOST)
    control_port = free_port(ROBOT_HOST)
    (work / "mosquitto.conf").write_text(
        f"listener {broker_port} {PLC_HOST}\nallow_anonymous true\npersistence false\n"
    )
    for (name, password), role in ((OPERATOR, "operator"), (ADMIN, "admin")):
        subprocess.run(
            [
                *python,
                "users",
                "add",
                name,
                "--role",
                role,
                "--password-stdin",
                "--state-dir",
                str(state),
            ],
            input=password + "\n",
            text=True,
            env=env,
            check=True,
        )
    processes: list[subprocess.Popen[bytes]] = []
    try:
        mosquitto = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
        processes.append(subprocess.Popen([mosquitto, "-c", str(work / "mosquitto.conf")]))
        processes.append(
            subprocess.Popen(
                [
                    *python,
                    "emulator",
                    "--host",
                    ROBOT_HOST,
                    "--control-port",
                    str(control_port),
                    "--seed",
                    "1",
                    "--no-discovery",
                ],
                env=env,
            )
        )
        service = subprocess.Popen(
            [
                *python,
                "serve",
                "--robot",
                ROBOT_HOST,
                "--robot-name",
                ROBOT,
                "--local-host",
                PLC_HOST,
                "--host",
                PLC_HOST,
                "--port",
                str(http_port),
                "--state-dir",
                str(state),
                "--history",
                "--mqtt-url",
                f"mqtt://{PLC_HOST}:{broker_port}",
            ],
            env=env,
        )
        processes.append(service)
        http = httpx.Client(base_url=f"http://{PLC_HOST}:{http_port}", timeout=DEADLINE_S)
        emulator = httpx.Client(base_url=f"http://{ROBOT_HOST}:{control_port}", timeout=10)

        def ready() -> bool:
            with contextlib.suppress(httpx.HTTPError):
                return http.get(f"/api/v1/robots/{ROBOT}/readyz").status_code == 200
            return False

        wait_for("the service ready", ready)
        drive(http, emulator)
        scrape = http.get("/metrics")
        metrics = scrape.text
        (HERE / "metrics-58f13a2.json").write_text(
            json.dumps(
                {
                    "content_type": scrape.headers["content-type"],
                    "families": metrics_shape(metrics),
                    "histogram_le": histogram_bounds(metrics),
                },
                indent=1,
                ensure_ascii=False,
            )
            + "\n"
        )
        print("make_legacy: wrote metrics-58f13a2.json")
        service.send_signal(signal.SIGINT)  # a clean stop: the database closed
        service.wait(DEADLINE_S)
    finally:
        for process in reversed(processes):
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
                try:
                    process.wait(10)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()
    dump(state / "hmi.db", HERE / f"hmi-{SERVICE_COMMIT}.sql", SERVICE_COMMIT)


def login(http: httpx.Client, user: tuple[str, str]) -> dict[str, str]:
    answer = http.post("/api/v1/auth/login", json={"username": user[0], "password": user[1]})
    answer.raise_for_status()
    http.cookies.clear()  # bearer tokens only: a cookie would make each request a browser's
    return {"Authorization": f"Bearer {answer.json()['token']}"}


def phase(emulator: httpx.Client) -> str:
    status = emulator.get("/status").json()
    robot = status.get("robot", status)
    return str(robot.get("phase"))


def drive(http: httpx.Client, emulator: httpx.Client) -> None:
    """What people do with the service: every table gets rows."""
    operator = login(http, OPERATOR)
    admin = login(http, ADMIN)
    failed = http.post("/api/v1/auth/login", json={"username": "olivia", "password": "wrong"})
    assert failed.status_code == 401, failed.text
    robot = f"/api/v1/robots/{ROBOT}"
    http.put(
        f"{robot}/tags",
        json={"tags": {"controlbox_do.2": "gripper close", "bit_input_registers.40": "part ready"}},
        headers=admin,
    ).raise_for_status()
    http.post(f"{robot}/control/take", headers=operator).raise_for_status()
    http.patch(
        f"{robot}/command", json={"controlbox_do": {"2": True}}, headers=operator
    ).raise_for_status()
    refused = http.patch(f"{robot}/command", json={"analog_output": {"0": 99}}, headers=operator)
    assert refused.status_code == 422, refused.text

    def alarm(key: str) -> dict[str, object]:
        items = http.get("/api/v1/alarms", params={"which": "all"}, headers=operator).json()
        found: dict[str, object] = next(a for a in items["items"] if a["key"] == key)
        return found

    emulator.post("/estop", json={}).raise_for_status()
    wait_for("the e-stop alarm", lambda: alarm("emergency_stop")["state"] != "normal")
    estop = alarm("emergency_stop")
    http.post(
        f"/api/v1/alarms/{estop['id']}/ack", json={"comment": "checked the cell"}, headers=operator
    ).raise_for_status()
    emulator.post("/reset", json={}).raise_for_status()
    wait_for("the e-stop cleared", lambda: alarm("emergency_stop")["state"] == "normal")
    wait_for("the robot back in standby", lambda: phase(emulator) == "normal")
    emulator.post("/protective-stop", json={}).raise_for_status()
    wait_for("the protective stop", lambda: alarm("protective_stop")["state"] != "normal")
    stop = alarm("protective_stop")
    http.post(
        f"/api/v1/alarms/{stop['id']}/shelve",
        json={"reason": "maintenance", "duration_s": 3600},
        headers=operator,
    ).raise_for_status()
    http.post(f"{robot}/control/release", headers=operator).raise_for_status()

    def born() -> bool:
        return "cobot_hmi_sparkplug_born 1.0" in http.get("/metrics").text

    wait_for("the Sparkplug births", born)


# --------------------------------------------------------------------------- older stores

_STORE_SCRIPT = textwrap.dedent(
    """
    import asyncio, sys
    from pathlib import Path
    from cobot_hmi.service.storage.store import AuditEntry, Store

    with_robot = sys.argv[2] == "robot"

    async def main() -> None:
        store = Store(Path(sys.argv[1]))
        await store.open()
        extra = ({"robot": "left", "origin": "PATCH /api/v1/robots/left/command"}
                 if with_robot else {})
        await store.add_audit(AuditEntry("alice", "127.0.0.9", "control.take", [], None, None,
                                         "granted", None, time=1700000000.0, **extra))
        row = await store.add_audit(AuditEntry("alice", "127.0.0.9", "write",
                                               ["controlbox_do.2"], [False], [True], "pending",
                                               None, time=1700000001.0, **extra))
        await store.finish_audit(row, "confirmed", None)
        await store.add_audit(AuditEntry(None, "127.0.0.9", "write", ["analog_output.0"], None,
                                         None, "invalid", "AO 0 is at most 10 V",
                                         time=1700000002.0))
        if with_robot:
            store.submit_event(1700000003.0, "flag", {"flag": "servo_on", "value": True}, "left")
        else:
            store.submit_event(1700000003.0, "flag", {"flag": "servo_on", "value": True})
        store.submit_event(1700000004.0, "robot_state", {"state": 1, "name": "STANDBY"})
        await store.flush_events()
        await store.close()

    asyncio.run(main())
    """
)


def run_store(tree: Path, work: Path, commit: str) -> None:
    database = work / "hmi.db"
    with_robot = "robot" if commit == "5606929" else "plain"
    subprocess.run(
        [sys.executable, "-c", _STORE_SCRIPT, str(database), with_robot],
        env=old_env(tree),
        check=True,
    )
    dump(database, HERE / f"hmi-{commit}.sql", commit)


def main() -> int:
    with worktree(SERVICE_COMMIT) as tree, tempfile.TemporaryDirectory() as work:
        run_service(tree, Path(work))
    for commit in STORE_COMMITS:
        with worktree(commit) as tree, tempfile.TemporaryDirectory() as work:
            run_store(tree, Path(work), commit)
    return 0


if __name__ == "__main__":
    sys.exit(main())
