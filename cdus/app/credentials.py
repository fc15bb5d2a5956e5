"""What credentials does one secured run have? A password per role, and with TLS a private CA and a
certificate per role, written to the run directory for the router and every process.

``cdus launch --secure`` (user/password) or ``--tls`` (TLS with client
certificates, plus the passwords) calls ``make_credentials``: it writes, in
``<run>/secure/`` (mode 0700, every file 0600),

    passwords           the router's user:password dictionary
    router.json5        the router's settings (authentication, TLS, the access-control list
                        of cdus.wire.access); the launcher applies the same settings to its
                        own router, and a world started by hand as the router reads this file
    <role>.json5        a client config per role (world, ground, vehicle-<id>; ros2 and
                        ros2-client with [ros2] enabled, robot-<id> per plant = "ros2"
                        vehicle, docs/ros2.md): user,
                        password, certificate, the router's endpoints, multicast off
    ca.pem, <role>.pem/.key, router.pem/.key    with TLS

The CA's private key is never written: nobody can sign another certificate for the run.
See docs/multihost.md, "A secured fleet".
"""

from __future__ import annotations

import datetime
import ipaddress
import json
import os
import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

from cdus.wire import access
from cdus.wire.transport import Transport, client_of, endpoint_host

MODES = ("password", "tls")
WILDCARDS = ("0.0.0.0", "::", "[::]")
CERT_DAYS = 30


class CredentialsError(ValueError):
    """The secured mode cannot be set up as asked; the message says what to change."""


@dataclass(frozen=True)
class Credentials:
    mode: str
    directory: Path
    listen: tuple[str, ...]  # the router's endpoints (tls/... with TLS)
    router_settings: dict[str, Any]  # zenoh config key ("a/b/c") -> value, for the router

    def file(self, role: str) -> Path:
        """The client config file (``--zenoh-config``) of ``role``."""
        return self.directory / f"{role}.json5"

    def router_extra(self) -> tuple[tuple[str, str], ...]:
        """The router settings as (json5 key, json5 value) pairs for ``Transport.extra``."""
        return tuple((k, json.dumps(v)) for k, v in self.router_settings.items())


def secure_endpoints(listen: tuple[str, ...], mode: str) -> tuple[str, ...]:
    """The router's endpoints in ``mode``: with TLS, ``tcp/`` becomes ``tls/``."""
    if mode not in MODES:
        raise CredentialsError(f"--secure: unknown mode {mode!r}; choose one of {', '.join(MODES)}")
    if mode == "password":
        return listen
    out = []
    for ep in listen:
        proto, sep, rest = ep.partition("/")
        if proto not in ("tcp", "tls") or not sep:
            raise CredentialsError(f"--secure tls: the router endpoint {ep!r} cannot carry TLS; "
                                   f"give tcp/HOST:PORT or tls/HOST:PORT")
        out.append(f"tls/{rest}")
    return tuple(out)


def _write_private(path: Path, data: str | bytes) -> None:
    """Create or replace ``path`` with mode 0600 from the start (never readable by others)."""
    tmp = path.with_name(path.name + ".tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)
    os.chmod(tmp, 0o600)
    os.replace(tmp, path)


def nest(settings: dict[str, Any]) -> dict:
    """{"a/b": 1, "a/c": 2} -> {"a": {"b": 1, "c": 2}}."""
    out: dict = {}
    for key, value in settings.items():
        node = out
        parts = key.split("/")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return out


def make_credentials(directory: str | os.PathLike, fleet: str, listeners: Mapping[str, Sequence[str]],
                     listen: tuple[str, ...], mode: str = "password", ros2: access.Ros2Grant | None = None,
                     robots: Sequence[access.RobotGrant] = ()) -> Credentials:
    """Generate the run's credentials in ``directory`` (see the module's docstring) for the
    vehicles of ``listeners`` (vehicle id -> the ids its ω goes to, ``listeners_of``), with
    ``ros2`` for the ROS 2 bridge and ROS 2 machines, and with ``robots`` for each robot
    (docs/ros2.md)."""
    listen = secure_endpoints(tuple(listen), mode)
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    os.chmod(d, 0o700)
    roles = access.roles(list(listeners), ros2=ros2 is not None, robots=[r.vehicle for r in robots])
    passwords = {r: secrets.token_urlsafe(24) for r in roles}
    _write_private(d / "passwords", "".join(f"{r}:{pw}\n" for r, pw in passwords.items()))
    router = {
        "transport/auth/usrpwd/dictionary_file": str((d / "passwords").resolve()),
        "access_control": access.fleet_acl(fleet, listeners, match_certificates=mode == "tls", ros2=ros2,
                                           robots=robots),
    }
    client_tls: dict[str, Any] = {}
    if mode == "tls":
        hosts = [endpoint_host(ep) for ep in listen]
        _write_certificates(d, roles, [h for h in hosts if h not in WILDCARDS])
        router["transport/link/tls"] = {"root_ca_certificate": str((d / "ca.pem").resolve()),
                                        "listen_private_key": str((d / "router.key").resolve()),
                                        "listen_certificate": str((d / "router.pem").resolve()),
                                        "enable_mtls": True}
        client_tls = {"root_ca_certificate": str((d / "ca.pem").resolve()), "enable_mtls": True}
        if any(h in WILDCARDS for h in hosts):
            # the certificate cannot name every address a wildcard listens on; the run's own
            # CA signed one server certificate, which still authenticates the router
            client_tls["verify_name_on_connect"] = False
    _write_private(d / "router.json5", json.dumps(nest({
        "mode": "router", "listen/endpoints": list(listen), "scouting/multicast/enabled": False,
        "scouting/gossip/enabled": False, **router}), indent=2) + "\n")
    connect = list(client_of(Transport(mode="router", listen=listen)).connect)
    for role in roles:
        settings: dict[str, Any] = {
            "mode": "client", "connect/endpoints": connect,
            "scouting/multicast/enabled": False, "scouting/gossip/enabled": False,
            "transport/auth/usrpwd/user": role, "transport/auth/usrpwd/password": passwords[role],
        }
        if client_tls:
            settings["transport/link/tls"] = {**client_tls,
                                              "connect_private_key": str((d / f"{role}.key").resolve()),
                                              "connect_certificate": str((d / f"{role}.pem").resolve())}
        _write_private(d / f"{role}.json5", json.dumps(nest(settings), indent=2) + "\n")
    return Credentials(mode, d, listen, router)


def _write_certificates(d: Path, roles: list[str], hosts: list[str]) -> None:
    """A CA (its key kept in memory only), the router's server certificate for ``hosts``
    (plus 127.0.0.1 and localhost), and one client certificate per role (CN = the role)."""
    # cryptography costs ~0.4 s to import: only a TLS run pays it
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    now = datetime.datetime.now(datetime.timezone.utc)
    start, end = now - datetime.timedelta(hours=1), now + datetime.timedelta(days=CERT_DAYS)

    def name(cn: str) -> x509.Name:
        return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, cn)])

    def builder(subject: str, issuer: x509.Name, public_key: Any) -> x509.CertificateBuilder:
        return (x509.CertificateBuilder().subject_name(name(subject)).issuer_name(issuer)
                .public_key(public_key).serial_number(x509.random_serial_number())
                .not_valid_before(start).not_valid_after(end))

    def pem(cert: x509.Certificate) -> bytes:
        return cert.public_bytes(serialization.Encoding.PEM)

    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = name("cdus run CA")
    ca = (builder("cdus run CA", ca_name, ca_key.public_key())
          .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
          .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=True, crl_sign=True,
                                       content_commitment=False, key_encipherment=False, data_encipherment=False,
                                       key_agreement=False, encipher_only=False, decipher_only=False), critical=True)
          .add_extension(x509.SubjectKeyIdentifier.from_public_key(ca_key.public_key()), critical=False)
          .sign(ca_key, hashes.SHA256()))
    _write_private(d / "ca.pem", pem(ca))

    def leaf(cn: str, usage: Any, sans: list[x509.GeneralName]) -> None:
        key = ec.generate_private_key(ec.SECP256R1())
        b = (builder(cn, ca_name, key.public_key())
             .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
             .add_extension(x509.ExtendedKeyUsage([usage]), critical=False)
             .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False))
        if sans:
            b = b.add_extension(x509.SubjectAlternativeName(sans), critical=False)
        _write_private(d / f"{cn}.key", key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                                          serialization.NoEncryption()))
        _write_private(d / f"{cn}.pem", pem(b.sign(ca_key, hashes.SHA256())))

    sans: list[x509.GeneralName] = []
    for h in dict.fromkeys([*hosts, "127.0.0.1", "localhost"]):
        try:
            sans.append(x509.IPAddress(ipaddress.ip_address(h)))
        except ValueError:
            sans.append(x509.DNSName(h))
    leaf("router", ExtendedKeyUsageOID.SERVER_AUTH, sans)
    for role in roles:
        leaf(role, ExtendedKeyUsageOID.CLIENT_AUTH, [])
