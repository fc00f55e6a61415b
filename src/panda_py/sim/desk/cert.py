"""The simulated Desk's TLS certificate: self-signed like a robot's, generated on first
start and cached (``~/.cache/panda_py/desk``, one for every simulator of this user), so
that clients which pin it on first use see the same certificate on every later start.
Clients pin it rather than check its names, as with a robot's."""

from __future__ import annotations

import datetime
import ipaddress
import os
from pathlib import Path


def default_cert_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return Path(base) / "panda_py" / "desk"


def ensure_certificate(directory: Path) -> Path:
    """``directory/desk.pem``: the certificate, then its key (one file, mode 0600, so that
    simulators starting at once on a fresh machine each rename a consistent pair into
    place), created if missing."""
    path = directory / "desk.pem"
    if path.exists():
        return path
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "robot.franka.de")])
    alt: list[x509.GeneralName] = [
        x509.DNSName("robot.franka.de"),
        x509.DNSName("localhost"),
        x509.IPAddress(ipaddress.ip_address("127.0.0.1")),
    ]
    now = datetime.datetime.now(datetime.timezone.utc)
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(days=1))
        .not_valid_after(now + datetime.timedelta(days=3650))
        .add_extension(x509.SubjectAlternativeName(alt), critical=False)
        .sign(key, hashes.SHA256())
    )
    directory.mkdir(mode=0o700, parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(cert.public_bytes(serialization.Encoding.PEM))
        f.write(
            key.private_bytes(
                serialization.Encoding.PEM,
                serialization.PrivateFormat.PKCS8,
                serialization.NoEncryption(),
            )
        )
    os.replace(tmp, path)
    return path


def fingerprint(cert_path: Path) -> str:
    """SHA-256 of the certificate (DER) as colon-separated hex, as browsers show it."""
    import hashlib
    import ssl

    text = cert_path.read_text()
    footer = "-----END CERTIFICATE-----"
    der = ssl.PEM_cert_to_DER_cert(text[: text.index(footer) + len(footer)])
    digest = hashlib.sha256(der).hexdigest().upper()
    return ":".join(digest[i : i + 2] for i in range(0, len(digest), 2))
