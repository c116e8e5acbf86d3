"""Where commands and the library write results: path checks that raise
:class:`~cerberus_core.errors.ConfigError` before anything is written, and result folders written
whole (:func:`result_folder`, :func:`writing_results`). The sub-commands and
:class:`cerberus_core.run.Run` use them directly; a caller adds its own refusal of a folder (``refuse``)."""
from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from cerberus_core.errors import ConfigError, OutputError
from cerberus_core.plumbing.atomic import atomic_folder, atomic_write_text
from cerberus_core.plumbing.lock import check_unlocked, is_lock_file
from cerberus_core.plumbing.names import printable

#: Written last into every result folder (reconstruct, eval): marks a folder a later run may replace.
RESULT_MARKER = ".cerberus-result.json"


#: The usual limits of a file name and of a whole path, in bytes (Linux's NAME_MAX and PATH_MAX).
NAME_MAX, PATH_MAX = 255, 4096


def check_path_length(path: Path, key: str = "out") -> Path:
    """:class:`ConfigError` when ``path`` or one of its names is longer than file systems allow (a name
    over :data:`NAME_MAX` bytes, the whole over :data:`PATH_MAX`), before anything tries to use it.
    Output names derived from it add at most a few dozen bytes. ``key`` is the parameter that holds ``path``
    (the error's ``key``)."""
    def short(text: str) -> str:
        text = printable(text)
        return text if len(text) <= 40 else text[:37] + "..."

    whole = len(os.fsencode(str(path.absolute())))
    if whole > PATH_MAX - NAME_MAX:
        raise ConfigError.about(key, Path(short(str(path))), f"the path is {whole} bytes long, more than file systems "
                                f"allow for it and the names written inside it ({PATH_MAX - NAME_MAX}); choose a "
                                "shorter path")
    for part in path.parts:
        if len(os.fsencode(part)) > NAME_MAX - 32:
            raise ConfigError.about(key, None, f"the name {short(part)} is {len(os.fsencode(part))} bytes long; file "
                                    f"systems allow {NAME_MAX}, and a temporary name is added to it while writing: "
                                    f"choose a name under {NAME_MAX - 32} bytes")
    return path


Refusal = Callable[[Path], "str | None"]
"""A caller's own check of an output folder: the problem with writing into it (``"is a dataset folder;
write results to another folder"``), or ``None``."""


def resolved(path: str | os.PathLike, key: str = "path") -> Path:
    """``path`` made absolute with every symlink followed (:meth:`Path.resolve`); the one place a path is
    resolved, so that a symlink loop is one :class:`ConfigError` naming ``key`` everywhere, not a
    ``RuntimeError``."""
    try:
        return Path(path).expanduser().resolve()
    except (RuntimeError, OSError) as exc:  # Python < 3.13 raises RuntimeError for a loop, later ones OSError
        raise ConfigError.about(key, printable(path), f"cannot be resolved: a symlink loop "
                                f"({getattr(exc, 'strerror', None) or exc}); fix or remove the link") from None


def check_apart(path: Path, inputs: Sequence[str | os.PathLike], key: str = "out", *,
                what: str = "writing it would replace it") -> Path:
    """:class:`ConfigError` when the output ``path`` is, or holds, one of ``inputs`` (compared by real path,
    symlinks followed): the one rule that no output may be or contain an input."""
    where = resolved(path, key)
    for kept in inputs:
        k = resolved(kept, "input")
        if k == where or where in k.parents:
            relation = "is" if k == where else "holds"
            raise ConfigError.about(key, Path(path), f"{relation} the input {printable(kept)}, and {what}; choose "
                                    f"another `{key}`")
    return path


def output_folder(path: Path, key: str = "out", *, refuse: Refusal | None = None) -> Path:
    """``path`` may be created as a folder: not an existing file, nor under one, nor a path too long to
    write (:func:`check_path_length`), nor a symlink loop, nor a folder the caller's ``refuse`` finds a problem with (a
    :class:`ConfigError` about ``key`` with that problem)."""
    check_path_length(path, key)
    resolved(path, key)  # a symlink loop is one line here, not a FileExistsError from mkdir later
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                what = "is a file" if p == path else f"is under {p}, which is a file"
                raise ConfigError.about(key, path, f"{what}; pass a folder path")
            break
    if refuse is not None and path.is_dir() and (problem := refuse(path)):
        raise ConfigError.about(key, path, problem)
    return path


def output_file(path: Path, key: str = "out", inputs: Sequence[str | os.PathLike] = ()) -> Path:
    """``path`` may be written as a file: not an existing folder, nor under a file, nor too long
    (:func:`check_path_length`), nor one of ``inputs`` (:func:`check_apart`)."""
    check_path_length(path, key)
    check_apart(path, inputs, key)
    if path.is_dir():
        raise ConfigError.about(key, path, "is a folder; pass a file path")
    for p in path.parents:
        if p.exists():
            if not p.is_dir():
                raise ConfigError.about(key, path, f"is under {p}, which is a file; pass a path inside a folder")
            break
    return path


def _home() -> Path | None:
    """The user's home directory, resolved (``None`` where the system does not say)."""
    try:
        return Path.home().resolve()
    except (RuntimeError, OSError, KeyError):
        return None


def result_folder(path: Path, key: str = "out", *, overwrite: bool = False, keep: Sequence[Path] = (),
                  earlier: frozenset[str] = frozenset(), refuse: Refusal | None = None) -> Path:
    """``path`` may receive a result folder, which replaces it whole (:func:`writing_results`).

    Refused (:class:`ConfigError`, before anything is written): what :func:`output_folder` refuses; a
    folder that is, or holds, one of ``keep`` (the inputs, the run, the dataset), the current directory or the
    home directory, or is a file system's root (a mount point), even with ``overwrite``; a non-empty folder that is not an earlier result
    (no :data:`RESULT_MARKER`, nor only the names in ``earlier``: what an older version wrote) unless
    ``overwrite``; a folder a live process is writing into. A destination that is read-only or not
    writable is an :class:`~cerberus_core.errors.OutputError` now, before the work starts.
    """
    output_folder(path, key, refuse=refuse)
    whole = f"a result folder is replaced whole: write the results to a folder of their own, e.g. " \
            f"`{key}={printable(path / 'results')}`"
    check_apart(path, keep, key, what=whole)
    where = resolved(path, key)
    for place, name in ((Path.cwd(), "the current directory"), (_home(), "your home directory")):
        if place is not None and place.is_relative_to(where):
            raise ConfigError.about(key, path, f"holds {name}, and {whole}")
    if where.is_dir() and os.path.ismount(where):
        raise ConfigError.about(key, path, f"is the root of a file system, and {whole}")
    if path.is_dir():
        check_unlocked(path)
        held = sorted(p.name for p in path.iterdir() if not is_lock_file(p))
        earlier_result = (path / RESULT_MARKER).is_file() or (earlier and set(held) <= earlier)
        if held and not earlier_result and not overwrite:
            shown = ", ".join(printable(n) for n in held[:3]) + (f" and {len(held) - 3} more" if len(held) > 3 else "")
            raise ConfigError.about(key, path, f"is not empty (it holds {shown}) and holds no earlier Cerberus "
                                    f"results; pass `overwrite=True` to replace everything in it, or another `{key}`")
    existing = next(p for p in (path.parent.absolute(), *path.parent.absolute().parents) if p.exists())
    if not os.access(existing, os.W_OK | os.X_OK):  # also false on a read-only file system, even for root
        raise OutputError(f"cannot write {printable(path)}: {printable(existing)} is not writable (read-only "
                          f"file system or no permission); choose a writable `{key}`")
    return path


@contextlib.contextmanager
def writing_results(path: Path, command: str) -> Iterator[Path]:
    """Write a result folder whole: yields a temporary folder beside ``path`` to write into; when the
    block ends it gets :data:`RESULT_MARKER` and replaces ``path`` in one rename
    (:func:`cerberus_core.plumbing.atomic.atomic_folder`). An error or a signal leaves ``path`` as it was."""
    with atomic_folder(path) as tmp:
        yield tmp
        atomic_write_text(tmp / RESULT_MARKER, json.dumps({"command": command, "written": time.time()}) + "\n")
