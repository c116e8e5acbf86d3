"""Atomic writes: the one way the toolkit writes a file, or a folder of results, that a reader may open.

* :func:`atomic_write` — write to a temporary file in the same folder, flush, fsync, rename over the
  target, fsync the folder. A reader sees the old file, no file, or the complete new one; a failure
  removes the temporary and leaves the target untouched.
* :func:`atomic_folder` — build a whole folder under a temporary name beside the target, then swap it
  in with one rename (an exchange where the kernel has ``renameat2``). The target holds the complete
  old results or the complete new ones, never a mix; an error or a signal while writing removes the
  temporary folder and leaves the target untouched.

A write the file system refuses (permission, read-only, full, a name too long) raises
:class:`~cerberus_core.errors.OutputError` naming the path and the fix.

Every temporary is a folder named with the writer's process id (``.NAME.PID.XXXXXXXX.tmp``) that holds
:data:`TEMP_MARKER` from the moment it is created (a file is written inside it, then renamed out). A
writer killed outright (SIGKILL, a power cut) cannot remove its temporary, so the next write beside it
removes the temporaries of ``NAME`` whose process is gone (:func:`remove_stale`), and only those that
carry the marker (:func:`is_temporary`): a user's folder or file that merely has such a name is never
touched (issue 39).
"""
from __future__ import annotations

import contextlib
import ctypes
import errno
import io
import os
import re
import shutil
import signal
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

from cerberus_core.errors import OutputError

#: errno values that mean "this destination cannot take the write", each with the fix a user can apply.
_OUTPUT_ERRNOS = {
    errno.EACCES: "no permission to write there: choose a folder you can write to",
    errno.EPERM: "the file system does not allow writing there: choose another folder",
    errno.EROFS: "the file system is read-only: choose a writable folder",
    errno.ENOSPC: "the disk is full: free some space or choose another disk",
    errno.EDQUOT: "the disk quota is exhausted: free some space or choose another disk",
    errno.EFBIG: "the file is larger than this file system or process allows: free space or raise the limit",
    errno.ENAMETOOLONG: "a file name is too long for this file system: use shorter input names or a shorter path",
    errno.EILSEQ: "the file system refuses a character of the name: rename the input with plain characters",
    errno.ENOENT: "the folder cannot hold new files (a virtual file system such as /proc, or it vanished): "
                  "choose a folder on a disk",
    errno.ENOTDIR: "a part of the path is a file, not a folder: choose another path",
}


def output_error(exc: OSError, path: str | Path) -> OSError:
    """``exc`` as an :class:`OutputError` naming ``path`` and the fix, when it is a refused write (see
    ``_OUTPUT_ERRNOS``); any other error is returned unchanged."""
    if exc.errno is None and re.search(r"\d+ requested and \d+ written", str(exc)):
        exc = OSError(errno.ENOSPC, str(exc))  # numpy's short write (ndarray.tofile) carries no errno: a full disk
    if isinstance(exc, OutputError) or exc.errno not in _OUTPUT_ERRNOS:
        return exc
    reason = os.strerror(exc.errno) if exc.errno else str(exc)
    err = OutputError(f"cannot write {os.fsencode(str(path)).decode('utf-8', 'replace')}: {reason}; "
                      f"{_OUTPUT_ERRNOS[exc.errno]}")
    err.errno = exc.errno
    return err


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:  # pragma: no cover - platforms without directory fds
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)


def _current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_FILE_MODE = 0o666 & ~_current_umask()


def atomic_write(path: Path, write: Callable[[io.BufferedWriter], None]) -> None:
    """Write ``path`` through a temporary file in the same folder (inside a marked temporary folder:
    the module docstring): write, flush, fsync, rename.

    A reader sees either the old file, no file, or the complete new one.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale(path.parent, path.name)
        folder = _temporary_folder(path.parent, path.name, ".tmp")
    except OSError as exc:
        raise output_error(exc, path) from None
    tmp = folder / "file"
    try:
        with open(tmp, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, path)
    except OSError as exc:
        raise output_error(exc, path) from None
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    _fsync_dir(path.parent)


#: The file inside every temporary folder this module creates: what marks it as the toolkit's own.
TEMP_MARKER = ".cerberus-temporary"


def _temporary_folder(parent: Path, name: str, suffix: str) -> Path:
    """A new temporary folder beside ``name`` in ``parent`` (``.NAME.PID.XXXXXXXX<suffix>``), holding
    :data:`TEMP_MARKER` before anything else is put in it."""
    tmp = Path(tempfile.mkdtemp(dir=parent, prefix=_temp_prefix(name), suffix=suffix))
    try:
        os.close(os.open(tmp / TEMP_MARKER, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
    except BaseException:
        os.rmdir(tmp)
        raise
    return tmp


def is_temporary(path: Path) -> bool:
    """Whether ``path`` is a temporary this module created: a real folder (not a link) named
    ``.NAME.PID.XXXXXXXX.tmp`` or ``.old`` holding :data:`TEMP_MARKER` as a plain file. A folder without
    it is left alone even when empty: nothing proves the toolkit made it."""
    name = path.name
    if not (name.startswith(".") and name.endswith((".tmp", ".old"))):
        return False
    if path.is_symlink() or not path.is_dir():
        return False
    try:
        marker = path / TEMP_MARKER
        return marker.is_file() and not marker.is_symlink()
    except OSError:
        return False


def _temp_prefix(name: str) -> str:
    """``.NAME.PID.``: the start of a temporary's name beside ``name`` (see the module docstring)."""
    return f".{_short(name)}.{os.getpid()}."


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # EPERM: it exists, owned by someone else
        return True
    return True


def remove_stale(folder: Path, name: str) -> list[Path]:
    """Remove the temporaries of ``name`` in ``folder`` left by processes that no longer run.

    Returns:
        The removed paths. Temporaries of running processes, names not in this module's pattern, and
        anything without the marker (:func:`is_temporary`: a user's file or folder named like one) are
        left alone; a temporary that cannot be removed is skipped.
    """
    removed = []
    prefix = f".{_short(name)}."
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        if not (entry.name.startswith(prefix) and entry.name.endswith((".tmp", ".old"))):
            continue
        pid = entry.name[len(prefix):].split(".", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid() or _alive(int(pid)):
            continue
        path = Path(entry.path)
        if not is_temporary(path):
            continue
        with contextlib.suppress(OSError):
            shutil.rmtree(path)
            removed.append(path)
    return removed


def _short(name: str, limit: int = 100) -> str:
    """A temporary file's name part: at most ``limit`` characters of ``name``, so that the temporary
    name stays within the file system's limit however long the target's name is."""
    return name[:limit]


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write a UTF-8 text file atomically."""
    atomic_write(Path(path), lambda fh: fh.write(text.encode()))


# ------------------------------------------------------------------ folders
_DIR_MODE = 0o777 & ~_current_umask()
_RENAME_EXCHANGE = 2  # linux/fs.h


def _exchange(a: Path, b: Path) -> bool:
    """Swap two existing paths in one step (Linux ``renameat2(RENAME_EXCHANGE)``); ``False`` where the
    kernel, C library or file system cannot, so the caller falls back to two renames."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):  # pragma: no cover - not glibc / not Linux
        return False
    at_fdcwd = -100
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(code, os.strerror(code), str(b))


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """SIGINT and SIGTERM wait (are blocked, then delivered) while the block runs: a rename pair is
    never cut in the middle by Ctrl-C. A no-op outside the main thread or where unsupported."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


@contextlib.contextmanager
def atomic_folder(target: str | Path) -> Iterator[Path]:
    """Build a folder of results whole, then put it in place of ``target`` in one step.

    Yields an empty temporary folder beside ``target`` (same parent, so same file system) to write
    into. When the block ends normally, the temporary folder replaces ``target`` (whatever it held
    is removed); when it raises (an error, Ctrl-C, SIGTERM), the temporary folder is removed and
    ``target`` is untouched. Signals arriving during the swap itself are delivered after it.

    Callers decide beforehand whether ``target`` may be replaced (see
    :func:`cerberus_core.plumbing.outputs.check_output`): this function replaces it unconditionally.

    Raises:
        OutputError: the parent folder cannot be created or written (permission, read-only, full).
    """
    target = Path(target)
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        remove_stale(parent, target.name)
        tmp = _temporary_folder(parent, target.name, ".tmp")
        os.chmod(tmp, _DIR_MODE)  # mkdtemp creates 0700; results get the usual permissions
    except OSError as exc:
        raise output_error(exc, target) from None
    try:
        try:
            yield tmp
            (tmp / TEMP_MARKER).unlink(missing_ok=True)  # the results themselves do not carry it
            _fsync_dir(tmp)
            with _signals_deferred():
                _swap_in(tmp, target)
        except OSError as exc:
            err = output_error(exc, target)
            if isinstance(err, OutputError):  # name the results' real place, not the temporary one
                shown = os.fsencode(str(tmp)).decode("utf-8", "replace")
                named = OutputError(str(err).replace(shown, os.fsencode(str(target)).decode("utf-8", "replace")))
                named.errno = err.errno
                err = named
            raise err from None
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _swap_in(tmp: Path, target: Path) -> None:
    """Put ``tmp`` at ``target``; the old ``target`` (if any) is removed afterwards."""
    if not os.path.lexists(target):
        os.rename(tmp, target)
    elif target.is_dir() and not target.is_symlink() and _exchange(tmp, target):
        shutil.rmtree(tmp, ignore_errors=True)  # tmp now holds the old results
    else:  # two renames: the old folder steps aside under a hidden name, the new one takes its place
        old = _temporary_folder(target.parent, target.name, ".old")
        os.rename(target, old / "old")
        try:
            os.rename(tmp, target)
        except BaseException:
            os.rename(old / "old", target)
            shutil.rmtree(old, ignore_errors=True)
            raise
        shutil.rmtree(old, ignore_errors=True)
    _fsync_dir(target.parent)
