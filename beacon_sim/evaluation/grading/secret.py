"""The grade's secret, which keys every student's random streams and never reaches a child:
drawn (:func:`new_secret`), checked, named by its fingerprint, kept in
:data:`SECRET_FILE` (owner-only) and read back.
"""

from __future__ import annotations

from pathlib import Path

from beacon_sim.evaluation.grading.config import GradeError

#: The file in a grade's output folder that keeps the grade's secret (hex), readable by its
#: owner only: ``grade --secret-file`` takes it back (docs/grading.md, "The grade's secret").
SECRET_FILE = "grade.secret"


def new_secret() -> bytes:
    """A fresh secret for a grade: :data:`~beacon_sim.core.streams.SECRET_BYTES` bytes from
    the operating system's generator."""
    import secrets

    from beacon_sim.core.streams import SECRET_BYTES

    return secrets.token_bytes(SECRET_BYTES)


def check_secret(secret: bytes) -> bytes:
    """``secret`` if it can key a grade (at least 16 bytes), else :class:`GradeError`."""
    if not isinstance(secret, bytes | bytearray) or len(secret) < 16:
        raise GradeError("a grade's secret must be at least 16 bytes (32 hex digits)")
    return bytes(secret)


def secret_fingerprint(secret: bytes) -> str:
    """16 hex digits that name a secret without giving it away (``grade.json`` keeps them, so
    a secret file can be matched to the grade it made)."""
    import hashlib

    return hashlib.sha256(b"beacon-sim grade secret " + secret).hexdigest()[:16]


def read_secret(path: str | Path) -> bytes:
    """The secret kept in ``path`` (hex digits, as :func:`write_outputs` writes it);
    :class:`GradeError` naming what is wrong."""
    try:
        text = Path(path).read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise GradeError(f"{path}: cannot read the grade's secret: {exc}") from None
    try:
        secret = bytes.fromhex(text)
    except ValueError:
        raise GradeError(f"{path}: expected the grade's secret as hex digits (the {SECRET_FILE} "
                         "a grade wrote)") from None
    try:
        return check_secret(secret)
    except GradeError as exc:
        raise GradeError(f"{path}: {exc}") from None


def write_secret(secret_hex: str, path: Path) -> Path:
    """Keep a grade's secret in ``path``, readable and writable by its owner only."""
    import os

    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="ascii") as fh:
        fh.write(secret_hex + "\n")
    os.chmod(path, 0o600)
    return path
