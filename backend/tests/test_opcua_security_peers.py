"""The OPC UA server's own security (issue 37), seen by a client that checks nothing for it.

node-opcua (``test_opcua``) refuses on its side what the server does not offer, so it cannot
show that the server refuses. The peer here is raw OPC UA binary over a socket (``RawChannel``:
asyncua's encoders and its client-side ``SecureConnection`` for the chunks and the crypto,
every request and its parameters chosen by the test): a None channel where no endpoint offers
None, a session asked over it, a password in clear where its token policy says encrypted, a
certificate nobody trusted. asyncua's own ``Client`` then shows that a client that follows the
endpoints still gets in. Run against the server before issue 37 (asyncua's checks alone), the
five refusal tests fail; the two others (TakeControl over SignAndEncrypt, asyncua's client over
None) are the positive controls and pass either way.

One cell for the module: one simulated robot, the service with OPC UA on a loopback address
(None offered there, writes on) and, from the same service, a second OPC UA server bound to
0.0.0.0 (Basic256Sha256 only).
"""

from __future__ import annotations

import asyncio
import contextlib
import struct
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import pytest_asyncio
from asyncua import Client, ua
from asyncua.common.connection import SecureConnection, TransportLimits
from asyncua.common.utils import create_nonce
from asyncua.crypto import uacrypto
from asyncua.crypto.security_policies import (
    SecurityPolicy,
    SecurityPolicyAes128Sha256RsaOaep,
    SecurityPolicyBasic256Sha256,
    SecurityPolicyNone,
    encrypt_asymmetric,
)
from asyncua.ua.ua_binary import (
    Primitives,
    header_from_binary,
    nodeid_from_binary,
    struct_from_binary,
    struct_to_binary,
    uatcp_to_binary,
)
from asyncua.ua.uatypes import ObjectIds
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization

from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.opcua.feed import ServiceFeed
from cobot_hmi.opcua.server import OpcUaServer
from conftest import _next_host as next_host
from emulator_harness import FAST_TIMINGS
from opcua_support import CLIENT_URI, client_certificate, listening_port, trust
from service_support import OPERATOR, Running, cell_settings, running_service

pytestmark = [pytest.mark.timeout(300), pytest.mark.asyncio(loop_scope="module")]

ANSWER_S = 30.0
"""How long the server may take to answer one message (a functional bound)."""
B256 = SecurityPolicyBasic256Sha256
NONE_URI = SecurityPolicyNone.URI
SIGN, ENCRYPT, NO_MODE = (
    ua.MessageSecurityMode.Sign,
    ua.MessageSecurityMode.SignAndEncrypt,
    ua.MessageSecurityMode.None_,
)
ROBOT_URI = "urn:cobot-hmi:robot:still"
NAMESPACES = ua.NodeId(ObjectIds.Server_NamespaceArray)


class RefusedError(Exception):
    """The server answered with an Error message or a ServiceFault, or closed the socket."""

    def __init__(self, code: int) -> None:
        super().__init__(ua.StatusCode(code).name)
        self.code = code
        self.name = ua.StatusCode(code).name


@dataclass
class Identity:
    """A client application's certificate and key (DER, and the key object)."""

    certificate: x509.Certificate
    key: Any

    @classmethod
    def load(cls, paths: tuple[Path, Path]) -> Identity:
        certificate = x509.load_pem_x509_certificate(paths[0].read_bytes())
        key = serialization.load_pem_private_key(paths[1].read_bytes(), password=None)
        return cls(certificate, key)


class RawChannel:
    """One connection whose every frame the test decides (see the module docstring)."""

    def __init__(
        self,
        reader: asyncio.StreamReader,
        writer: asyncio.StreamWriter,
        url: str,
        policy: SecurityPolicy,
    ) -> None:
        self._reader, self._writer = reader, writer
        self.url = url
        self.policy = policy
        self._connection = SecureConnection(policy, TransportLimits())
        self._request_id = 0
        self.authentication_token = ua.NodeId()
        self.server_nonce = b""
        self.server_certificate = b""

    @classmethod
    @contextlib.asynccontextmanager
    async def connect(
        cls, host: str, port: int, policy: SecurityPolicy | None = None
    ) -> AsyncIterator[RawChannel]:
        reader, writer = await asyncio.open_connection(host, port)
        channel = cls(reader, writer, f"opc.tcp://{host}:{port}", policy or SecurityPolicyNone())
        try:
            writer.write(uatcp_to_binary(ua.MessageType.Hello, ua.Hello(EndpointUrl=channel.url)))
            assert isinstance(await channel._receive(), ua.Acknowledge)
            yield channel
        finally:
            writer.close()
            with contextlib.suppress(OSError):
                await writer.wait_closed()

    async def _receive(self) -> Any:
        try:
            head = await asyncio.wait_for(self._reader.readexactly(8), ANSWER_S)
            size = struct.unpack_from("<I", head, 4)[0]
            data = head + await asyncio.wait_for(self._reader.readexactly(size - 8), ANSWER_S)
        except asyncio.IncompleteReadError:
            raise RefusedError(ua.StatusCodes.BadConnectionClosed) from None
        buffer = ua.utils.Buffer(data)
        message = self._connection.receive_from_header_and_body(header_from_binary(buffer), buffer)
        if isinstance(message, ua.ErrorMessage):
            raise RefusedError(message.Error.value)
        return message

    async def _send(self, request: Any, kind: ua.MessageType = ua.MessageType.SecureMessage) -> Any:
        self._request_id += 1
        request.RequestHeader.AuthenticationToken = self.authentication_token
        request.RequestHeader.RequestHandle = self._request_id
        request.RequestHeader.TimeoutHint = int(ANSWER_S * 1000)
        self._writer.write(
            self._connection.message_to_binary(
                struct_to_binary(request), message_type=kind, request_id=self._request_id
            )
        )
        body = (await self._receive()).body()
        if nodeid_from_binary(body.copy()) == ua.FourByteNodeId(
            ObjectIds.ServiceFault_Encoding_DefaultBinary
        ):
            fault = struct_from_binary(ua.ServiceFault, body)
            raise RefusedError(fault.ResponseHeader.ServiceResult.value)
        return body

    async def closed_by_server(self) -> bool:
        """Whether the server closes the socket (end of stream, nothing more sent)."""
        return await asyncio.wait_for(self._reader.read(1), ANSWER_S) == b""

    async def open(self, mode: ua.MessageSecurityMode | None = None) -> None:
        """OpenSecureChannel with the channel's policy and its mode (or ``mode``)."""
        nonce = create_nonce(self.policy.secure_channel_nonce_length)
        parameters = ua.OpenSecureChannelParameters(
            RequestType=ua.SecurityTokenRequestType.Issue,
            SecurityMode=self.policy.Mode if mode is None else mode,
            ClientNonce=nonce,
            RequestedLifetime=600_000,
        )
        request = ua.OpenSecureChannelRequest(Parameters=parameters)
        body = await self._send(request, ua.MessageType.SecureOpen)
        response = struct_from_binary(ua.OpenSecureChannelResponse, body)
        self._connection.set_channel(response.Parameters, ua.SecurityTokenRequestType.Issue, nonce)

    async def endpoints(self) -> list[ua.EndpointDescription]:
        request = ua.GetEndpointsRequest(Parameters=ua.GetEndpointsParameters(EndpointUrl=self.url))
        response = struct_from_binary(ua.GetEndpointsResponse, await self._send(request))
        endpoints: list[ua.EndpointDescription] = response.Endpoints
        return endpoints

    async def create_session(self) -> None:
        parameters = ua.CreateSessionParameters(
            ClientDescription=ua.ApplicationDescription(
                ApplicationUri=CLIENT_URI,
                ApplicationName=ua.LocalizedText("raw peer"),
                ApplicationType=ua.ApplicationType.Client,
            ),
            EndpointUrl=self.url,
            SessionName="raw peer",
            ClientNonce=create_nonce(32),
            ClientCertificate=self.policy.host_certificate,
            RequestedSessionTimeout=60_000,
            MaxResponseMessageSize=0,
        )
        body = await self._send(ua.CreateSessionRequest(Parameters=parameters))
        result = struct_from_binary(ua.CreateSessionResponse, body).Parameters
        self.authentication_token = result.AuthenticationToken
        self.server_nonce = result.ServerNonce
        self.server_certificate = result.ServerCertificate

    async def activate(self, token: Any) -> None:
        signature = ua.SignatureData()
        if self.policy.Mode != NO_MODE:
            signature.Algorithm = self.policy.AsymmetricSignatureURI
            signature.Signature = self.policy.asymmetric_cryptography.signature(
                self.server_certificate + self.server_nonce
            )
        parameters = ua.ActivateSessionParameters(
            ClientSignature=signature, UserIdentityToken=token, LocaleIds=["en"]
        )
        body = await self._send(ua.ActivateSessionRequest(Parameters=parameters))
        self.server_nonce = struct_from_binary(
            ua.ActivateSessionResponse, body
        ).Parameters.ServerNonce

    async def read(self, node: ua.NodeId) -> ua.DataValue:
        parameters = ua.ReadParameters(
            NodesToRead=[ua.ReadValueId(NodeId=node, AttributeId=ua.AttributeIds.Value)]
        )
        body = await self._send(ua.ReadRequest(Parameters=parameters))
        value: ua.DataValue = struct_from_binary(ua.ReadResponse, body).Results[0]
        return value

    async def call(self, robot: ua.NodeId, method: ua.NodeId) -> ua.CallMethodResult:
        request = ua.CallRequest(
            Parameters=ua.CallParameters(
                MethodsToCall=[ua.CallMethodRequest(ObjectId=robot, MethodId=method)]
            )
        )
        result: ua.CallMethodResult = struct_from_binary(
            ua.CallResponse, await self._send(request)
        ).Results[0]
        return result


def clear_password(policy_id: str, user: tuple[str, str]) -> ua.UserNameIdentityToken:
    return ua.UserNameIdentityToken(
        PolicyId=policy_id, UserName=user[0], Password=user[1].encode(), EncryptionAlgorithm=None
    )


def encrypted_password(
    policy_id: str, user: tuple[str, str], server_certificate: bytes, nonce: bytes
) -> ua.UserNameIdentityToken:
    """OPC 10000-4 §7.40.2.1: length, password, server nonce, encrypted with the server's key."""
    public_key = uacrypto.x509_from_der(server_certificate).public_key()
    secret = Primitives.Bytes.pack(user[1].encode() + nonce)
    data, algorithm = encrypt_asymmetric(public_key, secret, B256.URI)
    return ua.UserNameIdentityToken(
        PolicyId=policy_id, UserName=user[0], Password=data, EncryptionAlgorithm=algorithm
    )


@dataclass
class Cell:
    running: Running
    loopback: tuple[str, int]
    """The service's own OPC UA server (None offered)."""
    open_bind: tuple[str, int]
    """The second server, bound to 0.0.0.0: where to connect to it."""
    server_certificate: x509.Certificate
    trusted: Identity
    state_dir: Path
    namespace: int = 0

    def secure(self, identity: Identity, mode: ua.MessageSecurityMode) -> SecurityPolicy:
        return B256(self.server_certificate, identity.certificate, identity.key, mode)

    def robot(self, path: str = "") -> ua.NodeId:
        return ua.NodeId(f"still.{path}" if path else "still", self.namespace)


@contextlib.asynccontextmanager
async def _cell(state_dir: Path) -> AsyncIterator[Cell]:
    plc_host, robot_host = next_host(), next_host()
    robot = SimulatedRobot(RobotSettings(timings=FAST_TIMINGS))
    target = Target(TargetSettings(host=robot_host, tcp_port=0), robot)
    await target.start()
    port = listening_port(plc_host)
    settings = cell_settings(
        [("still", robot_host, target.tcp_port)],
        plc_host,
        state_dir,
        opcua_url=f"opc.tcp://{plc_host}:{port}",
        opcua_writes=True,
    )
    certificate = client_certificate(state_dir / "client")
    trust(certificate[0], settings.opcua.opcua_trusted_dir(state_dir))
    open_port = listening_port("0.0.0.0")
    open_settings = settings.replace(opcua_url=f"opc.tcp://0.0.0.0:{open_port}")
    try:
        async with running_service(settings) as running:
            service = running.service
            feed = ServiceFeed(
                service.robots, service.users, open_settings.web, asyncio.get_running_loop()
            )
            second = OpcUaServer(open_settings.opcua, state_dir, feed)  # the same PKI directory
            await second.start()
            try:
                own = state_dir / "opcua" / "pki" / "own" / "cert.der"
                cell = Cell(
                    running,
                    (plc_host, port),
                    (plc_host, open_port),
                    x509.load_der_x509_certificate(own.read_bytes()),
                    Identity.load(certificate),
                    state_dir,
                )
                async with RawChannel.connect(*cell.loopback) as channel:
                    await channel.open()
                    await channel.create_session()
                    await channel.activate(ua.AnonymousIdentityToken(PolicyId="anonymous"))
                    namespaces = (await channel.read(NAMESPACES)).Value
                    assert namespaces is not None
                    cell.namespace = list(namespaces.Value).index(ROBOT_URI)
                yield cell
            finally:
                await second.stop()
    finally:
        await target.stop()


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def cell(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Cell]:
    async with _cell(tmp_path_factory.mktemp("opcua-security")) as running:
        yield running


# ------------------------------------------------------------ 1. None where it is not offered


async def test_no_session_over_none_where_none_is_not_offered(cell: Cell) -> None:
    """The 0.0.0.0 server offers Basic256Sha256 only. A None channel opens for discovery
    (GetEndpoints, which lists no None endpoint), but CreateSession over it is refused with
    Bad_SecurityPolicyRejected; so is a session asked without OpenSecureChannel at all, and
    the reactivation over None of a session created over SignAndEncrypt."""
    async with RawChannel.connect(*cell.open_bind) as channel:
        await channel.open()
        endpoints = await channel.endpoints()
        assert endpoints and {e.SecurityPolicyUri for e in endpoints} == {B256.URI}
        with pytest.raises(RefusedError) as refused:
            await channel.create_session()
        assert refused.value.name == "BadSecurityPolicyRejected"

    async with RawChannel.connect(*cell.open_bind) as channel:  # no OpenSecureChannel
        with pytest.raises(RefusedError) as refused:
            await channel.create_session()
        assert refused.value.name == "BadSecurityPolicyRejected"

    secure = cell.secure(cell.trusted, ENCRYPT)
    async with RawChannel.connect(*cell.open_bind, secure) as channel:
        await channel.open()
        await channel.create_session()
        await channel.activate(clear_password("username_signandencrypt", OPERATOR))
        assert (await channel.read(NAMESPACES)).Value is not None
        token = channel.authentication_token
        async with RawChannel.connect(*cell.open_bind) as hijack:
            await hijack.open()
            hijack.authentication_token = token
            with pytest.raises(RefusedError) as refused:
                await hijack.activate(clear_password("username_signandencrypt", OPERATOR))
            assert refused.value.name == "BadSecurityPolicyRejected"


async def test_the_operator_takes_control_over_signandencrypt_only(cell: Cell) -> None:
    """What the refused None session would have done: the operator's TakeControl, here over
    SignAndEncrypt (the peer can do it when the channel is one of the endpoints)."""
    secure = cell.secure(cell.trusted, ENCRYPT)
    async with RawChannel.connect(*cell.open_bind, secure) as channel:
        await channel.open()
        await channel.create_session()
        await channel.activate(clear_password("username_signandencrypt", OPERATOR))
        taken = await channel.call(cell.robot(), cell.robot("TakeControl"))
        assert taken.StatusCode.name == "Good", taken
        released = await channel.call(cell.robot(), cell.robot("ReleaseControl"))
        assert released.StatusCode.name == "Good", released


# ------------------------------------------------------------ 2. a password in clear


async def test_user_name_token_policies_have_ids_of_their_own(cell: Cell) -> None:
    async with RawChannel.connect(*cell.loopback) as channel:
        await channel.open()
        endpoints = await channel.endpoints()
    policies = {
        (e.SecurityPolicyUri, e.SecurityMode, t.PolicyId, t.SecurityPolicyUri)
        for e in endpoints
        for t in e.UserIdentityTokens
        if t.TokenType == ua.UserTokenType.UserName
    }
    assert policies == {
        (NONE_URI, NO_MODE, "username_basic256sha256", B256.URI),
        (B256.URI, SIGN, "username_basic256sha256", B256.URI),
        (B256.URI, ENCRYPT, "username_signandencrypt", NONE_URI),
    }


async def test_a_password_in_clear_is_refused_over_none(cell: Cell) -> None:
    """On loopback None is offered, its user name policy says Basic256Sha256: a password in
    clear (under that policy's id, the old shared id ``username``, or the SignAndEncrypt
    policy's id) is Bad_IdentityTokenInvalid, and so is one encrypted with another nonce; the
    password encrypted as the policy says logs in."""
    async with RawChannel.connect(*cell.loopback) as channel:
        await channel.open()
        await channel.create_session()
        for policy_id in ("username_basic256sha256", "username", "username_signandencrypt"):
            with pytest.raises(RefusedError) as refused:
                await channel.activate(clear_password(policy_id, OPERATOR))
            assert refused.value.name == "BadIdentityTokenInvalid", policy_id
        stale = encrypted_password(
            "username_basic256sha256", OPERATOR, channel.server_certificate, b"\x00" * 32
        )
        with pytest.raises(RefusedError) as refused:
            await channel.activate(stale)
        assert refused.value.name == "BadIdentityTokenInvalid"
        await channel.activate(
            encrypted_password(
                "username_basic256sha256",
                OPERATOR,
                channel.server_certificate,
                channel.server_nonce,
            )
        )
        assert (await channel.read(NAMESPACES)).Value is not None


async def test_asyncua_follows_the_token_policy_over_none(cell: Cell) -> None:
    """asyncua's own client, which reads the endpoint's token policy, logs in over None."""
    host, port = cell.loopback
    # asyncua's watchdog reads the server's state every second and tears the session down when
    # one answer is late: on a busy machine that was the test's failure, not the server's.
    client = Client(f"opc.tcp://{host}:{port}", timeout=ANSWER_S, watchdog_intervall=ANSWER_S)
    client.set_user(OPERATOR[0])
    client.set_password(OPERATOR[1])
    async with client:
        namespaces = await client.get_node(NAMESPACES).read_value()
    assert ROBOT_URI in namespaces


# ------------------------------------------------------------ 3. the certificate at the channel


async def test_an_untrusted_certificate_is_refused_when_the_channel_opens(
    cell: Cell, tmp_path: Path
) -> None:
    """OpenSecureChannel with a certificate nobody trusted: an Error message
    Bad_CertificateUntrusted and the socket closed, the certificate kept in rejected/; moved
    into trusted/, the same certificate opens a channel (the list is read at each channel)."""
    stranger = Identity.load(client_certificate(tmp_path / "stranger"))
    for mode in (ENCRYPT, SIGN):
        async with RawChannel.connect(*cell.open_bind, cell.secure(stranger, mode)) as channel:
            with pytest.raises(RefusedError) as refused:
                await channel.open()
            assert refused.value.name == "BadCertificateUntrusted", mode
            assert await channel.closed_by_server()
    thumbprint = stranger.certificate.fingerprint(hashes.SHA1()).hex()
    rejected = cell.state_dir / "opcua" / "pki" / "rejected" / f"{thumbprint}.der"
    assert rejected.is_file(), "the refused certificate is kept for an administrator"
    trusted = cell.running.settings.opcua.opcua_trusted_dir(cell.state_dir) / rejected.name
    rejected.rename(trusted)
    try:
        async with RawChannel.connect(*cell.open_bind, cell.secure(stranger, ENCRYPT)) as channel:
            await channel.open()
            assert await channel.endpoints()
    finally:
        trusted.unlink()


async def test_a_policy_not_offered_is_refused_when_the_channel_opens(cell: Cell) -> None:
    """A policy no endpoint offers (Aes128_Sha256_RsaOaep), and Basic256Sha256 asked with mode
    None: an Error message Bad_SecurityPolicyRejected (asyncua left both unanswered)."""
    aes = SecurityPolicyAes128Sha256RsaOaep(
        cell.server_certificate, cell.trusted.certificate, cell.trusted.key, ENCRYPT
    )
    async with RawChannel.connect(*cell.open_bind, aes) as channel:
        with pytest.raises(RefusedError) as refused:
            await channel.open()
        assert refused.value.name == "BadSecurityPolicyRejected"
    async with RawChannel.connect(*cell.open_bind, cell.secure(cell.trusted, ENCRYPT)) as channel:
        with pytest.raises(RefusedError) as refused:
            await channel.open(mode=NO_MODE)
        assert refused.value.name == "BadSecurityPolicyRejected"
