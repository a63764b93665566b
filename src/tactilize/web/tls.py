"""A self-signed certificate for ``tactilize serve --https``, made here by ``cryptography``.

The page needs a secure context for its AudioWorklet output and for Chromium's
``pointerrawupdate`` (docs/references.md, section 5 (secure contexts)); loopback
is one, a LAN address over plain HTTP is not.  A certificate signed by no
authority makes the browser warn once per certificate; the same one is kept
(under the user data directory) and reused while it is valid and names the
address served, so the warning is not repeated at every start.
"""

from __future__ import annotations

import datetime as _dt
import ipaddress
import os
import tempfile
from pathlib import Path
from typing import Iterable

from ..errors import TactilizeError

__all__ = ["tls_dir", "certificate_for", "certificate_names"]

#: How long a generated certificate is valid [days].
VALID_DAYS = 365
#: A certificate this close to its end is replaced [days].
RENEW_DAYS = 7
_CERT, _KEY = "serve-cert.pem", "serve-key.pem"


def tls_dir() -> Path:
    """Where the certificate and its key are kept: ``<user data dir>/tactilize/tls``."""
    import platformdirs

    return Path(platformdirs.user_data_dir("tactilize", appauthor=False)) / "tls"


def certificate_names(path: str | os.PathLike) -> set[str]:
    """The DNS names and IP addresses a PEM certificate is valid for (its subjectAltName)."""
    from cryptography import x509

    cert = x509.load_pem_x509_certificate(Path(path).read_bytes())
    san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    return set(san.get_values_for_type(x509.DNSName)) | {str(a) for a in san.get_values_for_type(x509.IPAddress)}


def _usable(cert_path: Path, key_path: Path, names: set[str], now: _dt.datetime) -> bool:
    from cryptography import x509

    try:
        cert = x509.load_pem_x509_certificate(cert_path.read_bytes())
        key_path.stat()
        covered = certificate_names(cert_path)
    except (OSError, ValueError, x509.ExtensionNotFound):
        return False
    return names <= covered and cert.not_valid_after_utc - now > _dt.timedelta(days=RENEW_DAYS)


def certificate_for(hosts: Iterable[str], directory: str | os.PathLike | None = None) -> tuple[Path, Path]:
    """The certificate and key files to serve ``hosts`` with HTTPS, made if needed.

    The certificate always names ``localhost``, 127.0.0.1 and ::1 besides
    ``hosts``; an existing one is reused when it still names them all and is
    valid for more than :data:`RENEW_DAYS` days.

    Parameters
    ----------
    hosts : iterable of str
        Addresses or names the page is reached at.
    directory : path, optional
        Where to keep them; :func:`tls_dir` by default.

    Returns
    -------
    (cert_path, key_path) : tuple of Path
        PEM files; the key readable by the owner only.

    Raises
    ------
    TactilizeError
        The directory cannot be written.
    """
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    folder = Path(directory) if directory is not None else tls_dir()
    names = {"localhost", "127.0.0.1", "::1"} | {h.strip("[]") for h in hosts if h and h not in ("0.0.0.0", "::")}
    cert_path, key_path = folder / _CERT, folder / _KEY
    now = _dt.datetime.now(_dt.timezone.utc)
    if _usable(cert_path, key_path, names, now):
        return cert_path, key_path
    # Keep the names of the certificate being replaced: a new one means a new warning on every device.
    if cert_path.exists():
        try:
            names |= certificate_names(cert_path)
        except (OSError, ValueError, x509.ExtensionNotFound):
            pass
    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "tactilize serve (self-signed)")])
    alt: list[x509.GeneralName] = []
    for n in sorted(names):
        try:
            alt.append(x509.IPAddress(ipaddress.ip_address(n)))
        except ValueError:
            alt.append(x509.DNSName(n))
    cert = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - _dt.timedelta(minutes=5))
        .not_valid_after(now + _dt.timedelta(days=VALID_DAYS))
        .add_extension(x509.SubjectAlternativeName(alt), critical=False)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(x509.ExtendedKeyUsage([x509.oid.ExtendedKeyUsageOID.SERVER_AUTH]), critical=False)
        .sign(key, hashes.SHA256())
    )
    try:
        folder.mkdir(parents=True, exist_ok=True)
        # A new file, made owner-only (mkstemp: 0600), then moved over the old
        # key: opening the old one would keep whatever mode it had (0644 too),
        # and the key is never readable by others, not even for a moment.
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".serve-key-")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                          serialization.NoEncryption()))
            os.replace(tmp, key_path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    except OSError as exc:
        raise TactilizeError(str(folder), f"cannot store the HTTPS certificate ({exc.strerror or exc})") from None
    return cert_path, key_path
