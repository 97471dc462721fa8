"""A real OpenLDAP directory for the directory-login tests: Debian's ``slapd`` (``make test``
installs it) with its own configuration, data and certificates in a directory of its own.

``slapd -f`` reads a generated ``slapd.conf``: the core, cosine, inetorgperson and nis schemas,
an mdb database for ``dc=example,dc=org`` (its root ``cn=admin``), the memberof overlay (so
``memberOf`` is offered for ``groupOfNames``, as Active Directory offers it), plain LDAP (with
StartTLS) and LDAPS on free ports of 127.0.0.1, a server certificate for 127.0.0.1 signed by a
CA the fixture makes (``tls_support.TestCa``). Users and groups are added over LDAP once slapd
answers (the overlay runs on adds, not on ``slapadd``):

- ``olga`` in ``cn=operators`` (``groupOfNames``, ``member``);
- ``vera`` in ``cn=viewers`` (``groupOfUniqueNames``, ``uniqueMember``);
- ``adam`` in ``cn=admins`` and ``cn=viewers``; ``nora`` in no group;
- ``gina`` in ``cn=viewers``, for the test that moves her between groups;
- ``cn=hmi-service,ou=services`` the service account (search-then-bind).

Readiness is a condition (an anonymous bind answers), never a sleep; ``stop`` kills slapd
and ``start`` brings it back on the same ports with the same data.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import pytest
from ldap3 import MODIFY_ADD, MODIFY_DELETE, Connection, Server

from conftest import free_tcp_port
from tls_support import TestCa

BASE_DN: Final = "dc=example,dc=org"
PEOPLE: Final = f"ou=people,{BASE_DN}"
GROUPS: Final = f"ou=groups,{BASE_DN}"
ROOT_DN: Final = f"cn=admin,{BASE_DN}"
ROOT_PASSWORD: Final = "root-secret"
SERVICE_DN: Final = f"cn=hmi-service,ou=services,{BASE_DN}"
SERVICE_PASSWORD: Final = "service-secret"
OPERATORS: Final = f"cn=operators,{GROUPS}"
VIEWERS: Final = f"cn=viewers,{GROUPS}"
ADMINS: Final = f"cn=admins,{GROUPS}"
USER_DN_TEMPLATE: Final = f"uid={{user}},{PEOPLE}"
USERS: Final = {
    # name: (password, groups)
    "olga": ("olga-password", (OPERATORS,)),
    "vera": ("vera-password", (VIEWERS,)),
    "adam": ("adam-password", (ADMINS, VIEWERS)),
    "nora": ("nora-password", ()),
    "gina": ("gina-password", (VIEWERS,)),
}
GROUP_ROLES: Final = [f"{OPERATORS}=operator", f"{VIEWERS}=viewer", f"{ADMINS}=admin"]
"""``ldap_group_role`` as the repeated flag gives it."""
INJECTIONS: Final = (
    "*",
    "*)(uid=*",
    "olga)(|(uid=*",
    "olga,ou=people",
    f"olga,{PEOPLE}",
    "olga)(objectClass=*",
    "olga\\",
)
"""Names that a hand-made filter or DN would widen to olga (or everyone); each must be a name
nobody has, so olga's password opens nothing."""
HOST: Final = "127.0.0.1"
READY_DEADLINE_S: Final = 60.0
"""How long slapd may take to answer (a functional deadline: a healthy start takes well
under a second; the machine may be busy)."""


def slapd_binary() -> str | None:
    found = shutil.which("slapd")
    if found:
        return found
    return "/usr/sbin/slapd" if os.access("/usr/sbin/slapd", os.X_OK) else None


needs_slapd = pytest.mark.skipif(
    slapd_binary() is None,
    reason="slapd is not installed (make test installs Debian's slapd and ldap-utils)",
)


def user_dn(name: str) -> str:
    return USER_DN_TEMPLATE.replace("{user}", name)


@dataclass
class Slapd:
    directory: Path
    port: int
    ldaps_port: int
    process: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"ldap://{HOST}:{self.port}"

    @property
    def ldaps_url(self) -> str:
        return f"ldaps://{HOST}:{self.ldaps_port}"

    @property
    def ca_file(self) -> Path:
        return self.directory / "ca.pem"

    @property
    def config(self) -> Path:
        return self.directory / "slapd.conf"

    def start(self) -> None:
        binary = slapd_binary()
        assert binary is not None
        listen = f"ldap://{HOST}:{self.port}/ ldaps://{HOST}:{self.ldaps_port}/"
        # -d 0: stay in the foreground (a child this fixture can kill), no debug output.
        with (self.directory / "slapd.log").open("ab") as log:  # the child keeps its copy
            self.process = subprocess.Popen(
                [binary, "-f", str(self.config), "-h", listen, "-d", "0"],
                stdout=subprocess.DEVNULL,
                stderr=log,
            )
        deadline = time.monotonic() + READY_DEADLINE_S
        while not self._answers():
            if self.process.poll() is not None:
                output = (self.directory / "slapd.log").read_text(errors="replace")
                raise AssertionError(f"slapd exited ({self.process.returncode}): {output[-2000:]}")
            assert time.monotonic() < deadline, "slapd did not answer in time"
            time.sleep(0.02)  # polling a condition (see waiting.py), not a wait that hopes

    def _answers(self) -> bool:
        connection = Connection(Server(self.url, connect_timeout=2), receive_timeout=2)
        try:
            return bool(connection.bind())
        except Exception:
            return False
        finally:
            with contextlib.suppress(Exception):
                connection.unbind()
            if connection.socket is not None:  # a failed open leaves ldap3's socket open
                connection.socket.close()

    def stop(self) -> None:
        process, self.process = self.process, None
        if process is None or process.poll() is not None:
            return
        process.send_signal(signal.SIGKILL)
        process.wait()

    @contextlib.contextmanager
    def admin(self) -> Iterator[Connection]:
        """A connection bound as the directory's root (to change groups in a test)."""
        connection = Connection(
            Server(self.url, connect_timeout=10),
            ROOT_DN,
            ROOT_PASSWORD,
            auto_bind=True,
            receive_timeout=10,
        )
        try:
            yield connection
        finally:
            connection.unbind()

    def move(self, name: str, *, leave: str, join: str) -> None:
        """``name`` out of the group ``leave`` and into ``join`` (both ``groupOfNames`` or
        ``groupOfUniqueNames``, by their member attribute)."""
        with self.admin() as admin:
            for group, change in ((leave, MODIFY_DELETE), (join, MODIFY_ADD)):
                attribute = "uniqueMember" if group == VIEWERS else "member"
                changes = {attribute: [(change, [user_dn(name)])]}
                assert admin.modify(group, changes), admin.result  # type: ignore[no-untyped-call]


def _certificates(directory: Path) -> None:
    """A CA (``ca.pem``) and a server certificate for 127.0.0.1 signed by it."""
    ca = TestCa.create(directory)
    ca.issue(directory / "server.pem", directory / "server.key", HOST, name="slapd")


def _config(directory: Path) -> str:
    schemas = "\n".join(
        f"include /etc/ldap/schema/{name}.schema"
        for name in ("core", "cosine", "inetorgperson", "nis")
    )
    return f"""{schemas}
modulepath /usr/lib/ldap
moduleload back_mdb
moduleload memberof
pidfile {directory}/slapd.pid
argsfile {directory}/slapd.args
TLSCACertificateFile {directory}/ca.pem
TLSCertificateFile {directory}/server.pem
TLSCertificateKeyFile {directory}/server.key

database mdb
maxsize 16777216
suffix "{BASE_DN}"
rootdn "{ROOT_DN}"
rootpw {ROOT_PASSWORD}
directory {directory}/data
overlay memberof
access to attrs=userPassword by anonymous auth by self read by * none
access to * by * read
"""


def _entries() -> list[tuple[str, list[str], dict[str, object]]]:
    entries: list[tuple[str, list[str], dict[str, object]]] = [
        (BASE_DN, ["dcObject", "organization"], {"dc": "example", "o": "Example plant"}),
        (PEOPLE, ["organizationalUnit"], {"ou": "people"}),
        (GROUPS, ["organizationalUnit"], {"ou": "groups"}),
        (f"ou=services,{BASE_DN}", ["organizationalUnit"], {"ou": "services"}),
        (
            SERVICE_DN,
            ["organizationalRole", "simpleSecurityObject"],
            {"cn": "hmi-service", "userPassword": SERVICE_PASSWORD},
        ),
    ]
    for name, (password, _) in USERS.items():
        entries.append(
            (
                user_dn(name),
                ["inetOrgPerson"],
                {"uid": name, "cn": name.title(), "sn": name.title(), "userPassword": password},
            )
        )
    for group, kind, attribute in (
        (OPERATORS, "groupOfNames", "member"),
        (VIEWERS, "groupOfUniqueNames", "uniqueMember"),
        (ADMINS, "groupOfNames", "member"),
    ):
        members = [user_dn(n) for n, (_, groups) in USERS.items() if group in groups]
        entries.append((group, [kind], {"cn": group[3:].split(",")[0], attribute: members}))
    return entries


@contextlib.contextmanager
def running_slapd(directory: Path) -> Iterator[Slapd]:
    """slapd with the test data in ``directory`` (its own config, data, certificates)."""
    (directory / "data").mkdir(parents=True)
    _certificates(directory)
    slapd = Slapd(directory, free_tcp_port(HOST), free_tcp_port(HOST))
    slapd.config.write_text(_config(directory))
    slapd.start()
    try:
        with slapd.admin() as admin:
            for dn, classes, attributes in _entries():
                assert admin.add(dn, classes, attributes), (dn, admin.result)  # type: ignore[no-untyped-call]
        yield slapd
    finally:
        slapd.stop()
