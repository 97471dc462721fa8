"""Layer: service (OPC UA). The server enforces its own endpoints, whatever the client does.

asyncua (2.1) leaves three checks to a well-behaved client: a connection starts with
SecurityPolicy None and keeps it when no endpoint matches what the client asks for (so a None
channel, then a session, opens on a server that offers only Basic256Sha256); a user name
token's password is taken as it comes, in clear or encrypted (and an encrypted one's server
nonce is never compared), whatever the token policy says; the client's certificate is checked
at CreateSession only. Here the server checks them itself:

- **OpenSecureChannel** (OPC 10000-6 §6.7): each offered policy and mode opens through a
  ``CheckedFactory``, which first checks the client's certificate (validity period, trust
  list: ``security.ClientValidator.check_channel``); a policy or mode the server does not
  offer is refused. A refusal is an Error message (Bad_CertificateUntrusted,
  Bad_CertificateTimeInvalid, Bad_SecurityPolicyRejected …) and the socket closed. Where None
  is not offered a None channel still opens, for discovery only: GetEndpoints and FindServers
  need no security (OPC 10000-4 §5.4.1) and clients fetch the server's certificate that way.
- **CreateSession and ActivateSession** (``check_session_channel``): the request's channel must
  be open with a policy and mode among the endpoints, else Bad_SecurityPolicyRejected; so a
  discovery-only None channel, or a client that skips OpenSecureChannel, never gets a session.
- **ActivateSession's identity token** (``token_policy``, ``password``): the token names a
  token policy of its channel's endpoint, of its type, else Bad_IdentityTokenInvalid. The two
  user name policies have ids of their own: ``username_basic256sha256`` (None and Sign
  endpoints: the password encrypted with the server's certificate, RSA-OAEP, followed by the
  last server nonce, OPC 10000-4 §7.40.2.1) and ``username_signandencrypt`` (SignAndEncrypt
  endpoints: the password in the token, the channel encrypts it). A password that does not
  follow its policy (in clear where it must be encrypted, another algorithm, another nonce) is
  refused with Bad_IdentityTokenInvalid before the users file is asked.

asyncua has no hook for the first two (its connection objects are private): the factories are
put in place by ``GuardedServer`` (``_setup_server_nodes``, where asyncua makes them; checked
once it listens), and the current request's connection is found by the
task that processes it (``current_connection``). Every such access is in this module.
"""

from __future__ import annotations

import asyncio
import logging
from struct import unpack_from
from typing import Any, Final, NoReturn

from asyncua import Server, ua
from asyncua.crypto import uacrypto
from asyncua.crypto.security_policies import (
    SECURITY_POLICY_TYPE_MAP,
    SecurityPolicy,
    SecurityPolicyFactory,
    SecurityPolicyNone,
)
from asyncua.server.internal_session import ServiceError
from asyncua.ua.ua_binary import uatcp_to_binary
from cryptography import x509

from cobot_hmi.opcua.security import ClientValidator, SecurityError

log = logging.getLogger(__name__)

NONE_URI: Final = SecurityPolicyNone.URI


def username_policy_id(security_policy_uri: str) -> str:
    """A user name token policy's id by the policy its password is encrypted with
    (``username_basic256sha256``), or ``username_signandencrypt`` where the channel does."""
    if not security_policy_uri or security_policy_uri == NONE_URI:
        return "username_signandencrypt"
    return "username_" + security_policy_uri.rsplit("#", 1)[-1].lower()


_DECRYPT: Final = {
    "http://www.w3.org/2001/04/xmlenc#rsa-oaep": uacrypto.decrypt_rsa_oaep,
    "http://opcfoundation.org/UA/security/rsa-oaep-sha2-256": uacrypto.decrypt_rsa_oaep_sha256,
}
_POLICY_CLASSES: Final = {cls.URI: cls for cls, _, _ in SECURITY_POLICY_TYPE_MAP.values()}


class EndpointGuard:
    """What the server offers, and the checks of the module docstring."""

    def __init__(self, offered: list[ua.SecurityPolicyType], validator: ClientValidator) -> None:
        self.offered = frozenset(
            (SECURITY_POLICY_TYPE_MAP[kind][0].URI, SECURITY_POLICY_TYPE_MAP[kind][1])
            for kind in offered
        )
        self.validator = validator
        self.server: Server | None = None
        """Set by ``GuardedServer``: its ``bserver`` holds the connections."""

    # ------------------------------------------------------------ the current connection

    def _protocol(self) -> Any:
        """asyncua's protocol object of the connection whose request is being processed:
        each connection's requests are processed in a task of its own (``_task``)."""
        task = asyncio.current_task()
        binary_server = self.server.bserver if self.server is not None else None
        for protocol in getattr(binary_server, "clients", ()):
            if task is not None and getattr(protocol, "_task", None) is task:
                return protocol
        return None

    def current_connection(self) -> Any:
        """The current request's ``SecureConnection``, or None when not found."""
        protocol = self._protocol()
        processor = getattr(protocol, "processor", None)
        return getattr(processor, "_connection", None)

    # ------------------------------------------------------------ OpenSecureChannel

    def refuse_channel(self, code: int, reason: str) -> NoReturn:
        """Answer the OpenSecureChannel with an Error message, close the socket, and stop
        asyncua's processing of it (``BadUserAccessDenied`` is what makes it close quietly)."""
        protocol = self._protocol()
        transport = getattr(protocol, "transport", None)
        peer = getattr(protocol, "peer_name", None)
        log.warning("OPC UA: secure channel from %s refused: %s", peer, reason)
        if transport is not None:
            error = ua.ErrorMessage(ua.StatusCode(code), reason)
            transport.write(uatcp_to_binary(ua.MessageType.Error, error))
            transport.close()  # the write is flushed first
        raise ua.uaerrors.BadUserAccessDenied()

    def check_certificate(self, peer_certificate: bytes | None) -> None:
        try:
            certificate = uacrypto.x509_from_der(peer_certificate)
        except ValueError:
            certificate = None
        if not isinstance(certificate, x509.Certificate):
            self.refuse_channel(
                ua.StatusCodes.BadCertificateInvalid, "no readable client certificate"
            )
        try:
            self.validator.check_channel(certificate)
        except ServiceError as error:
            name = ua.StatusCode(error.code).name
            self.refuse_channel(error.code, f"client certificate: {name}")

    # ------------------------------------------------------------ sessions

    def check_session_channel(self) -> Any:
        """CreateSession and ActivateSession: the request's channel is open with a policy and
        mode the server offers (module docstring); its ``SecureConnection``."""
        connection = self.current_connection()
        policy = getattr(connection, "security_policy", None)
        if connection is None or policy is None or not connection.is_open():
            raise ServiceError(ua.StatusCodes.BadSecurityPolicyRejected)
        if (policy.URI, policy.Mode) not in self.offered:
            log.warning(
                "OPC UA: session refused over %s %s (not an endpoint)", policy.URI, policy.Mode
            )
            raise ServiceError(ua.StatusCodes.BadSecurityPolicyRejected)
        return connection

    def token_policy(self, token: Any) -> ua.UserTokenPolicy:
        """The token policy of the channel's endpoint that ``token`` names (module doc)."""
        policy = self.check_session_channel().security_policy
        if token is None or (
            isinstance(token, ua.ExtensionObject) and token.TypeId == ua.NodeId(ua.ObjectIds.Null)
        ):
            kind, policy_id = ua.UserTokenType.Anonymous, ""  # OPC 10000-4 §5.6.3: anonymous
        elif isinstance(token, ua.AnonymousIdentityToken):
            kind, policy_id = ua.UserTokenType.Anonymous, token.PolicyId or ""
        elif isinstance(token, ua.UserNameIdentityToken):
            kind, policy_id = ua.UserTokenType.UserName, token.PolicyId or ""
        else:
            raise ServiceError(ua.StatusCodes.BadIdentityTokenInvalid)
        server = self.server
        endpoints = server.iserver.endpoints if server is not None else []
        for endpoint in endpoints:
            if (endpoint.SecurityPolicyUri, endpoint.SecurityMode) != (policy.URI, policy.Mode):
                continue
            for offered in endpoint.UserIdentityTokens:
                if offered.TokenType == kind and (
                    offered.PolicyId == policy_id
                    or (kind == ua.UserTokenType.Anonymous and not policy_id)
                ):
                    return offered
        log.warning("OPC UA: identity token policy %r refused on %s", policy_id, policy.URI)
        raise ServiceError(ua.StatusCodes.BadIdentityTokenInvalid)

    def password(self, token: ua.UserNameIdentityToken, nonce: bytes, private_key: Any) -> str:
        """The token's password, as its token policy says it must come (module docstring)."""
        offered = self.token_policy(token)
        # an empty SecurityPolicyUri means the endpoint's own (OPC 10000-4, UserTokenPolicy)
        uri = offered.SecurityPolicyUri or self.check_session_channel().security_policy.URI
        policy_class = _POLICY_CLASSES.get(uri)
        required = getattr(policy_class, "AsymmetricEncryptionURI", "") if uri != NONE_URI else ""
        algorithm = token.EncryptionAlgorithm or ""
        secret = token.Password or b""
        if algorithm != required:
            log.warning(
                "OPC UA: password of %r refused: %s where its policy says %s",
                token.UserName,
                algorithm or "in clear",
                required or "in clear",
            )
            raise ServiceError(ua.StatusCodes.BadIdentityTokenInvalid)
        if not required:
            return secret.decode("utf-8")
        decrypt = _DECRYPT.get(required)
        if decrypt is None:  # a policy this server cannot decrypt for: never offered
            raise ServiceError(ua.StatusCodes.BadSecurityPolicyRejected)
        return _decrypted(decrypt(private_key, secret), nonce)


def _decrypted(plain: bytes, nonce: bytes) -> str:
    """An encrypted secret: its length (UInt32), the password, the last server nonce."""
    if len(plain) < 4 or not nonce:
        raise ServiceError(ua.StatusCodes.BadIdentityTokenInvalid)
    length = unpack_from("<I", plain)[0]
    secret = plain[4 : 4 + length]
    if length != len(plain) - 4 or length < len(nonce) or secret[-len(nonce) :] != nonce:
        log.warning("OPC UA: an encrypted password without the session's server nonce refused")
        raise ServiceError(ua.StatusCodes.BadIdentityTokenInvalid)
    return secret[: -len(nonce)].decode("utf-8")


class CheckedFactory(SecurityPolicyFactory):
    """An offered policy and mode: the client's certificate is checked before it opens."""

    def __init__(self, factory: SecurityPolicyFactory, guard: EndpointGuard) -> None:
        super().__init__(
            factory.cls,
            factory.mode,
            factory.certificate,
            factory.private_key,
            permission_ruleset=factory.permission_ruleset,
            certificate_chain=factory.certificate_chain,
        )
        self._guard = guard

    def create(self, peer_certificate: bytes | None) -> SecurityPolicy:
        if self.mode != ua.MessageSecurityMode.None_:
            self._guard.check_certificate(peer_certificate)
        policy: SecurityPolicy = super().create(peer_certificate)
        return policy


class DiscoveryOnlyNone(SecurityPolicyFactory):
    """SecurityPolicy None where no endpoint offers it: a channel for discovery only."""

    def __init__(self) -> None:
        super().__init__(SecurityPolicyNone, ua.MessageSecurityMode.None_)


class RefusingFactory(SecurityPolicyFactory):
    """Last in the list: every policy and mode nothing before it matched is refused."""

    def __init__(self, guard: EndpointGuard) -> None:
        super().__init__(SecurityPolicyNone, ua.MessageSecurityMode.Invalid)
        self._guard = guard

    def matches(self, uri: str, mode: ua.MessageSecurityMode | None = None) -> bool:
        return True

    def create(self, peer_certificate: bytes | None) -> SecurityPolicy:
        self._guard.refuse_channel(
            ua.StatusCodes.BadSecurityPolicyRejected, "security policy or mode not offered"
        )


class GuardedServer(Server):
    """asyncua's server whose connections go through an ``EndpointGuard``."""

    def __init__(self, iserver: Any, guard: EndpointGuard) -> None:
        super().__init__(iserver=iserver)
        self.guard = guard
        guard.server = self

    async def _setup_server_nodes(self) -> None:
        # asyncua makes its endpoints and policy factories here, before it listens.
        await super()._setup_server_nodes()
        factories: list[SecurityPolicyFactory] = [
            CheckedFactory(factory, self.guard) for factory in self._policies
        ]
        if (NONE_URI, ua.MessageSecurityMode.None_) not in self.guard.offered:
            factories.append(DiscoveryOnlyNone())
        factories.append(RefusingFactory(self.guard))
        self._policies[:] = factories
        for endpoint in self.iserver.endpoints:
            for token in endpoint.UserIdentityTokens:
                if token.TokenType == ua.UserTokenType.UserName:
                    token.PolicyId = username_policy_id(token.SecurityPolicyUri)

    async def start(self) -> None:
        """asyncua's start, then a check that the connections get the guarded factories: an
        asyncua that made them elsewhere would leave every channel unchecked, so the server
        stops and says so instead."""
        await super().start()
        factories = getattr(self.bserver, "_policies", None)
        if not factories or not isinstance(factories[-1], RefusingFactory):
            await self.stop()
            raise SecurityError("asyncua's security policy factories are not the guarded ones")
