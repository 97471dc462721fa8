"""Layer: service (OPC UA). Which security the server offers, its certificate, its trust list.

- **Policies**: Basic256Sha256 with Sign and with SignAndEncrypt always; SecurityPolicy None
  (no signature, no encryption) only when the server binds a loopback address, or when
  ``opcua_allow_no_security`` says so: elsewhere a client asking for None finds no such
  endpoint and its secure channel is refused. ``describe`` says which, in the log at start.
- **The application certificate**: made at the first start (RSA 2048, SHA-256, self-signed,
  5 years, the application URI and the host's name and address in its subjectAltName) in
  ``STATE_DIR/opcua/pki/own/`` (the key 0600) and kept: clients that trusted it go on trusting
  it. Its application URI is the server's.
- **The trust list**: a client's certificate is accepted when it is in the trusted directory
  (``opcua_trust_dir``, default ``STATE_DIR/opcua/pki/trusted``, DER or PEM), read again for
  each new secure channel and session, so adding a file takes effect without a restart. It is
  checked when the secure channel opens (``ClientValidator.check_channel``, from
  ``channel_policy``), and again with the application URI at CreateSession. A refused certificate is
  written to ``pki/rejected/`` (named by its thumbprint): moving it into ``trusted/`` trusts it,
  as in UaExpert's and most servers' workflow.
"""

from __future__ import annotations

import contextvars
import ipaddress
import logging
import os
import re
import socket
from datetime import UTC, datetime
from pathlib import Path
from typing import Final

from asyncua import Server, ua
from asyncua.crypto import cert_gen
from asyncua.crypto.truststore import TrustStore
from asyncua.crypto.validator import CertificateValidator, CertificateValidatorOptions
from asyncua.server.internal_session import ServiceError
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from cryptography.x509.oid import ExtendedKeyUsageOID

log = logging.getLogger(__name__)

CERTIFICATE_DAYS: Final = 5 * 365
APPLICATION_NAME: Final = "cobot-hmi"
POLICIES_SECURE: Final = (
    ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
    ua.SecurityPolicyType.Basic256Sha256_Sign,
)


class SecurityError(RuntimeError):
    """The OPC UA server cannot start with these settings (the message says why)."""


def policies(*, loopback: bool, allow_no_security: bool) -> list[ua.SecurityPolicyType]:
    """The security policies and modes offered (module docstring)."""
    offered = list(POLICIES_SECURE)
    if loopback or allow_no_security:
        offered.append(ua.SecurityPolicyType.NoSecurity)
    return offered


def describe(host: str, port: int, *, loopback: bool, allow_no_security: bool) -> str:
    """What the server offers on its address, in words for the log (never silent about None)."""
    where = f"opc.tcp://{host}:{port}"
    if loopback:
        return f"{where}: Basic256Sha256 Sign, SignAndEncrypt, and None (a loopback address)"
    if allow_no_security:
        return (
            f"{where}: Basic256Sha256 Sign, SignAndEncrypt, and None (opcua_allow_no_security: "
            "anyone on the network can read the traffic)"
        )
    return (
        f"{where}: Basic256Sha256 Sign and SignAndEncrypt only (SecurityPolicy None needs a "
        "loopback address or --opcua-allow-no-security)"
    )


def application_uri(hostname: str) -> str:
    return f"urn:{hostname}:{APPLICATION_NAME}"


class Certificates:
    """The server's own certificate and key, and the client trust list (module docstring)."""

    def __init__(self, pki_dir: Path, trusted_dir: Path, bind_host: str) -> None:
        self.own_dir = pki_dir / "own"
        self.trusted_dir = trusted_dir
        self.rejected_dir = pki_dir / "rejected"
        self.certificate_path = self.own_dir / "cert.der"
        self.key_path = self.own_dir / "key.pem"
        self._bind_host = bind_host
        self.application_uri = application_uri(socket.gethostname() or "localhost")

    def ensure(self) -> None:
        """Make the directories, and the certificate at the first start; read its URI."""
        for directory in (self.own_dir, self.trusted_dir, self.rejected_dir):
            directory.mkdir(parents=True, exist_ok=True)
        os.chmod(self.own_dir, 0o700)
        if not (self.certificate_path.is_file() and self.key_path.is_file()):
            self._make()
        certificate = x509.load_der_x509_certificate(self.certificate_path.read_bytes())
        uris = certificate.extensions.get_extension_for_class(
            x509.SubjectAlternativeName
        ).value.get_values_for_type(x509.UniformResourceIdentifier)
        if not uris:
            raise SecurityError(
                f"{self.certificate_path}: no application URI in its subjectAltName"
            )
        self.application_uri = uris[0]

    def _make(self) -> None:
        key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
        hostname = socket.gethostname() or "localhost"
        names: list[x509.GeneralName] = [
            x509.UniformResourceIdentifier(self.application_uri),
            x509.DNSName(hostname),
        ]
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(self._bind_host)))
        except ValueError:
            names.append(x509.DNSName(self._bind_host))
        certificate = cert_gen.generate_self_signed_app_certificate(
            key,
            f"{APPLICATION_NAME}@{hostname}",
            {"organizationName": APPLICATION_NAME},
            names,
            extended=[ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH],
            days=CERTIFICATE_DAYS,
        )
        pem = key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.TraditionalOpenSSL,
            serialization.NoEncryption(),
        )
        descriptor = os.open(self.key_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(descriptor, "wb") as file:
            file.write(pem)
        self.certificate_path.write_bytes(certificate.public_bytes(serialization.Encoding.DER))
        log.info("OPC UA: made the application certificate %s", self.certificate_path)

    def thumbprint(self) -> str:
        certificate = x509.load_der_x509_certificate(self.certificate_path.read_bytes())
        return certificate.fingerprint(hashes.SHA1()).hex()

    def validator(self) -> ClientValidator:
        return ClientValidator(self.trusted_dir, self.rejected_dir)


SECURE_CHANNEL: Final[contextvars.ContextVar[bool]] = contextvars.ContextVar(
    "opcua_secure_channel", default=True
)
"""Whether the session being created came over a signed channel (``sessions`` sets it)."""


class ClientValidator:
    """Checks a client's certificate when its secure channel opens (``check_channel``: its
    validity period, that it is trusted) and at CreateSession (those, and that its
    subjectAltName names the client's application URI); a refused one goes to the rejected
    directory."""

    def __init__(self, trusted_dir: Path, rejected_dir: Path) -> None:
        self._trusted_dir = trusted_dir
        self._rejected_dir = rejected_dir
        self._store = TrustStore([trusted_dir], [])
        self._validator = CertificateValidator(
            CertificateValidatorOptions.TIME_RANGE
            | CertificateValidatorOptions.URI
            | CertificateValidatorOptions.TRUSTED
            | CertificateValidatorOptions.PEER_CLIENT,
            self._store,
        )
        self.rejected = 0

    async def __call__(
        self, certificate: x509.Certificate, description: ua.ApplicationDescription
    ) -> None:
        if not SECURE_CHANNEL.get():  # Part 4 §5.6.2: with None the certificate is ignored
            return
        try:
            await self._store.load_trust()  # a file just added to trusted/ counts at once
            await self._validator.validate(certificate, description)
        except ValueError:  # no certificate in the trusted directory: nobody is trusted
            error = ServiceError(ua.StatusCodes.BadCertificateUntrusted)
            self._reject(certificate, description, error)
            raise error from None
        except ServiceError as error:
            self._reject(certificate, description.ApplicationUri, error)
            raise

    def check_channel(self, certificate: x509.Certificate) -> None:
        """At OpenSecureChannel (OPC 10000-6 §6.7): the validity period, and trusted (the
        application URI is checked at CreateSession, which names it). Synchronous: asyncua
        selects a channel's policy in a plain call; the trust list is a few small files."""
        now = datetime.now(UTC)
        if not certificate.not_valid_before_utc <= now <= certificate.not_valid_after_utc:
            error = ServiceError(ua.StatusCodes.BadCertificateTimeInvalid)
        elif not self._trusted(certificate):
            error = ServiceError(ua.StatusCodes.BadCertificateUntrusted)
        else:
            return
        self._reject(certificate, _uri_of(certificate), error)
        raise error

    def _trusted(self, certificate: x509.Certificate) -> bool:
        """Whether the trusted directory, as it is now, trusts ``certificate`` (the same
        verification as asyncua's ``TrustStore.is_trusted``)."""
        trusted: list[x509.Certificate] = []
        for path in sorted(self._trusted_dir.glob("*.*")):
            if not _TRUST_FILE.match(path.name.lower()):
                continue
            try:
                data = path.read_bytes()
                trusted.append(
                    x509.load_pem_x509_certificate(data)
                    if data.lstrip().startswith(b"-----")
                    else x509.load_der_x509_certificate(data)
                )
            except (OSError, ValueError) as error:
                log.warning("OPC UA: %s is not a readable certificate (%s)", path, error)
        if not trusted:
            return False
        verifier = self._store.policy_builder.store(
            x509.verification.Store(trusted)
        ).build_client_verifier()
        try:
            verifier.verify(certificate, [])
        except x509.verification.VerificationError:
            return False
        return True

    def _reject(self, certificate: x509.Certificate, who: str, error: ServiceError) -> None:
        self.rejected += 1
        name = certificate.fingerprint(hashes.SHA1()).hex()
        path = self._rejected_dir / f"{name}.der"
        if not path.exists():
            path.write_bytes(certificate.public_bytes(serialization.Encoding.DER))
        log.warning(
            "OPC UA: client certificate of %s refused (%s); saved as %s: move it into %s "
            "to trust it",
            who,
            ua.StatusCode(error.code).name,
            path,
            self._trusted_dir,
        )


_TRUST_FILE: Final = re.compile(r".*(der|pem)")
"""The trusted directory's certificate files (asyncua's ``TrustStore`` reads the same)."""


def _uri_of(certificate: x509.Certificate) -> str:
    """The application URI in a certificate's subjectAltName, for the log."""
    try:
        names = certificate.extensions.get_extension_for_class(x509.SubjectAlternativeName)
    except x509.ExtensionNotFound:
        return certificate.subject.rfc4514_string()
    uris = names.value.get_values_for_type(x509.UniformResourceIdentifier)
    return uris[0] if uris else certificate.subject.rfc4514_string()


async def load_into(server: Server, certificates: Certificates) -> None:
    """The certificate and key into the asyncua server."""
    await server.load_certificate(str(certificates.certificate_path))
    await server.load_private_key(str(certificates.key_path))
