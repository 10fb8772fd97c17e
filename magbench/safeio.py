"""Safe file input and output for every command: bounded once-only reads, atomic same-file-safe writes.

Reads (``read_input``): only a regular file is read (a FIFO, a device, a socket or a symlink to one is
refused at once, without blocking: the file is opened non-blocking and checked with ``fstat``), at most
``max_bytes`` of it, once; the bytes and their sha256 digest are returned, and the caller parses from
those bytes, so a file rewritten while it is read cannot mix two versions.  The identity of the file read
(device, inode) is kept so that no output may later overwrite it.

Writes (``atomic_write``, ``atomic_output``): to a temporary file in the output's own folder, flushed and
synced, then renamed over the output with ``os.replace`` (atomic on POSIX): a full disk, a kill or an
error leaves the old output (or none), never a truncated or empty one.  Before writing, the output is
compared by inode with every input (``os.path.samefile``: hard links and symlinks included); an output
that is an input is refused, as is one that exists and is not a regular file.

Every ``OSError`` becomes an ``InputError`` naming the path and the reason (the command line's exit 2).
"""
from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import stat
import tempfile
from dataclasses import dataclass
from pathlib import Path

from magbench.errors import InputError

MAX_INPUT_BYTES = 8 * 1024**3
"""The largest data file read (8 GiB): a larger one is refused before any of it is read."""
READ_CHUNK = 16 * 1024**2


@dataclass(frozen=True)
class InputBytes:
    """The bytes of one input file as read once, their sha256, and the file's identity."""

    path: Path
    data: bytes
    sha256: str
    device: int
    inode: int


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def one_line(text) -> str:
    """``text`` for a '#' comment line of a written file: its control characters (a line break in a calibration's
    method name, or in its file's name, had written a metadata line of its own, '# units: uT'; so had one in a
    dataset's metadata value) as escapes.  Used by ``apply``'s ``# calibration:`` line and ``Dataset.to_csv``."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


def os_reason(exc: OSError) -> str:
    """The reason of an ``OSError`` in words ('Permission denied', 'No space left on device')."""
    return exc.strerror or (errno.errorcode.get(exc.errno, "") if exc.errno else "") or type(exc).__name__


def as_path(path, what: str = "file") -> Path:
    """``path`` (a string or an ``os.PathLike``) as a ``Path``, else ``InputError`` (None, a number, a name with a NUL
    byte had reached the operating system's TypeError or ValueError)."""
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"a {what} is named by a path (a string), not a {type(path).__name__}")
    if "\0" in os.fspath(path):
        raise InputError(f"the {what} name {os.fspath(path)!r} holds a NUL byte, which no file name can")
    return Path(path)


def read_input(path, what: str = "file", max_bytes: int = MAX_INPUT_BYTES) -> InputBytes:
    """Read a regular file once, at most ``max_bytes`` (``InputError`` beyond, naming the limit), with its
    sha256.  A directory, FIFO, device or socket is refused without reading (or blocking on) it."""
    path = as_path(path, what)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise InputError(f"no such file: {path}") from None
    except IsADirectoryError:
        raise InputError(f"{path} is a directory, not a {what}") from None
    except OSError as exc:
        raise InputError(f"cannot read {path}: {os_reason(exc)}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = _kind(st.st_mode)
            raise InputError(f"{path} is {kind}, not a {what}" if kind.startswith("a ")
                             else f"{path} is not a regular file: refusing to read it as a {what}")
        if st.st_size > max_bytes:
            raise InputError(f"{path} is {st.st_size:,} bytes, more than the {max_bytes:,}-byte limit for a {what}")
        digest = hashlib.sha256()
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, min(READ_CHUNK, max_bytes + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            digest.update(chunk)
            total += len(chunk)
            if total > max_bytes:  # it grew while read
                raise InputError(f"{path} grew beyond the {max_bytes:,}-byte limit for a {what} while it was read")
        return InputBytes(path, b"".join(chunks), digest.hexdigest(), st.st_dev, st.st_ino)
    except OSError as exc:
        raise InputError(f"cannot read {path}: {os_reason(exc)}") from None
    finally:
        os.close(fd)


def _same_file(a: Path, b) -> bool:
    """Whether ``a`` and ``b`` (a path or an ``InputBytes``) are one file (by device and inode)."""
    try:
        if isinstance(b, InputBytes):
            st = os.stat(a)
            if (st.st_dev, st.st_ino) == (b.device, b.inode):
                return True
            return Path(b.path).exists() and os.path.samefile(a, b.path)
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_output(path, inputs=(), force: bool = False, what: str = "output", probe: bool = True) -> Path:
    """``path`` as a file a command may write: refused (``InputError``) when it is a directory or another
    non-regular file, when its folder does not exist, when it exists and ``force`` is false, and when it
    is one of ``inputs`` (paths or ``InputBytes``; compared by inode, so hard links and symlinks count), and when
    its folder takes no new file (``_probe_folder``: a read-only folder, ``/proc``), before any work is done (not
    with ``probe=False``: ``atomic_output`` creates its own file there at once)."""
    if not str(path).strip():
        raise InputError(f"the {what} name is empty: give a file name")
    path = Path(path)
    for item in inputs:
        if item is None:
            continue
        name = item.path if isinstance(item, InputBytes) else item
        if os.path.abspath(path) == os.path.abspath(name) or _same_file(path, item):
            raise InputError(f"the {what} {path} is the input file {name} (the same file, by inode): "
                             "give another name (an input is never overwritten)")
    try:
        st = os.stat(path)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise InputError(f"cannot write {path}: {os_reason(exc)}") from None
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise InputError(f"{path} is a directory, not a file")
    parent = path.parent
    if not parent.is_dir():
        raise InputError(f"directory {parent} does not exist")
    if st is not None:
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{path} exists and is {_kind(st.st_mode)}: refusing to replace it")
        if not force:
            raise InputError(f"{path} exists; refusing to overwrite it (use --force)")
    if probe:
        _probe_folder(path)
    return path


def _probe_folder(path: Path) -> None:
    """Refuse ``path`` when its folder takes no new file: one created there (the temporary name ``atomic_output``
    would use) and removed again.  Permission bits alone do not say it (root ignores them; a read-only mount and
    ``/proc`` refuse whatever they say), and a write refused after a long fit lost the fit."""
    try:
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".probe")
    except OSError as exc:
        raise InputError(f"cannot write {path}: {os_reason(exc)}") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)


@contextlib.contextmanager
def atomic_output(path, inputs=(), force: bool = False, what: str = "output"):
    """Yield a temporary path in ``path``'s folder (same suffix, so writers that go by the extension
    work); when the block ends without error, the file is synced and renamed onto ``path``.  On any error
    the temporary file is removed and ``path`` is left as it was."""
    path = check_output(path, inputs, force, what, probe=False)  # the temporary file below is the probe
    try:
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=f".tmp{path.suffix}")
        os.close(fd)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {os_reason(exc)}") from None
    tmp = Path(name)
    try:
        yield tmp
        with open(tmp, "rb+") as handle:
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        check_output(path, inputs, force=True, what=what, probe=False)  # nothing became an input meanwhile
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise InputError(f"cannot write {path}: {os_reason(exc)}") from None
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def atomic_write(path, data, inputs=(), force: bool = False, what: str = "output") -> Path:
    """Write ``data`` (bytes, or text written as UTF-8) to ``path`` atomically (``atomic_output``)."""
    payload = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    path = Path(path)
    with atomic_output(path, inputs, force, what) as tmp, open(tmp, "wb") as handle:
        view = memoryview(payload)
        while view:
            view = view[handle.write(view):]
        handle.flush()
    return path


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
