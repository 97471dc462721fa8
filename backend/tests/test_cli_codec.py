"""``cobot-hmi decode`` and ``cobot-hmi encode-command`` as a user runs them."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from golden_vectors import GOLDEN_DIR

CLI = [sys.executable, "-m", "cobot_hmi.cli"]


def run(*args: str, stdin: bytes = b"") -> subprocess.CompletedProcess[bytes]:
    return subprocess.run([*CLI, *args], input=stdin, capture_output=True, timeout=60, check=False)


def test_decode_hex_file_prints_the_frame_as_json() -> None:
    result = run("decode", "--hex", str(GOLDEN_DIR / "t2o_mid_motion.hex"))
    assert result.returncode == 0, result.stderr
    expected = json.loads((GOLDEN_DIR / "t2o_mid_motion.json").read_text())
    assert json.loads(result.stdout) == expected


def test_decode_binary_from_stdin(tmp_path: Path) -> None:
    wire = bytes.fromhex((GOLDEN_DIR / "t2o_every_bit_extreme.hex").read_text())
    result = run("decode", "-", stdin=wire + b"\x01\x02")
    assert result.returncode == 0, result.stderr
    decoded = json.loads(result.stdout)
    assert decoded["robot_state_name"] == "UNKNOWN"
    assert decoded["extra"] == "0102"


@pytest.mark.parametrize(
    ("stdin", "reason"),
    [
        (b"00" * 283, "expected 284 bytes, got 283"),
        (b"zz", "bad hex input"),
    ],
)
def test_decode_bad_frame_exits_2_with_one_line(stdin: bytes, reason: str) -> None:
    result = run("decode", "--hex", "-", stdin=stdin)
    assert result.returncode == 2
    assert reason in result.stderr.decode()
    assert len(result.stderr.decode().strip().splitlines()) == 1
    assert result.stdout == b""


def test_decode_missing_file_exits_2() -> None:
    result = run("decode", "/nonexistent/frame.bin")
    assert result.returncode == 2
    assert "cannot read" in result.stderr.decode()


def test_encode_command_partial_json_to_hex() -> None:
    body = {
        "controlbox_do": {"2": True},
        "tool_do": {"0": True},
        "analog_output_type": {"0": 1},
        "analog_output": {"0": 7.5, "1": 12.0},
        "bit_input_registers": {"40": True},
    }
    result = run("encode-command", "--hex", stdin=json.dumps(body).encode())
    assert result.returncode == 0, result.stderr
    expected = (GOLDEN_DIR / "o2t_commissioning.hex").read_text().strip()
    assert result.stdout.decode().strip() == expected


def test_encode_command_raw_bytes_and_empty_image() -> None:
    result = run("encode-command", stdin=b"{}")
    assert result.returncode == 0
    assert result.stdout == bytes(20)


@pytest.mark.parametrize(
    ("body", "reason"),
    [
        (b'{"controlbox_do": {"16": true}}', "index out of range"),
        (b'{"digital_out": {"0": true}}', "unknown field 'digital_out'"),
        (b'{"analog_output": {"0": NaN}}', "not a finite number"),
        (b'{"analog_output": {"0": Infinity}}', "not a finite number"),
        (b"{not json", "not JSON"),
    ],
)
def test_encode_command_refuses_bad_input(body: bytes, reason: str) -> None:
    result = run("encode-command", "--hex", stdin=body)
    assert result.returncode == 2
    assert reason in result.stderr.decode()
    assert result.stdout == b""


def test_codegen_check_passes_on_the_committed_tree() -> None:
    result = run("codegen", "--check")
    assert result.returncode == 0, result.stdout.decode()
