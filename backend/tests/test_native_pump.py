"""How the cyclic pump is chosen and built (``cobot_hmi.native``): the extension is compiled at
install time, so importing the package compiles and writes nothing; without it the pure-Python
pump takes over with a warning, unless ``COBOT_HMI_PUMP=native`` demands the extension; each
pump object, dropped unclosed, stops its thread. (What the pumps do: test_cyclic_pump.py, for
both.)"""

from __future__ import annotations

import logging
import os
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

import cobot_hmi.native
from cobot_hmi.native import PumpUnavailableError, load_native, pump_class, pure

NATIVE_DIR = Path(cobot_hmi.native.__file__).parent


@pytest.fixture
def extension_missing(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """As on a machine where the extension cannot be imported."""
    monkeypatch.setitem(sys.modules, "cobot_hmi.native._cyclic_pump", None)
    load_native.cache_clear()
    try:
        yield
    finally:
        load_native.cache_clear()


def files_under(root: Path) -> set[Path]:
    return {p for p in root.rglob("*") if "__pycache__" not in p.parts}


def test_the_extension_is_built_and_chosen_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("COBOT_HMI_PUMP", raising=False)
    native, reason = load_native()
    assert native is not None, reason
    assert pump_class() == (native, "native")


def test_importing_and_running_the_pump_compiles_and_writes_nothing(tmp_path: Path) -> None:
    before = files_under(NATIVE_DIR)
    home = tmp_path / "home"
    home.mkdir()
    script = (
        "import asyncio\n"
        "from cobot_hmi.udp_endpoint import UdpEndpoint\n"
        "async def main():\n"
        "    with UdpEndpoint('127.0.0.1', 0, lambda *_: None, receive_size=64) as e:\n"
        "        print(e.implementation)\n"
        "asyncio.run(main())\n"
    )
    env = {
        **os.environ,
        "HOME": str(home),
        "XDG_CACHE_HOME": str(home / ".cache"),
        "PYTHONDONTWRITEBYTECODE": "1",
        "COBOT_HMI_PUMP": "native",
        "PATH": "",  # no compiler to be found, were one looked for
    }
    result = subprocess.run(
        [sys.executable, "-c", script],
        env=env,
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "native"
    assert files_under(NATIVE_DIR) == before, "where the old build wrote its library"
    assert list(home.iterdir()) == []


def test_without_the_extension_the_pure_pump_takes_over_with_a_warning(
    extension_missing: None, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.delenv("COBOT_HMI_PUMP", raising=False)
    cobot_hmi.native._warn_fallback.cache_clear()
    with caplog.at_level(logging.WARNING, logger="cobot_hmi.native"):
        assert pump_class() == (pure.Pump, "python")
    assert "pure-Python pump" in caplog.text
    assert "halted; None in sys.modules" in caplog.text, "and why"


def test_native_demanded_without_the_extension_fails_loudly(
    extension_missing: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COBOT_HMI_PUMP", "native")
    with pytest.raises(PumpUnavailableError, match="cannot be loaded"):
        pump_class()


def test_python_is_chosen_on_request_and_nonsense_is_refused(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("COBOT_HMI_PUMP", "python")
    assert pump_class() == (pure.Pump, "python")
    monkeypatch.setenv("COBOT_HMI_PUMP", "fast")
    with pytest.raises(ValueError, match="native, python or auto"):
        pump_class()


def native_pump_threads() -> int:
    count = 0
    for task in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{task}/comm") as comm:
                count += comm.read().strip() == "cyclic-pump"
        except FileNotFoundError:
            pass
    return count


def python_pump_threads() -> int:
    return sum(1 for t in threading.enumerate() if t.name == "cyclic-pump")


@pytest.mark.parametrize("implementation", ["native", "python"])
def test_a_pump_dropped_unclosed_stops_its_thread(
    implementation: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COBOT_HMI_PUMP", implementation)
    pump_type, _ = pump_class()
    count = native_pump_threads if implementation == "native" else python_pump_threads
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        before = count()
        pump = pump_type(sock.fileno(), 4, 64, 4, 64)
        assert count() == before + 1
        del pump  # no close(): the finalizer joins the thread
        deadline = 100
        while count() != before and deadline:  # the kernel forgets a joined thread promptly
            threading.Event().wait(0.05)
            deadline -= 1
        assert count() == before
        with pump_type(sock.fileno(), 4, 64, 4, 64) as pump:
            assert count() == before + 1
        with pytest.raises(ValueError, match="closed"):
            pump.queued(1)
