"""A tshark capture of a scanner ↔ emulator session (issue 3, "Tests"): Wireshark's own
EtherNet/IP dissector finds no malformed packet and no expert warning, and both directions'
sequence counts rise. ``make test`` installs tshark (Makefile ``system-deps``); a missing tshark
fails here, it is never skipped."""

from __future__ import annotations

import asyncio
import shutil
import signal
from collections import defaultdict
from pathlib import Path

from cobot_hmi.codec import command_from_json
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.scanner.originator import Originator, OriginatorSettings


async def _tshark(*args: str) -> tuple[int, str, str]:
    process = await asyncio.create_subprocess_exec(
        "tshark", *args, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE
    )
    out, err = await asyncio.wait_for(process.communicate(), 60)
    assert process.returncode is not None
    return process.returncode, out.decode(), err.decode()


async def _capture_session(capture: Path, robot_host: str, plc_host: str) -> None:
    tshark = await asyncio.create_subprocess_exec(
        "tshark",
        "-i",
        "lo",
        "-w",
        str(capture),
        "-f",
        f"host {robot_host}",
        stdout=asyncio.subprocess.DEVNULL,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        assert tshark.stderr is not None
        started = b""
        while b"Capturing on" not in started:
            line = await asyncio.wait_for(tshark.stderr.readline(), 30)
            assert line, "tshark ended before capturing"
            started += line
        # dumpcap announces itself a little before packets reach the file: give it a moment,
        # or the Forward Open (which the dissector needs to decode the I/O packets) is missed.
        await asyncio.sleep(1.0)
        target = Target(TargetSettings(host=robot_host), StaticRobot())
        await target.start()
        originator = Originator(OriginatorSettings(robot_host, local_host=plc_host, rpi_us=10_000))
        try:
            await originator.start()
            assert await originator.wait_connected(10)
            await asyncio.sleep(0.3)
            originator.set_run(True)
            sent = originator.set_command(
                command_from_json({"controlbox_do": {"0": True}}, base=originator.command)
            )
            assert await originator.wait_sent(sent, 5)
            await asyncio.sleep(0.5)
        finally:
            await originator.stop()  # Forward Close + UnRegisterSession on the capture
            await target.stop()
        await asyncio.sleep(0.3)
    finally:
        if tshark.returncode is None:
            tshark.send_signal(signal.SIGINT)
        await asyncio.wait_for(tshark.communicate(), 30)


async def test_capture_is_clean_and_sequences_rise(
    tmp_path: Path, robot_host: str, plc_host: str
) -> None:
    assert shutil.which("tshark"), (
        "tshark missing: `make test` installs it (apt-get install tshark)"
    )
    capture = tmp_path / "session.pcapng"
    await _capture_session(capture, robot_host, plc_host)

    code, out, err = await _tshark(
        "-r", str(capture), "-Y", "_ws.malformed || _ws.expert.severity >= warning"
    )
    assert code == 0, err
    assert out.strip() == "", f"tshark flags packets:\n{out}"

    code, out, err = await _tshark(
        "-r",
        str(capture),
        "-Y",
        "enip.cpf.sai.seq",
        "-T",
        "fields",
        "-e",
        "ip.src",
        "-e",
        "enip.cpf.sai.seq",
        "-e",
        "cip.seq",
    )
    assert code == 0, err
    sequences: dict[str, list[tuple[int, int]]] = defaultdict(list)
    for line in out.splitlines():
        source, encap_seq, cip_seq = line.split("\t")
        sequences[source].append((int(encap_seq, 0), int(cip_seq, 0)))
    assert set(sequences) == {robot_host, plc_host}, sequences.keys()
    for source, seqs in sequences.items():
        assert len(seqs) > 20, source
        encap = [e for e, _ in seqs]
        cip = [c for _, c in seqs]
        assert encap == sorted(encap) and len(set(encap)) == len(encap), source
        assert cip == sorted(cip) and cip[-1] > cip[0], source

    code, out, err = await _tshark(
        "-r",
        str(capture),
        "-Y",
        "cip.service == 0x54 || cip.service == 0x4e || cip.service == 0xd4 || cip.service == 0xce",
    )
    assert code == 0, err
    assert len(out.splitlines()) >= 4, f"Forward Open/Close and replies not all decoded:\n{out}"
