"""The package's one way to write files atomically: the results files of ``batch`` and the grid cache's ``.npz``
entries.

Each file is written to a new temporary file beside it (a random name, created exclusively, so two processes
never share one), flushed and ``fsync``-ed, and moved into place with :func:`os.replace` only when every file
of the call is complete. A reader therefore sees the old file or the whole new one, never half of it, and an
error (a full disk, a target that is a folder, Ctrl-C) removes the temporary files and leaves no partial output.
Permissions are those of a plain ``open(path, "w")``: ``0o666`` less the umask for a new file, the old mode
for a replaced one.
"""

from __future__ import annotations

import os
import secrets
import stat
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import BinaryIO

__all__ = ["write_atomically"]


def _create_temp(target: Path) -> tuple[int, str]:
    """Create a new temporary file beside ``target`` with the permissions ``open(target, "w")`` would
    give: ``0o666`` less the umask (the kernel applies it) or, when ``target`` exists, its mode.

    ``tempfile.mkstemp`` would create it ``0o600``, and :func:`os.replace` keeps the temporary
    file's mode, so results would be readable by their owner only. Returns ``(fd, path)``.
    """
    try:
        mode: int | None = stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        mode = None
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        tmp = str(target.parent / f".{target.name}.{secrets.token_hex(6)}.tmp")
        try:
            fd = os.open(tmp, flags, 0o666)
        except FileExistsError:
            continue
        if mode is not None:
            try:
                os.fchmod(fd, mode)
            except OSError:  # e.g. a file system without modes: keep the umask's
                pass
        return fd, tmp
    raise FileExistsError(f"no free temporary file name beside '{target}'")


def write_atomically(files: Sequence[tuple[str | os.PathLike, Callable[[BinaryIO], object]]]) -> None:
    """Write each ``(target, write)`` pair: ``write(fh)`` fills a binary file that replaces ``target`` once every
    file of ``files`` is complete (module docstring). Raises what a ``write`` or the file system raises, after
    removing the temporary files.

    Example: two files, both in place only when both are written:

    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> write_atomically([(folder / "a.txt", lambda fh: fh.write(b"one")),
    ...                   (folder / "b.txt", lambda fh: fh.write(b"two"))])
    >>> sorted(p.name for p in folder.iterdir()), (folder / "b.txt").read_text()
    (['a.txt', 'b.txt'], 'two')
    >>> write_atomically([(folder / "a.txt", lambda fh: fh.write(b"new")), (folder / "c.txt", lambda fh: 1 / 0)])
    Traceback (most recent call last):
    ...
    ZeroDivisionError: division by zero
    >>> sorted(p.name for p in folder.iterdir()), (folder / "a.txt").read_text()  # nothing replaced or left behind
    (['a.txt', 'b.txt'], 'one')
    >>> import shutil; shutil.rmtree(folder)
    """
    temps: list[str] = []
    try:
        for target, write in files:
            fd, tmp = _create_temp(Path(target))
            temps.append(tmp)
            with os.fdopen(fd, "wb") as fh:
                write(fh)
                fh.flush()
                os.fsync(fh.fileno())  # the data is on disk before the name points at it
        for (target, _), tmp in zip(files, temps, strict=True):
            os.replace(tmp, target)
    finally:
        for tmp in temps:
            if os.path.exists(tmp):
                os.unlink(tmp)
