"""Layer: service. HTTPS and WSS without a proxy: the listener's TLS context, its certificate
re-read when the files change, and the HSTS policy.

``ReloadingContext`` builds a server context (TLS 1.2 at least; Python's defaults otherwise:
forward-secret AEAD ciphers only at OpenSSL's security level 2) from the PEM files of
``--tls-cert`` and ``--tls-key``, and gives uvicorn its ``listener``. A certificate is replaced
by writing new files; no restart. OpenSSL copies a context's certificate into each connection
when the connection is made, so the check is at the start of each handshake: the context's
SNI callback (OpenSSL calls it for every ClientHello, with or without a server name) compares
the files' modification time, size and inode with those last loaded, and on a change loads
them into a new context, which this connection and every later one use (``SSLObject.context``
swapped before the certificate is chosen). Two ``stat`` calls per handshake; nothing on a
request. Connections already open keep the certificate they began with.

A pair that does not load (the key written after the certificate, a key that does not match,
a half-written file) leaves the last good certificate in use and is logged once per change of
the files; the next handshake after the second file lands loads the pair. At startup a pair
that does not load is an error (``TlsError``), the service does not start.

HSTS (RFC 6797) is sent on answers over HTTPS only (``SecurityHeaders``), for a year, not for
subdomains: a plant's other devices under the same domain are not this service's to decide.
"""

from __future__ import annotations

import contextlib
import logging
import os
import ssl
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from cryptography import x509
from cryptography.hazmat.primitives import hashes

log = logging.getLogger(__name__)

MINIMUM_VERSION: Final = ssl.TLSVersion.TLSv1_2
HSTS_MAX_AGE_S: Final = 365 * 24 * 3600
HSTS_HEADER: Final = f"max-age={HSTS_MAX_AGE_S}".encode()


class TlsError(RuntimeError):
    """The certificate or key cannot be used (which file, and why)."""


@dataclass(frozen=True, slots=True)
class _Signature:
    """What tells a changed file: both files' (mtime_ns, size, inode)."""

    cert: tuple[int, int, int]
    key: tuple[int, int, int]


def _stat(path: Path) -> tuple[int, int, int]:
    status = os.stat(path)
    return status.st_mtime_ns, status.st_size, status.st_ino


def server_context(cert: Path, key: Path) -> ssl.SSLContext:
    """A server context for the pair; ``TlsError`` saying which file is wrong."""
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.minimum_version = MINIMUM_VERSION
    try:
        context.load_cert_chain(cert, key)
    except FileNotFoundError as error:
        raise TlsError(f"{error.filename}: no such file") from None
    except ssl.SSLError as error:
        raise TlsError(
            f"{cert} with {key}: not a PEM certificate and its matching private key "
            f"({error.reason or error})"
        ) from None
    except OSError as error:
        raise TlsError(f"{error.filename or cert}: {error.strerror}") from None
    return context


class ReloadingContext:
    """The listener's TLS context (``listener``), its certificate re-read when the files
    change; ``reloads`` and ``failures`` count what happened."""

    def __init__(self, cert: Path, key: Path) -> None:
        self.cert = cert
        self.key = key
        try:
            self._signature: _Signature | None = self._read_signature()
        except OSError as error:
            raise TlsError(f"{error.filename}: {error.strerror}") from None
        self.listener = server_context(cert, key)
        self.listener.sni_callback = self._on_hello
        self.current = self.listener
        """The context new connections use (the listener's until the files change)."""
        self.not_after_s = not_after_of(cert)
        """When the certificate in use expires (s since the epoch): for the operators' alert."""
        self.reloads = 0
        self.failures = 0
        self._failed: _Signature | None = None
        """The files as they were when they last failed to load (not tried again)."""
        self._error: str | None = None

    def _read_signature(self) -> _Signature:
        return _Signature(_stat(self.cert), _stat(self.key))

    def refresh(self) -> bool:
        """Load the files again when they changed since last loaded; whether a new pair is in
        use now."""
        try:
            signature = self._read_signature()
        except OSError as error:  # between a rotation's remove and its write
            self._fail(f"{error.filename}: {error.strerror}")
            return False
        if signature in (self._signature, self._failed):
            return False
        try:
            fresh = server_context(self.cert, self.key)
        except TlsError as error:
            self._failed = signature
            self._fail(str(error))
            return False
        self.current, self._signature, self._failed, self._error = fresh, signature, None, None
        self.reloads += 1
        fingerprint = "?"
        with contextlib.suppress(OSError, ValueError):  # loaded a moment ago; replaced since?
            certificate = _certificate(self.cert)
            self.not_after_s = certificate.not_valid_after_utc.timestamp()
            fingerprint = _fingerprint(certificate)
        log.warning("TLS certificate reloaded from %s (%s)", self.cert, fingerprint)
        return True

    def _fail(self, why: str) -> None:
        """Counted and logged once until something else happens."""
        if why == self._error:
            return
        self._error = why
        self.failures += 1
        log.error("TLS certificate not reloaded, the last good one stays in use: %s", why)

    def _on_hello(
        self, connection: ssl.SSLObject | ssl.SSLSocket, server_name: str | None, _: ssl.SSLContext
    ) -> None:
        self.refresh()
        if self.current is not self.listener:
            connection.context = self.current


def _certificate(cert: Path) -> x509.Certificate:
    """The first certificate in a PEM file."""
    return x509.load_pem_x509_certificate(cert.read_bytes())


def _fingerprint(certificate: x509.Certificate) -> str:
    return ":".join(f"{byte:02X}" for byte in certificate.fingerprint(hashes.SHA256()))


def not_after_of(cert: Path) -> float:
    """When the first certificate in a PEM file expires (its notAfter, s since the epoch)."""
    return _certificate(cert).not_valid_after_utc.timestamp()


def fingerprint_of(cert: Path) -> str:
    """The SHA-256 fingerprint of the first certificate in a PEM file (``AB:CD:…``), as a
    browser shows it."""
    return _fingerprint(_certificate(cert))
