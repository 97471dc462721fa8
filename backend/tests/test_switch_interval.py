"""The service process's GIL hand-over deadline follows its cyclic pump (service/api/server.py):
CPython's 5 ms with the C pump, whose thread needs no GIL to keep the packets' timing; 0.5 ms
with the pure-Python pump, whose thread needs the GIL for every packet."""

from __future__ import annotations

import sys
from collections.abc import Iterator

import pytest

from cobot_hmi import native
from cobot_hmi.service.api import server


@pytest.fixture
def restored_interval() -> Iterator[None]:
    before = sys.getswitchinterval()
    yield
    sys.setswitchinterval(before)


@pytest.mark.usefixtures("restored_interval")
def test_the_c_pump_keeps_cpythons_switch_interval(monkeypatch: pytest.MonkeyPatch) -> None:
    if native.load_native()[0] is None:
        pytest.fail("the C extension is built at install (make venv): " + native.load_native()[1])
    monkeypatch.setenv(native.ENV_VAR, "native")
    server.prepare_process()
    assert sys.getswitchinterval() == pytest.approx(0.005)


@pytest.mark.usefixtures("restored_interval")
@pytest.mark.parametrize("choice", ["python", "bogus"])
def test_the_python_pump_hands_the_gil_over_sooner(
    monkeypatch: pytest.MonkeyPatch, choice: str
) -> None:
    monkeypatch.setenv(native.ENV_VAR, choice)
    server.prepare_process()
    assert sys.getswitchinterval() == pytest.approx(0.0005)
