"""One writer per folder: a lock file held while a command writes into a run or dataset folder.

:func:`folder_lock` creates ``FOLDER/.cerberus.lock`` holding the writer's pid, host, start time and
command, and removes it on exit. A second writer is refused with :class:`LockedError` naming the
holder. A lock left by a killed process is *stale* and is taken over:

* the lock file is created complete and already ``flock``-ed, then linked into place
  (``link`` fails if the name exists: the ``O_CREAT | O_EXCL`` guarantee without an empty-file
  window);
* the holder keeps an exclusive ``flock`` on it for its lifetime; the kernel drops it when the
  process dies, however it dies. A lock file whose ``flock`` can be taken is therefore stale;
* where ``flock`` is unavailable (some network file systems, Windows) the recorded pid decides: on
  the same host, a pid that no longer runs means stale; a lock from another host is never taken
  over (the message says how to remove it).

Usage::

    with folder_lock(run_dir, "cerberus train"):
        ...  # write into run_dir
"""
from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from cerberus_core.errors import LockedError
from cerberus_core.plumbing import jsontext

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

LOCK_NAME = ".cerberus.lock"


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    except OSError:  # pragma: no cover
        return True
    return True


def _try_flock(fd: int) -> bool | None:
    """``True``: locked; ``False``: someone else holds it; ``None``: flock unsupported here."""
    if fcntl is None:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    except OSError:
        return None


def read_lock(folder: str | Path) -> dict | None:
    """The holder record of ``folder``'s lock file (``None`` if there is none or it is unreadable)."""
    try:
        return jsontext.loads((Path(folder) / LOCK_NAME).read_text())
    except (OSError, ValueError):
        return None


def _describe(info: dict | None) -> str:
    if not info:
        return "another process"
    started = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(info.get("started", 0)))
    return f"pid {info.get('pid')} on {info.get('host')} (since {started}: {info.get('command', '?')})"


class FolderLock:
    """A held lock (see :func:`folder_lock`). ``created_folder``: the folder did not exist before."""

    def __init__(self, folder: Path, fd: int, created_folder: bool) -> None:
        self.folder, self.path, self._fd, self.created_folder = folder, folder / LOCK_NAME, fd, created_folder

    def release(self) -> None:
        """Remove the lock file; remove the folder too if this lock created it and it is still empty."""
        if self._fd < 0:
            return
        with contextlib.suppress(OSError):
            self.path.unlink()
        os.close(self._fd)  # drops the flock
        self._fd = -1
        if self.created_folder:
            with contextlib.suppress(OSError):
                self.folder.rmdir()  # only succeeds when nothing else was written


def acquire(folder: str | Path, command: str | None = None) -> FolderLock:
    """Take ``folder``'s lock (creating the folder); :class:`LockedError` if a live process holds it."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise LockedError(f"{folder} is a file, not a folder; pass a folder path")
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    record = json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "started": time.time(),
                         "command": command or " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])})
    for _ in range(20):
        # 1. a complete, flock-ed lock file under a private name, linked into place only if none exists
        tmp = folder / f"{LOCK_NAME}.{os.getpid()}.{time.monotonic_ns()}"
        fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
        try:
            os.write(fd, record.encode())
            os.fsync(fd)
            _try_flock(fd)
            try:
                os.link(tmp, path)
                return FolderLock(folder, fd, created)
            except FileExistsError:
                pass
            except OSError:  # no hard links on this file system: fall back to O_EXCL on the name
                try:
                    os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
                except FileExistsError:
                    pass
                else:
                    os.close(fd)
                    fd = -1
                    path.write_text(record)
                    fd = os.open(path, os.O_RDWR)
                    _try_flock(fd)
                    return FolderLock(folder, fd, created)
        except BaseException:
            if fd >= 0:
                os.close(fd)
            raise
        finally:
            with contextlib.suppress(OSError):
                tmp.unlink()
        os.close(fd)
        # 2. the name exists: held, or stale?
        try:
            other = os.open(path, os.O_RDWR)
        except FileNotFoundError:
            continue  # released meanwhile: try again
        try:
            info = read_lock(folder)
            got = _try_flock(other)
            if got is False:
                raise LockedError(f"{folder} is in use by {_describe(info)}; wait for it to finish or stop it "
                                  "(one writer per folder)")
            if got is None and info and info.get("host") == socket.gethostname() and _pid_alive(int(info["pid"])):
                raise LockedError(f"{folder} is in use by {_describe(info)}; wait for it to finish or stop it")
            if got is None and info and info.get("host") != socket.gethostname():
                raise LockedError(f"{folder} is locked by {_describe(info)}; if that process is gone, delete "
                                  f"{path} and retry")
            # stale: its holder died. Remove it, unless it was replaced meanwhile, and retry.
            with contextlib.suppress(OSError):
                if os.fstat(other).st_ino == os.stat(path).st_ino:
                    print(f"note: taking over the stale lock of {_describe(info)} in {folder}", file=sys.stderr)
                    path.unlink()
        finally:
            os.close(other)
    raise LockedError(f"{folder}: could not take the lock file {path} (contended); retry")


def live_holder(folder: str | Path) -> dict | None:
    """The record of the live process holding ``folder``'s lock, or ``None`` (no lock, or a stale one).
    Creates nothing: for checks before a command decides to write."""
    path = Path(folder) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        info = read_lock(folder)
        got = _try_flock(fd)
        if got is False:
            return info or {}
        if got is None and info and (info.get("host") != socket.gethostname() or _pid_alive(int(info["pid"]))):
            return info
        return None
    finally:
        os.close(fd)  # also drops a flock taken on a stale file


def check_unlocked(folder: str | Path) -> None:
    """:class:`LockedError` if a live process holds ``folder``'s lock (see :func:`live_holder`)."""
    info = live_holder(folder)
    if info is not None:
        raise LockedError(f"{folder} is in use by {_describe(info)}; wait for it to finish or stop it "
                          "(one writer per folder)")


@contextlib.contextmanager
def folder_lock(folder: str | Path, command: str | None = None) -> Iterator[FolderLock]:
    """Hold ``folder``'s lock for the ``with`` block (see the module docstring)."""
    lock = acquire(folder, command)
    try:
        yield lock
    finally:
        lock.release()


def is_lock_file(path: Path) -> bool:
    """Whether ``path`` is a lock file or the private name of one being created."""
    return path.name == LOCK_NAME or path.name.startswith(LOCK_NAME + ".")
