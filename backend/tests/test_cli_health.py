"""``cobot-hmi health simulate`` as a user runs it: the engine on the emulated arm's program,
faster than real time, each joint's verdict and figures printed as JSON (``joints`` as the
service's health answer gives them)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

CLI = [sys.executable, "-m", "cobot_hmi.cli", "health", "simulate"]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=120, check=False)


def test_simulate_prints_each_joints_verdict_with_the_wear_on_its_joint() -> None:
    result = run("--arm", "M1013", "--cycles", "50", "--wear", "3:friction=+10%")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    joints = report["joints"]
    assert [j["joint"] for j in joints] == [1, 2, 3, 4, 5, 6]
    assert [j["verdict"] for j in joints] == ["ok", "ok", "watch", "ok", "ok", "ok"]
    assert joints[2]["reason"].startswith("J3: friction ")
    assert joints[2]["friction_percent"] == pytest.approx(10.0, abs=2.5)
    for joint in joints:
        assert set(joint) >= {
            "joint",
            "verdict",
            "reason",
            "friction_percent",
            "heat_excess_c",
            "life_used_percent",
            "life_remaining_h",
            "signature_rms_percent",
            "rated",
        }
    assert report["simulation"]["wear"] == [
        {"joint": 3, "field": "friction_percent", "value": 10.0}
    ]
    assert report["cycle_time"]["verdict"] == "ok"


def test_simulate_from_a_cold_start_on_the_other_arm_is_all_ok() -> None:
    result = run("--arm", "M0609", "--cycles", "30", "--cold-start")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["arm"] == "M0609"
    assert [j["verdict"] for j in report["joints"]] == ["ok"] * 6


@pytest.mark.parametrize("wear", ["7:friction=+10%", "3:grease=+10%", "3friction10"])
def test_simulate_refuses_a_bad_wear_option(wear: str) -> None:
    result = run("--cycles", "1", "--wear", wear)
    assert result.returncode == 2
    assert "--wear" in result.stderr
    assert "JOINT:KIND=VALUE" in result.stderr
