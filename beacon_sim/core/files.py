"""A user's files: read only when they are what they claim, written only whole.

The one home for both directions:

- **Reading.** :func:`read_user_bytes` and :func:`read_user_text` read a file a user named (a
  scenario, a map YAML and its image, a grade config, a student's filter file) only when it
  is a *regular* file no bigger than the reader's cap, checked before the content is read:
  a FIFO, ``/dev/zero``, ``/dev/urandom``, a socket or a folder is refused at once (opening
  does not block: ``O_NONBLOCK``), and the file is read at most ``cap + 1`` bytes, so one
  that grows while it is read cannot fill the memory either. :func:`open_user_file` does
  the same for a reader that streams (recordings), :func:`check_user_file` for one that
  hands the path to someone else (Python's import of a filter file).
- **Writing.** :func:`atomic_output` gives a temporary path beside the target and renames it
  into place (``os.replace``) only when the body finished; :func:`atomic_write` opens that
  path as a file. A full disk, an error or a kill leaves the previous file as it was (never
  a truncated or 0-byte file), and the message names the file. Writers to one path at once
  each write their own temporary file; one that replaces a file another writer renamed
  into place after it began says so (:class:`~beacon_sim.errors.FileReplacedWarning`).

Every failure is the caller's error class (a :class:`~beacon_sim.errors.BeaconSimError`),
one line naming the file.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from beacon_sim.errors import BeaconSimError, FileReplacedWarning

#: Largest Python source file read or imported as a filter [bytes].
MAX_SOURCE_BYTES = 4 * 2**20

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a folder"))


def _kind(mode: int) -> str:
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a regular file"


def _check_stat(path: Path, st: os.stat_result, what: str, cap: int, error: type[BeaconSimError],
                hint: str) -> None:
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{path}: {_kind(st.st_mode)}, not a {what} (only regular files are read)")
    if st.st_size > cap:
        raise error(f"{path}: {st.st_size:,} bytes: a {what} holds at most {cap:,}{hint}")


def _os_error(path: Path, exc: OSError, what: str, error: type[BeaconSimError]) -> BeaconSimError:
    return error(f"{path}: cannot read the {what}: {exc.strerror or type(exc).__name__}")


def check_user_file(path: str | Path, *, what: str, cap: int,
                    error: type[BeaconSimError] = BeaconSimError, hint: str = "") -> int:
    """Whether ``path`` is a regular file of at most ``cap`` bytes (symbolic links followed);
    returns its size, or raises ``error`` (one line naming the file). For a file someone else
    reads (Python's import); a reader of its own calls :func:`read_user_bytes`."""
    path = Path(path)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise _os_error(path, exc, what, error) from None
    _check_stat(path, st, what, cap, error, hint)
    return st.st_size


def _open_checked(path: Path, what: str, cap: int, error: type[BeaconSimError], hint: str) -> int:
    """A read-only descriptor of ``path`` once it is known to be a regular file within the cap.
    The descriptor is checked (``fstat``), not the name, so a file swapped for a FIFO between
    the check and the open is caught; ``O_NONBLOCK`` keeps the open of a FIFO from waiting."""
    check_user_file(path, what=what, cap=cap, error=error, hint=hint)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0) \
        | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise _os_error(path, exc, what, error) from None
    try:
        _check_stat(path, os.fstat(fd), what, cap, error, hint)
    except BaseException:
        os.close(fd)
        raise
    return fd


def open_user_file(path: str | Path, *, what: str, cap: int,
                   error: type[BeaconSimError] = BeaconSimError, hint: str = "") -> IO[bytes]:
    """A regular file of at most ``cap`` bytes opened for reading (binary), for a reader that
    streams it; ``error`` (one line naming the file) for anything else."""
    path = Path(path)
    fd = _open_checked(path, what, cap, error, hint)
    return os.fdopen(fd, "rb")


def read_user_bytes(path: str | Path, *, what: str, cap: int,
                    error: type[BeaconSimError] = BeaconSimError, hint: str = "") -> bytes:
    """The content of a regular file of at most ``cap`` bytes (``what`` names it in messages:
    "scenario", "map image", ...; ``hint`` ends the too-big message, e.g. how to raise the
    cap). Anything else raises ``error``, one line naming the file, before reading."""
    path = Path(path)
    fd = _open_checked(path, what, cap, error, hint)
    try:
        with os.fdopen(fd, "rb") as f:
            data = f.read(cap + 1)
    except OSError as exc:
        raise _os_error(path, exc, what, error) from None
    if len(data) > cap:  # it grew while being read
        raise error(f"{path}: more than {cap:,} bytes: a {what} holds at most {cap:,}{hint}")
    return data


def read_user_text(path: str | Path, *, what: str, cap: int,
                   error: type[BeaconSimError] = BeaconSimError, hint: str = "") -> str:
    """:func:`read_user_bytes` decoded as UTF-8 (``error`` naming the byte that is not)."""
    data = read_user_bytes(path, what=what, cap=cap, error=error, hint=hint)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not a text {what} (byte {exc.start}: not UTF-8)") from None


# -- writing ----------------------------------------------------------------------------------

@contextlib.contextmanager
def atomic_output(path: str | Path, *, what: str = "file",
                  error: type[BeaconSimError] = BeaconSimError) -> Iterator[Path]:
    """A temporary path beside ``path`` for the body to write; renamed onto ``path``
    (``os.replace``, atomic on one file system) only when the body ends without an error.
    On any error, or a kill, the previous ``path`` is untouched and the temporary file is
    removed (a kill may leave a hidden ``.NAME.*.tmp``, never a partial ``path``). An
    ``OSError`` (a full disk, a read-only folder) becomes ``error`` naming ``path``."""
    path = Path(path)
    folder = path.parent
    tmp = folder / f".{path.name}.{secrets.token_hex(4)}.tmp"
    before = _identity(path)
    try:
        # created here, empty and with the permissions of a new file (umask applies)
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0),
                         0o666))
    except OSError as exc:
        raise error(f"{path}: cannot write the {what}: {exc.strerror or type(exc).__name__}") from None
    try:
        yield tmp
        meanwhile = _identity(path) != before
        os.replace(tmp, path)
        if meanwhile:
            warnings.warn(f"{path}: another writer wrote this {what} while this one was being "
                          "written; this one replaced it", FileReplacedWarning, stacklevel=3)
    except OSError as exc:
        _remove(tmp)
        raise error(f"{path}: cannot write the {what}: {exc.strerror or type(exc).__name__} "
                    "(the previous file, if any, is unchanged)") from None
    except BaseException:
        _remove(tmp)
        raise


def _identity(path: Path) -> tuple[int, int, int, int] | None:
    """What tells one version of ``path`` from another (device, inode, size, modification
    time [ns]), or None when there is no file: another writer's rename changes it."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


def _remove(tmp: Path) -> None:
    with contextlib.suppress(OSError):
        os.unlink(tmp)


@contextlib.contextmanager
def atomic_write(path: str | Path, mode: str = "w", *, what: str = "file",
                 error: type[BeaconSimError] = BeaconSimError, **open_args: Any) -> Iterator[IO[Any]]:
    """A file opened for writing (``mode`` "w" or "wb", ``open_args`` as for :func:`open`,
    e.g. ``encoding``, ``newline``) that replaces ``path`` only once it is complete and on
    the disk (flushed and ``fsync``-ed): :func:`atomic_output`."""
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_write: mode {mode!r}: expected 'w' or 'wb'")
    if mode == "w":
        open_args.setdefault("encoding", "utf-8")
    with atomic_output(path, what=what, error=error) as tmp:
        with open(tmp, mode, **open_args) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())


def write_text_atomic(path: str | Path, text: str, *, what: str = "file",
                      error: type[BeaconSimError] = BeaconSimError, **open_args: Any) -> None:
    """``text`` written to ``path`` whole or not at all (:func:`atomic_write`)."""
    with atomic_write(path, "w", what=what, error=error, **open_args) as fh:
        fh.write(text)



def create_text_new(path: str | Path, text: str, *, what: str = "file",
                    error: type[BeaconSimError] = BeaconSimError) -> None:
    """``text`` written to ``path`` (UTF-8) whole or not at all, and only if no ``path``
    exists at the moment it is created: the text goes to a temporary file beside it, which
    is then hard-linked as ``path`` (``os.link`` fails when the name exists, so a file
    another program made after any earlier check is never replaced). Where the file system
    has no hard links, ``path`` is created with ``O_EXCL`` and written in place (removed
    again if the write fails). A ``path`` that exists: ``error`` saying so; any other
    ``OSError``: ``error`` naming ``path``."""
    path = Path(path)
    tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    exists = f"{path}: the file exists; choose another name"
    try:
        os.close(os.open(tmp, flags, 0o666))   # ours alone (a random name, created exclusively)
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise error(exists) from None
        except OSError as exc:
            if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
                raise
            try:   # no hard links on this file system: an exclusive create, written in place
                fd = os.open(path, flags, 0o666)
            except FileExistsError:
                raise error(exists) from None
            try:
                with os.fdopen(fd, "w", encoding="utf-8") as out:
                    out.write(text)
            except BaseException:
                _remove(path)
                raise
    except OSError as exc:
        raise error(f"{path}: cannot write the {what}: {exc.strerror or type(exc).__name__}") from None
    finally:
        _remove(tmp)
