"""The ``demo`` verb: a cell of emulated robots (an M1013 at 127.0.0.2 and an M0609 at
127.0.0.5), each its own process, and the service against them on http://127.0.0.1:8000 with a
fresh operator password. Every address is checked before anything starts; Ctrl-C stops the
service first (Forward Close while the robots still listen), then the emulators, which also end
when the demo is killed.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import errno
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO, TYPE_CHECKING, Final

if TYPE_CHECKING:
    from cobot_hmi.settings import HmiSettings

DEMO_ROBOTS: Final = (
    # name, address, model, seed of its noise: two arms, two programs (each model's own).
    ("m1013", "127.0.0.2", "M1013", 1),
    ("m0609", "127.0.0.5", "M0609", 2),
)
DEMO_HTTP_HOST: Final = "127.0.0.1"
DEMO_HTTP_PORT: Final = 8000
DEMO_USER: Final = "operator"


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    demo = subparsers.add_parser(
        "demo",
        help="two emulated robots (127.0.0.2, 127.0.0.5) and the service on http://127.0.0.1:8000",
        description=(
            "Start emulated robots as processes of their own (an M1013 at 127.0.0.2 and an "
            "M0609 at 127.0.0.5) and the service against them, serving the built frontend. The "
            "state (users file, database) lives in a fresh temporary directory unless "
            "--state-dir is given; the operator's password is printed once. Every address is "
            "checked first: one that is taken ends the demo with a message. Ctrl-C stops all "
            "(the service sends its Forward Closes first); the emulators also end when the demo "
            "is killed."
        ),
    )
    demo.add_argument(
        "--robots",
        type=int,
        choices=range(1, len(DEMO_ROBOTS) + 1),
        default=None,
        help=f"how many robots (default {len(DEMO_ROBOTS)}, or as many as --robot-host gives)",
    )
    demo.add_argument(
        "--robot-host",
        action="append",
        default=None,
        metavar="HOST",
        help="an emulator's address, once per robot in order (default "
        + ", ".join(host for _, host, _, _ in DEMO_ROBOTS)
        + ")",
    )
    _add_address_arguments(demo)
    _add_door_arguments(demo)
    demo.set_defaults(handler=_demo)


def _add_address_arguments(demo: argparse.ArgumentParser) -> None:
    """Where the emulators, the service's T→O port and its HTTP listener are; the RPI; the state
    directory, the frontend and HTTPS."""
    demo.add_argument("--robot-tcp-port", type=int, default=44818, help="emulators' TCP port")
    demo.add_argument("--robot-udp-port", type=int, default=2222, help="emulators' UDP port")
    demo.add_argument(
        "--control-port",
        type=int,
        default=8081,
        help="emulators' control API port, each on its own address (0: any free port)",
    )
    demo.add_argument("--local-host", default=DEMO_HTTP_HOST, help="address receiving T→O")
    demo.add_argument("--local-udp-port", type=int, default=2222, help="UDP port receiving T→O")
    demo.add_argument("--host", default=DEMO_HTTP_HOST, help="HTTP bind address")
    demo.add_argument("--port", type=int, default=DEMO_HTTP_PORT, help="HTTP port")
    demo.add_argument("--rpi-ms", type=float, default=10.0, help="RPI, ms")
    demo.add_argument(
        "--state-dir",
        type=Path,
        default=None,
        help="users file and database (default: a fresh temporary directory, removed at the end)",
    )
    demo.add_argument("--frontend-dir", type=Path, default=None, help="built frontend")
    demo.add_argument(
        "--tls",
        action="store_true",
        help="serve HTTPS and WSS with a self-signed certificate made in the state directory "
        "(its SHA-256 fingerprint printed; docs/operations.md, 'Certificates')",
    )
    demo.add_argument(
        "--http-redirect-port",
        type=int,
        default=None,
        metavar="PORT",
        help="with --tls: plain HTTP on this port of --host that only redirects to HTTPS "
        "(80 beside 443 on a kiosk's address)",
    )


def _add_door_arguments(demo: argparse.ArgumentParser) -> None:
    """The doors the demo may open too: Sparkplug B and OPC UA."""
    demo.add_argument(
        "--mqtt-url",
        default=None,
        metavar="URL",
        help="also publish the cell to this MQTT broker as a Sparkplug B edge node "
        "(mqtt://HOST:PORT; docs/operations.md, 'Sparkplug B')",
    )
    demo.add_argument(
        "--mqtt-writes",
        action="store_true",
        help="with --mqtt-url: accept DCMD writes (through control, audited)",
    )
    demo.add_argument(
        "--opcua-url",
        default=None,
        metavar="URL",
        help="also serve the cell over OPC UA (opc.tcp://HOST[:PORT], port 4840 by default; "
        "docs/operations.md, 'OPC UA')",
    )
    demo.add_argument(
        "--opcua-writes",
        action="store_true",
        help="with --opcua-url: clients may write the command image (through control, audited)",
    )


def _fail(reason: str) -> int:
    print(f"cobot-hmi: {reason}", file=sys.stderr)
    return 2


class _DemoError(Exception):
    """Why the demo cannot start; printed as it is."""


TAKEN_GRACE_S: Final = 3.0
"""How long a taken address is probed again before the demo gives up: an emulator of a demo
that was just killed (it ends on its parent's death) lets go of its addresses within moments,
and a supervisor restarting the demo at once must not be refused for it."""


def _probe(host: str, port: int, kind: int) -> None:
    """Bind ``host:port`` as its real owner will (``OSError`` when someone else holds it).

    TCP: with ``SO_REUSEADDR``, as the emulator's and the service's listeners bind, so the last
    run's connections still in TIME-WAIT or FIN-WAIT-2 do not count; on Linux the bind still
    fails while another socket listens there. UDP has no such leftovers: a plain bind, as the
    class 1 sockets bind, fails exactly while another socket is bound there."""
    with socket.socket(socket.AF_INET, kind) as probe:
        if kind == socket.SOCK_STREAM:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind((host, port))


def _check_free(host: str, port: int, kind: int, what: str) -> None:
    """``_DemoError`` when another socket holds ``host:port`` (a listener, for TCP), still
    after ``TAKEN_GRACE_S``."""
    deadline = time.monotonic() + TAKEN_GRACE_S
    while True:
        try:
            _probe(host, port, kind)
        except OSError as error:
            if error.errno == errno.EADDRINUSE and time.monotonic() < deadline:
                time.sleep(0.05)
                continue
            proto = "TCP" if kind == socket.SOCK_STREAM else "UDP"
            raise _DemoError(
                f"{what}: {proto} {host}:{port} is taken ({error.strerror}); is another demo or "
                "emulator running? Stop it, or give other addresses (cobot-hmi demo --help)"
            ) from None
        return


def _bind_http(host: str, port: int) -> socket.socket:
    """The HTTP listening socket, bound now so nobody takes it between check and serve."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
    except OSError as error:
        sock.close()
        raise _DemoError(
            f"the HMI: TCP {host}:{port} is taken ({error.strerror}); is another demo running? "
            "Stop it, or give another --host/--port"
        ) from None
    return sock


def _die_with_parent(parent_pid: int) -> None:
    """In the emulator's process, before exec: end with SIGTERM when the demo ends, even by
    ``kill -9`` (Linux ``prctl(PR_SET_PDEATHSIG)``, kept across exec)."""
    import ctypes

    pr_set_pdeathsig = 1
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(pr_set_pdeathsig, signal.SIGTERM, 0, 0, 0)
    if os.getppid() != parent_pid:  # the demo died before prctl took effect
        os._exit(1)


DEMO_CYCLE_MARKER_REGISTER: Final = 63
"""The bit output register the demo's emulators mark each cycle start on, and the service's
cycle trigger (docs/emulator.md "The demo program's cycle marker")."""


def _start_emulator(
    args: argparse.Namespace, host: str, model: str, seed: int
) -> subprocess.Popen[bytes]:
    command = [
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "emulator",
        "--host",
        host,
        "--tcp-port",
        str(args.robot_tcp_port),
        "--udp-port",
        str(args.robot_udp_port),
        "--control-port",
        str(args.control_port),
        "--model",
        model,
        "--seed",
        str(seed),
        "--verbose",  # its connection log shows the Forward Close on Ctrl-C
        "--cycle-marker-register",  # the demo program marks each cycle's start
        str(DEMO_CYCLE_MARKER_REGISTER),
    ]
    parent_pid = os.getpid()
    # Its own session: the terminal's Ctrl-C reaches only us, so the service can still send
    # its Forward Close to a live emulator before we stop it.
    return subprocess.Popen(
        command,
        start_new_session=True,
        stdout=subprocess.PIPE,
        env=os.environ.copy(),
        preexec_fn=lambda: _die_with_parent(parent_pid),  # noqa: PLW1509 (no threads yet)
    )


def _wait_ready(process: subprocess.Popen[bytes], host: str, timeout_s: float) -> None:
    """Until OUR emulator says it serves (another one on the address must not pass for it),
    then its further output goes to ours."""
    import selectors

    assert process.stdout is not None
    stream = process.stdout
    deadline = time.monotonic() + timeout_s
    seen = b""
    with selectors.DefaultSelector() as selector:
        selector.register(stream, selectors.EVENT_READ)
        while b"\n" not in seen:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise _DemoError(f"the emulator at {host} did not start in {timeout_s:.0f} s")
            if not selector.select(remaining):
                continue
            chunk = os.read(stream.fileno(), 4096)
            if not chunk:
                process.wait()
                said = seen.decode(errors="replace").strip()
                raise _DemoError(f"the emulator at {host} did not start: {said or 'it ended'}")
            seen += chunk
    line = seen.decode(errors="replace")
    if "EtherNet/IP target on" not in line:
        raise _DemoError(f"the emulator at {host} did not start: {line.strip()}")
    sys.stdout.write(line)
    sys.stdout.flush()
    threading.Thread(target=_copy_output, args=(stream,), daemon=True).start()


def _copy_output(stream: IO[bytes]) -> None:
    with contextlib.suppress(OSError, ValueError):
        while chunk := os.read(stream.fileno(), 4096):
            sys.stdout.buffer.write(chunk)
            sys.stdout.flush()


def _stop_process(process: subprocess.Popen[bytes], timeout_s: float = 5.0) -> None:
    if process.poll() is not None:
        return
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def _stop_all(processes: list[subprocess.Popen[bytes]]) -> None:
    for process in processes:
        _stop_process(process)


def _demo_robots(args: argparse.Namespace) -> list[tuple[str, str, str, int]]:
    hosts: list[str] = args.robot_host or []
    count = args.robots if args.robots is not None else (len(hosts) or len(DEMO_ROBOTS))
    if len(hosts) > count:
        raise _DemoError(f"--robot-host given {len(hosts)} times for {count} robot(s)")
    robots = []
    for index, (name, host, model, seed) in enumerate(DEMO_ROBOTS[:count]):
        robots.append((name, hosts[index] if index < len(hosts) else host, model, seed))
    return robots


def _demo(args: argparse.Namespace) -> int:
    import tempfile

    from cobot_hmi.service.config.loading import load_settings
    from cobot_hmi.service.service_settings import SettingsError
    from cobot_hmi.settings import HmiSettings

    try:
        robots = _demo_robots(args)
    except _DemoError as error:
        return _fail(str(error))
    if args.http_redirect_port is not None and not args.tls:
        return _fail("--http-redirect-port redirects to HTTPS: give --tls too")
    with contextlib.ExitStack() as stack:
        state_dir: Path = args.state_dir
        if state_dir is None:
            # Fresh for each demo: two demos on one machine never share (or reset) a password.
            state_dir = Path(
                stack.enter_context(tempfile.TemporaryDirectory(prefix="cobot-hmi-demo-"))
            )
        flags: dict[str, object] = {
            "robots": [
                {"name": name, "host": host, "tcp_port": args.robot_tcp_port}
                for name, host, _, _ in robots
            ],
            "local_host": args.local_host,
            "local_udp_port": args.local_udp_port,
            "host": args.host,
            "port": args.port,
            "rpi_ms": args.rpi_ms,
            "state_dir": state_dir,
            "cycle_trigger": f"bit_output_registers.{DEMO_CYCLE_MARKER_REGISTER}:rising",
        }
        if args.frontend_dir is not None:
            flags["frontend_dir"] = args.frontend_dir
        if args.tls:
            from cobot_hmi.service.api.tls_selfsigned import self_signed_pair

            flags["tls_cert"], flags["tls_key"], _ = self_signed_pair(state_dir, [args.host])
            flags["http_redirect_port"] = args.http_redirect_port
        if args.mqtt_url is not None:
            flags["mqtt_url"] = args.mqtt_url
            flags["mqtt_writes"] = args.mqtt_writes
        if args.opcua_url is not None:
            flags["opcua_url"] = args.opcua_url
            flags["opcua_writes"] = args.opcua_writes
        try:
            settings = load_settings(flags, None, None, HmiSettings)
        except SettingsError as error:
            return _fail(str(error))
        try:
            return _run_demo(args, settings, robots, stack)
        except _DemoError as error:
            return _fail(str(error))


def _run_demo(
    args: argparse.Namespace,
    settings: HmiSettings,
    robots: list[tuple[str, str, str, int]],
    stack: contextlib.ExitStack,
) -> int:
    from cobot_hmi.composition import build_service
    from cobot_hmi.service.access.users import Role, UsersError, UsersFile, generate_password
    from cobot_hmi.service.api.server import prepare_process, serve
    from cobot_hmi.service.api.tls import fingerprint_of

    # Every address first: nothing starts, and no password is shown, while one is taken.
    http_socket = stack.enter_context(_bind_http(args.host, args.port))
    if settings.tls.http_redirect_port is not None:
        _check_free(
            args.host, settings.tls.http_redirect_port, socket.SOCK_STREAM, "the HMI's redirect"
        )
    _check_free(args.local_host, args.local_udp_port, socket.SOCK_DGRAM, "the HMI's T→O port")
    for name, host, _, _ in robots:
        what = f"the emulator {name}"
        _check_free(host, args.robot_tcp_port, socket.SOCK_STREAM, what)
        _check_free(host, args.robot_udp_port, socket.SOCK_DGRAM, what)
        if args.control_port:
            _check_free(host, args.control_port, socket.SOCK_STREAM, f"{what}'s control API")
    emulators: list[subprocess.Popen[bytes]] = []
    stack.callback(_stop_all, emulators)
    for _, host, model, seed in robots:
        emulators.append(_start_emulator(args, host, model, seed))
    for (_, host, _, _), process in zip(robots, emulators, strict=True):
        _wait_ready(process, host, timeout_s=30)
    try:
        password = generate_password()
        UsersFile(settings.web.users_path).add(DEMO_USER, Role.OPERATOR, password)
    except UsersError as error:
        raise _DemoError(str(error)) from None
    scheme = "https" if settings.tls.tls_cert is not None else "http"
    url = f"{scheme}://{args.host}:{http_socket.getsockname()[1]}/"
    cell = ", ".join(f"{name} ({model}) at {host}" for name, host, model, _ in robots)
    # From the printout on, Ctrl-C stops the demo cleanly (exit 0), also when it comes before
    # the server has taken SIGINT over (uvicorn's handler, asyncio.run's before it): a user
    # who has just read the password may press it at once.
    tls, edge = settings.tls, settings.sparkplug  # HTTPS, the Sparkplug B edge node
    with contextlib.suppress(KeyboardInterrupt):
        print(
            f"cobot-hmi demo: {cell}; HMI at {url}\n"
            f"  log in as {DEMO_USER!r} with password {password!r} (shown only now)\n"
            f"  state in {settings.web.state_dir}"
            + (" (removed at the end)" if args.state_dir is None else "")
            + (
                f"\n  TLS certificate {tls.tls_cert} (self-signed), SHA-256 fingerprint\n"
                f"    {fingerprint_of(tls.tls_cert)}"
                if tls.tls_cert is not None
                else ""
            )
            + (
                f"\n  plain HTTP on http://{args.host}:{tls.http_redirect_port}/ redirects to it"
                if tls.http_redirect_port is not None
                else ""
            )
            + (
                f"\n  Sparkplug B to {edge.mqtt_url}: spBv1.0/{edge.sparkplug_group}/+/"
                f"{edge.sparkplug_node_id}/# (writes {'on' if edge.mqtt_writes else 'off'})"
                if edge.mqtt_url
                else ""
            )
            + (
                f"\n  OPC UA at {settings.opcua.opcua_url} (writes "
                f"{'on' if settings.opcua.opcua_writes else 'off'})"
                if settings.opcua.opcua_url
                else ""
            )
            + "\n  Ctrl-C stops all.",
            flush=True,
        )
        prepare_process()
        asyncio.run(serve(settings, build_service, sockets=[http_socket]))
    _stop_all(emulators)
    print("cobot-hmi demo: stopped.", flush=True)
    return 0
