"""A real mosquitto broker on a free loopback port, and mosquitto_sub as the independent client.

Variants: anonymous, username/password (``mosquitto_passwd -b``), and TLS with a CA and a
server certificate generated here (the ``cryptography`` package). Where mosquitto is missing,
the tests that need it skip and say how to install it.
"""

from __future__ import annotations

import datetime
import getpass
import ipaddress
import os
import shutil
import socket
import subprocess
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import pytest

INSTALL_HINT = "install mosquitto: apt-get install mosquitto mosquitto-clients"


def _program(name: str) -> str | None:
    # mosquitto lives in /usr/sbin, which is not on every user's PATH
    return shutil.which(name) or shutil.which(name, path="/usr/sbin:/usr/local/sbin")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _port_open(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.2)
        return s.connect_ex(("127.0.0.1", port)) == 0


@dataclass
class Tls:
    """Files of a throw-away CA, a server certificate for 127.0.0.1, and a client certificate."""

    ca: Path
    server_cert: Path
    server_key: Path
    client_cert: Path
    client_key: Path


class Mosquitto:
    """One mosquitto process with a generated config; can be stopped and started again."""

    def __init__(
        self,
        folder: Path,
        *,
        users: dict[str, str] | None = None,
        tls: Tls | None = None,
        require_client_cert: bool = False,
        extra: Sequence[str] = (),
    ) -> None:
        """``extra``: more lines for mosquitto.conf (e.g. ``max_inflight_messages 1000``)."""
        self.folder = folder
        self.port = free_port()
        self.users = users
        self.tls = tls
        self.process: subprocess.Popen[bytes] | None = None
        lines = [
            f"listener {self.port} 127.0.0.1",
            f"allow_anonymous {'false' if users else 'true'}",
            # sessions and queued messages survive a restart, as on a real installation
            "persistence true",
            f"persistence_location {folder}/",
            f"log_dest file {folder}/mosquitto.log",
            # as root mosquitto would switch to the `mosquitto` user, who cannot read tmp_path
            f"user {getpass.getuser()}",
            "log_type all",
            *extra,
        ]
        if users:
            pwfile = folder / "passwords"
            for i, (user, password) in enumerate(users.items()):
                args = ["-b", str(pwfile), user, password]
                subprocess.run(
                    [
                        _program("mosquitto_passwd") or "mosquitto_passwd",
                        *(["-c"] if i == 0 else []),
                        *args,
                    ],
                    check=True,
                    capture_output=True,
                )
            lines.append(f"password_file {pwfile}")
        if tls:
            lines += [
                f"cafile {tls.ca}",
                f"certfile {tls.server_cert}",
                f"keyfile {tls.server_key}",
                f"require_certificate {'true' if require_client_cert else 'false'}",
            ]
        self.config = folder / "mosquitto.conf"
        self.config.write_text("\n".join(lines) + "\n")

    @property
    def url(self) -> str:
        return f"{'mqtts' if self.tls else 'mqtt'}://127.0.0.1:{self.port}"

    def start(self) -> None:
        self.process = subprocess.Popen(
            [_program("mosquitto") or "mosquitto", "-c", str(self.config)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        deadline = time.monotonic() + 10
        while not _port_open(self.port):
            if self.process.poll() is not None:
                err = self.process.stderr.read().decode() if self.process.stderr else ""
                raise RuntimeError(f"mosquitto did not start: {err}")
            if time.monotonic() > deadline:
                raise RuntimeError("mosquitto did not open its port within 10 s")
            time.sleep(0.02)

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()  # graceful: mosquitto saves its persistence file
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process = None

    def log_text(self) -> str:
        path = self.folder / "mosquitto.log"
        return path.read_text(errors="replace") if path.exists() else ""


class Subscriber:
    """``mosquitto_sub`` printing ``topic payload`` lines, collected by a thread."""

    def __init__(
        self,
        broker: Mosquitto,
        topic: str,
        *,
        qos: int = 2,
        client_id: str | None = None,
        extra: list[str] | None = None,
    ) -> None:
        args = [
            _program("mosquitto_sub") or "mosquitto_sub",
            "-h", "127.0.0.1",
            "-p", str(broker.port),
            "-t", topic,
            "-q", str(qos),
            "-F", "%r %t %p",
        ]  # fmt: skip
        if client_id:  # a persistent session: messages wait for it while it reconnects
            args += ["-i", client_id, "-c"]
        args += extra or []
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self.process = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for raw in self.process.stdout:
            with self._cond:
                self.lines.append(raw.decode("utf-8", "replace").rstrip("\n"))
                self._cond.notify_all()

    def messages(self) -> list[tuple[bool, str, str]]:
        """(retained, topic, payload) for every line so far."""
        out = []
        with self._cond:
            for line in self.lines:
                retained, topic, payload = (line.split(" ", 2) + ["", ""])[:3]
                out.append((retained == "1", topic, payload))
        return out

    def wait_for(self, count: int, timeout: float = 10.0) -> list[tuple[bool, str, str]]:
        deadline = time.monotonic() + timeout
        with self._cond:
            while len(self.lines) < count and time.monotonic() < deadline:
                self._cond.wait(0.05)
        return self.messages()

    def wait_until(
        self, done: Callable[[list[tuple[bool, str, str]]], bool], timeout: float = 15.0
    ) -> list[tuple[bool, str, str]]:
        """The messages once ``done`` holds for them; fails the test with what arrived if not.

        Prefer this to :meth:`wait_for` where the count varies (state messages ride along):
        a count reached early returns before the message the test is about has arrived.
        """
        deadline = time.monotonic() + timeout
        with self._cond:
            while time.monotonic() < deadline:
                if done(self.messages()):
                    return self.messages()
                self._cond.wait(0.05)
        raise AssertionError(f"timed out; the broker carried: {self.messages()}")

    def stop(self) -> None:
        self.process.terminate()
        self.process.wait(5)


@pytest.fixture(scope="session")
def mosquitto_available() -> None:
    if _program("mosquitto") is None or _program("mosquitto_sub") is None:
        if os.environ.get("HAPTICDESK_REQUIRE_BROKER"):  # CI: a missing broker is a failure
            pytest.fail(
                f"HAPTICDESK_REQUIRE_BROKER is set but mosquitto is missing: {INSTALL_HINT}"
            )
        pytest.skip(INSTALL_HINT)


@pytest.fixture
def broker(mosquitto_available: None, tmp_path: Path) -> Iterator[Mosquitto]:
    """An anonymous mosquitto on a free port."""
    b = Mosquitto(tmp_path)
    b.start()
    yield b
    b.stop()


@pytest.fixture
def subscribe(broker: Mosquitto) -> Iterator[object]:
    """``subscribe(topic, **kw)``: a mosquitto_sub on ``broker``, listening when it returns."""
    subs: list[Subscriber] = []

    def start(topic: str, **kw: object) -> Subscriber:
        sub = Subscriber(broker, topic, **kw)  # type: ignore[arg-type]
        subs.append(sub)
        wait_subscribed(broker, topic)
        return sub

    yield start
    for sub in subs:
        sub.stop()


def wait_subscribed(broker: Mosquitto, topic: str, timeout: float = 5.0) -> None:
    """Block until the broker's log shows a subscription to ``topic``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if f" {topic} (QoS" in broker.log_text() or f"\t{topic} (QoS" in broker.log_text():
            return
        time.sleep(0.02)
    raise RuntimeError(f"no subscription to {topic} in the broker's log")


def make_tls(folder: Path) -> Tls:
    """A CA, a server certificate for 127.0.0.1/localhost and a client certificate."""
    crypto = pytest.importorskip("cryptography", reason="TLS tests need the cryptography package")
    del crypto
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    now = datetime.datetime.now(datetime.UTC)

    def name(cn: str) -> x509.Name:
        return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, cn)])

    def write_key(key: ec.EllipticCurvePrivateKey, path: Path) -> Path:
        path.write_bytes(
            key.private_bytes(
                serialization.Encoding.PEM,
                serialization.PrivateFormat.PKCS8,
                serialization.NoEncryption(),
            )
        )
        os.chmod(path, 0o600)
        return path

    def write_cert(cert: x509.Certificate, path: Path) -> Path:
        path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
        return path

    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_cert = (
        x509.CertificateBuilder()
        .subject_name(name("hapticdesk test CA"))
        .issuer_name(name("hapticdesk test CA"))
        .public_key(ca_key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=1))
        .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )  # fmt: skip
        .add_extension(
            x509.SubjectKeyIdentifier.from_public_key(ca_key.public_key()), critical=False
        )
        .sign(ca_key, hashes.SHA256())
    )

    def leaf(
        cn: str, usage: x509.ObjectIdentifier, san: list[x509.GeneralName] | None
    ) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
        key = ec.generate_private_key(ec.SECP256R1())
        builder = (
            x509.CertificateBuilder()
            .subject_name(name(cn))
            .issuer_name(ca_cert.subject)
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.ExtendedKeyUsage([usage]), critical=False)
            .add_extension(
                x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()),
                critical=False,
            )
        )
        if san:
            builder = builder.add_extension(x509.SubjectAlternativeName(san), critical=False)
        return builder.sign(ca_key, hashes.SHA256()), key

    server, server_key = leaf(
        "localhost",
        ExtendedKeyUsageOID.SERVER_AUTH,
        [x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))],
    )
    client, client_key = leaf("desk", ExtendedKeyUsageOID.CLIENT_AUTH, None)
    return Tls(
        ca=write_cert(ca_cert, folder / "ca.crt"),
        server_cert=write_cert(server, folder / "server.crt"),
        server_key=write_key(server_key, folder / "server.key"),
        client_cert=write_cert(client, folder / "client.crt"),
        client_key=write_key(client_key, folder / "client.key"),
    )
