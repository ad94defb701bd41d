"""The OPC UA PKI directory: ``own/`` (server cert + key), ``trusted/``, ``rejected/``.

* ``own/cert.der`` and ``own/key.pem`` are created on first start if absent (RSA 2048,
  SHA-256, self-signed, the application URI and host names in subjectAltName).
* A client certificate is trusted when ``trusted/`` holds the very same certificate,
  or a CA certificate that directly issued it. The directory is re-read on each check,
  so moving a file from ``rejected/`` to ``trusted/`` takes effect without a restart.
* An untrusted certificate is written to ``rejected/<CN>-<sha1>.der`` for review.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import ipaddress
import os
import re
import socket
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from cellrunner.errors import CellrunnerError

CERT_SUFFIXES = (".der", ".pem", ".crt", ".cer")
SERVER_CERT_DAYS = 5 * 365


@dataclass(frozen=True)
class Pki:
    """Paths of one PKI directory; ``ensure_dirs`` creates them."""

    root: Path

    @property
    def own(self) -> Path:
        return self.root / "own"

    @property
    def trusted(self) -> Path:
        return self.root / "trusted"

    @property
    def rejected(self) -> Path:
        return self.root / "rejected"

    @property
    def cert_file(self) -> Path:
        return self.own / "cert.der"

    @property
    def key_file(self) -> Path:
        return self.own / "key.pem"

    def ensure_dirs(self) -> None:
        try:
            for path in (self.own, self.trusted, self.rejected):
                path.mkdir(parents=True, exist_ok=True)
            os.chmod(self.own, 0o700)
        except OSError as exc:
            raise CellrunnerError(f"cannot create the OPC UA PKI under {self.root}: {exc}") from exc

    # -- own certificate ----------------------------------------------------------------
    def ensure_server_certificate(
        self, application_uri: str, hosts: list[str]
    ) -> tuple[Path, Path]:
        """(cert, key) paths; both are created when the key or the certificate is absent."""
        self.ensure_dirs()
        if self.cert_file.is_file() and self.key_file.is_file():
            return self.cert_file, self.key_file
        from asyncua.crypto import cert_gen

        key = cert_gen.generate_private_key()  # RSA 2048, e = 65537
        cert = make_certificate(key, "cellrunner", application_uri, hosts, server=True)
        _write_private(self.key_file, cert_gen.dump_private_key_as_pem(key))  # PKCS8 PEM
        self.cert_file.write_bytes(cert.public_bytes(serialization.Encoding.DER))
        return self.cert_file, self.key_file

    # -- trust list ----------------------------------------------------------------------
    def trusted_certificates(self) -> list[x509.Certificate]:
        certs = []
        if self.trusted.is_dir():
            for path in sorted(self.trusted.iterdir()):
                if path.suffix.lower() in CERT_SUFFIXES and path.is_file():
                    cert = load_certificate_file(path)
                    if cert is not None:
                        certs.append(cert)
        return certs

    def is_trusted(self, cert: x509.Certificate, now: dt.datetime | None = None) -> bool:
        """In ``trusted/`` (itself, or its issuing CA), and within its validity dates."""
        now = now or dt.datetime.now(dt.UTC)
        if not cert.not_valid_before_utc <= now <= cert.not_valid_after_utc:
            return False
        der = cert.public_bytes(serialization.Encoding.DER)
        for anchor in self.trusted_certificates():
            if anchor.public_bytes(serialization.Encoding.DER) == der:
                return True
            if _is_ca(anchor) and anchor.subject == cert.issuer:
                try:
                    cert.verify_directly_issued_by(anchor)
                    return True
                except Exception:  # any failure means untrusted
                    continue
        return False

    def reject(self, cert: x509.Certificate) -> Path:
        """File ``cert`` in ``rejected/`` (idempotent); returns the path."""
        self.ensure_dirs()
        der = cert.public_bytes(serialization.Encoding.DER)
        thumb = hashlib.sha1(der).hexdigest()  # a file name, OPC UA thumbprint
        cn = common_name(cert) or "unnamed"
        path = self.rejected / f"{re.sub(r'[^A-Za-z0-9_.-]', '_', cn)[:40]}-{thumb}.der"
        if not path.exists():
            path.write_bytes(der)
        return path


def common_name(cert: x509.Certificate) -> str:
    names = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    return str(names[0].value) if names else ""


def load_certificate_file(path: Path) -> x509.Certificate | None:
    """A DER or PEM certificate, or None when the file is not one."""
    data = path.read_bytes()
    try:
        if b"-----BEGIN CERTIFICATE-----" in data:
            return x509.load_pem_x509_certificate(data)
        return x509.load_der_x509_certificate(data)
    except ValueError:
        return None


def make_certificate(
    key: rsa.RSAPrivateKey,
    common: str,
    application_uri: str,
    hosts: list[str],
    *,
    server: bool,
    days: int = SERVER_CERT_DAYS,
) -> x509.Certificate:
    """A self-signed OPC UA application instance certificate (OPC 10000-6 6.2.2).

    Built here rather than by asyncua's ``cert_gen.generate_self_signed_app_certificate``:
    that one marks the instance certificate as a CA allowed to sign certificates
    (``cA=TRUE``, ``keyCertSign``), which :meth:`Pki.is_trusted` would then accept as the
    issuer of other certificates, and starts its validity at this very second, with no
    margin for a PLC whose clock runs a little behind."""
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common)])
    alt: list[x509.GeneralName] = [x509.UniformResourceIdentifier(application_uri)]
    for host in dict.fromkeys(hosts):
        try:
            alt.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            alt.append(x509.DNSName(host))
    now = dt.datetime.now(dt.UTC)
    usage = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
    builder = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.SubjectAlternativeName(alt), critical=False)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=True,
                key_encipherment=True,
                data_encipherment=True,
                key_agreement=False,
                key_cert_sign=False,
                crl_sign=False,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(
            x509.ExtendedKeyUsage(
                [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
                if server
                else [usage]
            ),
            critical=False,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
    )
    return builder.sign(key, hashes.SHA256())


def default_hosts(endpoint_host: str | None) -> list[str]:
    """Host names for the server certificate: the endpoint's host and this machine's."""
    hosts = [h for h in (endpoint_host, socket.gethostname(), "localhost") if h]
    return list(dict.fromkeys(hosts))


def _is_ca(cert: x509.Certificate) -> bool:
    try:
        return bool(cert.extensions.get_extension_for_class(x509.BasicConstraints).value.ca)
    except x509.ExtensionNotFound:
        return False


def _write_private(path: Path, data: bytes) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as handle:
        handle.write(data)
