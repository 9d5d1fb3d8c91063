"""drivemap gateway -> OPC UA with certificate security, exercised by asyncua's own client.

Certificates (server, two clients) are generated into tmp_path at test time with asyncua's
``cert_gen`` (the way docs/gateway.md tells users to make theirs). The drive is a generated vfd1000
simulator over Modbus TCP; a write that is allowed must reach it. Only 127.0.0.1.
"""

from __future__ import annotations

import asyncio
import socket
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua  # noqa: E402
from asyncua.crypto import cert_gen  # noqa: E402
from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256  # noqa: E402
from cryptography import x509  # noqa: E402
from cryptography.hazmat.primitives.serialization import Encoding  # noqa: E402
from cryptography.x509.oid import ExtendedKeyUsageOID  # noqa: E402

from drivemap.cli import main
from tests.helpers_client import tcp_server
from tests.helpers_gateway import free_port, running, until, write_config

NS = "urn:drivemap:test"
SERVER_URI = "urn:drivemap:gateway:plant"  # what the gateway sets as its application URI
CLIENT_URI = "urn:drivemap:test:client"
SIGN = ua.MessageSecurityMode.Sign
ENCRYPT = ua.MessageSecurityMode.SignAndEncrypt


def make_certificate(folder: Path, name: str, uri: str, use: Any) -> tuple[Path, Path]:
    """A self-signed OPC UA application certificate (DER) and its private key (PEM)."""
    key = cert_gen.generate_private_key()
    cert = cert_gen.generate_self_signed_app_certificate(
        key, name, {"organizationName": "drivemap tests"},
        [x509.UniformResourceIdentifier(uri), x509.DNSName(socket.gethostname()), x509.DNSName("localhost")],
        extended=[use])
    cert_path, key_path = folder / f"{name}.der", folder / f"{name}-key.pem"
    cert_path.write_bytes(cert.public_bytes(Encoding.DER))
    key_path.write_bytes(cert_gen.dump_private_key_as_pem(key))
    return cert_path, key_path


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Path]]:
    folder = tmp_path_factory.mktemp("pki")
    return {
        "server": make_certificate(folder, "server", SERVER_URI, ExtendedKeyUsageOID.SERVER_AUTH),
        "maintenance": make_certificate(folder, "maintenance", CLIENT_URI, ExtendedKeyUsageOID.CLIENT_AUTH),
        "stranger": make_certificate(folder, "stranger", CLIENT_URI, ExtendedKeyUsageOID.CLIENT_AUTH),
    }


def config(sim_port: int, opc_port: int, pki: dict[str, tuple[Path, Path]], security: str,
           extra: str = "") -> str:
    server_cert, server_key = pki["server"]
    return f"""\
gateway: 1
name: plant
opcua:
  endpoint: opc.tcp://127.0.0.1:{opc_port}/drivemap/
  namespace: {NS}
  security: {security}
  certificate: {server_cert}
  private_key: {server_key}
  users:
    - {{name: viewer, password: look, write: false}}
  trusted_certificates:
    - {{name: maintenance, certificate: {pki["maintenance"][0]}}}
{extra}buses:
  - name: line1
    tcp: 127.0.0.1:{sim_port}
    timeout: 0.3
    devices:
      - {{name: pump1, model: vfd1000, unit: 1, interval: 0.2, writable: [communication_setting]}}
"""


async def secure_client(url: str, cert: tuple[Path, Path], mode: Any) -> Client:
    client = Client(url)
    client.application_uri = CLIENT_URI
    await client.set_security(SecurityPolicyBasic256Sha256, str(cert[0]), str(cert[1]), mode=mode)
    return client


async def node(client: Client, name: str) -> Any:
    idx = await client.get_namespace_index(NS)
    return await client.nodes.objects.get_child([f"{idx}:plant", f"{idx}:pump1", f"{idx}:{name}"])


async def write_status(client: Client, value: float) -> str:
    setting = await node(client, "communication_setting")
    try:
        await setting.write_value(ua.DataValue(ua.Variant(value, ua.VariantType.Double)))
    except ua.UaStatusCodeError as exc:
        return type(exc).__name__
    return "Good"


def _url(port: int) -> str:
    return f"opc.tcp://127.0.0.1:{port}/drivemap/"


@pytest.mark.parametrize("mode", [SIGN, ENCRYPT], ids=["Sign", "SignAndEncrypt"])
async def test_secure_channel_reads_values(tmp_path: Path, pki: dict[str, tuple[Path, Path]], mode: Any) -> None:
    """A client with its own certificate reads the drive's values over Basic256Sha256 Sign / SignAndEncrypt;
    the server offers exactly the configured policies."""
    opc_port = free_port()
    with tcp_server("vfd1000", (1,)) as (sim, _, port):
        sim.set("communication_setting", -12.5)
        cfg = write_config(tmp_path, config(port, opc_port, pki, f"[Basic256Sha256_{mode.name}]"))
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online, what="online")
            client = await secure_client(_url(opc_port), pki["stranger"], mode)
            async with client:
                assert client.security_policy.Mode == mode
                endpoints = await client.get_endpoints()
                assert {(e.SecurityPolicyUri.rsplit("#", 1)[1], e.SecurityMode) for e in endpoints} == {
                    ("Basic256Sha256", mode)}
                setting = await node(client, "communication_setting")
                for _ in range(100):
                    if await setting.read_value() == pytest.approx(-12.5):
                        break
                    await asyncio.sleep(0.05)
                assert await setting.read_value() == pytest.approx(-12.5)


@pytest.mark.parametrize("mode", [SIGN, ENCRYPT], ids=["Sign", "SignAndEncrypt"])
async def test_signing_only_server_refuses_an_unsecured_client(tmp_path: Path, pki: dict[str, tuple[Path, Path]],
                                                               mode: Any) -> None:
    """With only signing policies configured, a client without security (policy None) gets no session,
    anonymous or with a password."""
    opc_port = free_port()
    with tcp_server("vfd1000", (1,)) as (_, _, port):
        cfg = write_config(tmp_path, config(port, opc_port, pki, f"[Basic256Sha256_{mode.name}]"))
        async with running(cfg):
            plain = Client(_url(opc_port))
            with pytest.raises((ua.UaError, OSError, TimeoutError)):
                async with plain:
                    await node(plain, "communication_setting")
            viewer = Client(_url(opc_port))
            viewer.set_user("viewer")
            viewer.set_password("look")
            with pytest.raises((ua.UaError, OSError, TimeoutError)):
                async with viewer:
                    await node(viewer, "communication_setting")


async def test_client_certificate_mapped_to_a_user_writes(tmp_path: Path, pki: dict[str, tuple[Path, Path]]) -> None:
    """A client certificate in trusted_certificates logs in as its user (X509 identity token) and may
    write: the value reaches the simulated drive. A certificate that is not trusted is refused as an
    identity; over a secure channel with an unknown certificate an anonymous session may read but not
    write; a password user without write rights is refused (BadUserAccessDenied)."""
    opc_port = free_port()
    with tcp_server("vfd1000", (1,)) as (sim, _, port):
        cfg = write_config(tmp_path, config(port, opc_port, pki, "[Basic256Sha256_SignAndEncrypt]"))
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online, what="online")
            url = _url(opc_port)
            maintenance = await secure_client(url, pki["stranger"], ENCRYPT)
            await maintenance.load_client_certificate(str(pki["maintenance"][0]))
            await maintenance.load_private_key(pki["maintenance"][1])
            async with maintenance:
                assert await write_status(maintenance, 42.5) == "Good"
                assert sim.get("communication_setting") == pytest.approx(42.5)
                assert await write_status(maintenance, 150.0) == "BadOutOfRange"  # checked like any write

            stranger = await secure_client(url, pki["stranger"], ENCRYPT)
            await stranger.load_client_certificate(str(pki["stranger"][0]))
            await stranger.load_private_key(pki["stranger"][1])
            with pytest.raises(ua.UaStatusCodeError) as refused:
                async with stranger:
                    pass
            assert type(refused.value).__name__ in {"BadUserAccessDenied", "BadIdentityTokenRejected"}

            anonymous = await secure_client(url, pki["stranger"], ENCRYPT)
            async with anonymous:
                assert await (await node(anonymous, "communication_setting")).read_value() == pytest.approx(42.5)
                assert await write_status(anonymous, 10.0) == "BadUserAccessDenied"

            viewer = await secure_client(url, pki["stranger"], ENCRYPT)
            viewer.set_user("viewer")
            viewer.set_password("look")
            async with viewer:
                assert await write_status(viewer, 11.0) == "BadUserAccessDenied"
            assert sim.get("communication_setting") == pytest.approx(42.5)


async def test_channel_certificate_is_not_a_user(tmp_path: Path, pki: dict[str, tuple[Path, Path]]) -> None:
    """The secure channel's certificate authenticates the client application, not a user: over a channel
    signed with the trusted maintenance certificate, an anonymous session still may not write; with
    ``anonymous: false`` it gets no session, while the same certificate as an X509 identity does."""
    opc_port = free_port()
    with tcp_server("vfd1000", (1,)) as (sim, _, port):
        cfg = write_config(tmp_path, config(port, opc_port, pki, "[Basic256Sha256_Sign]"))
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online, what="online")
            client = await secure_client(_url(opc_port), pki["maintenance"], SIGN)
            async with client:
                assert await write_status(client, -33.0) == "BadUserAccessDenied"
        assert sim.get("communication_setting") != pytest.approx(-33.0)
        opc_port = free_port()
        cfg = write_config(tmp_path, config(port, opc_port, pki, "[Basic256Sha256_Sign]", "  anonymous: false\n"))
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online, what="online")
            client = await secure_client(_url(opc_port), pki["maintenance"], SIGN)
            with pytest.raises(ua.UaStatusCodeError):
                async with client:
                    pass
            client = await secure_client(_url(opc_port), pki["maintenance"], SIGN)
            await client.load_client_certificate(str(pki["maintenance"][0]))
            await client.load_private_key(pki["maintenance"][1])
            async with client:
                assert await write_status(client, -33.0) == "Good"
            assert sim.get("communication_setting") == pytest.approx(-33.0)


async def test_anonymous_writes_switched_on(tmp_path: Path, pki: dict[str, tuple[Path, Path]]) -> None:
    """``anonymous_writes: true`` lets an anonymous session write (off by default: see the tests above)."""
    opc_port = free_port()
    with tcp_server("vfd1000", (1,)) as (sim, _, port):
        cfg = write_config(tmp_path, config(port, opc_port, pki, "[none, Basic256Sha256_Sign]",
                                            "  anonymous_writes: true\n"))
        async with running(cfg) as gw:
            await until(lambda: gw.devices["pump1"].online, what="online")
            async with Client(_url(opc_port)) as anonymous:
                assert await write_status(anonymous, 7.5) == "Good"
            assert sim.get("communication_setting") == pytest.approx(7.5)


def _locate(text: str, needle: str) -> str:
    before = text[:text.index(needle)]
    return f"{before.count(chr(10)) + 1}:{len(before) - before.rfind(chr(10))}"


def _bad_files(folder: Path, pki: dict[str, tuple[Path, Path]]) -> dict[str, Path]:
    from cryptography.hazmat.primitives import serialization

    garbage = folder / "garbage.pem"
    garbage.write_text("-----BEGIN PRIVATE KEY-----\nnot base64 at all\n-----END PRIVATE KEY-----\n")
    der_garbage = folder / "garbage.der"
    der_garbage.write_bytes(b"\x30\x03\x02\x01")
    key = serialization.load_pem_private_key(pki["server"][1].read_bytes(), None)
    encrypted = folder / "encrypted.pem"
    encrypted.write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                            serialization.BestAvailableEncryption(b"secret")))
    pem_as_der = folder / "server-cert-in-pem.der"
    cert = x509.load_der_x509_certificate(pki["server"][0].read_bytes())
    pem_as_der.write_bytes(cert.public_bytes(Encoding.PEM))
    return {"garbage": garbage, "der_garbage": der_garbage, "encrypted": encrypted, "pem_as_der": pem_as_der,
            "missing": folder / "missing.der", "other_key": pki["maintenance"][1]}


CERT_ERRORS = [  # (which path in the config, replaced by which bad file, the message)
    ("server_key", "garbage", "is not a private key in PEM"),
    ("server_key", "encrypted", "is encrypted: the gateway needs an unencrypted private key"),
    ("server_key", "other_key", "is not the private key of"),
    ("server_key", "missing", "no such file"),
    ("server_cert", "der_garbage", "is not an X.509 certificate in DER"),
    ("server_cert", "pem_as_der", "is not an X.509 certificate in DER"),
    ("client_cert", "garbage", "is not an X.509 certificate in PEM"),
    ("client_cert", "missing", "no such file"),
]


@pytest.mark.parametrize(("where", "bad", "message"), CERT_ERRORS, ids=[f"{w}-{b}" for w, b, _ in CERT_ERRORS])
def test_certificate_file_errors_are_located(tmp_path: Path, pki: dict[str, tuple[Path, Path]],
                                             capsys: pytest.CaptureFixture[str], where: str, bad: str,
                                             message: str) -> None:
    """Unusable certificate and key files are configuration errors at the line of their path (exit 1,
    no traceback), found by ``drivemap gateway --check`` before anything starts."""
    files = _bad_files(tmp_path, pki)
    good = config(5020, 4840, pki, "[Basic256Sha256_Sign]")
    path = tmp_path / "gw.yaml"
    path.write_text(good)
    assert main(["gateway", "--check", str(path)]) == 0
    capsys.readouterr()
    original = {"server_key": pki["server"][1], "server_cert": pki["server"][0],
                "client_cert": pki["maintenance"][0]}[where]
    text = good.replace(str(original), str(files[bad]))
    path.write_text(text)
    assert main(["gateway", "--check", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"{path}:{_locate(text, str(files[bad]))}: error: " in err, err
    assert message in err, err
    assert "Traceback" not in err
