"""Where commands and the library write results: path checks that raise
:class:`~cerberus_core.errors.ConfigError` before anything is written, and result folders written
whole (:func:`writing_results`), and the one rule for what an output may replace (:func:`check_output`:
only a folder the toolkit wrote as the same kind of output, by its :data:`MARKER`). Every command that
writes a folder (data generate, train, eval, reconstruct, demo) and :class:`cerberus_core.run.Run` use them."""
from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from cerberus_core.errors import ConfigError, OutputError
from cerberus_core.plumbing.atomic import atomic_folder, atomic_write_text, is_temporary
from cerberus_core.plumbing.lock import check_unlocked, is_lock_file
from cerberus_core.plumbing.names import printable

#: Written into every folder the toolkit creates as an output (a dataset, a training run, the results of
#: eval, reconstruct and demo), with the kind of output it is (:data:`KINDS`): the only proof that a later
#: command may replace what the folder holds (:func:`check_output`, issue 39).
MARKER = ".cerberus-output.json"
#: What eval and reconstruct wrote before :data:`MARKER` (``{"command": "cerberus eval", ...}``); read, never written.
LEGACY_RESULT_MARKER = ".cerberus-result.json"


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


def output_folder(path: Path, key: str = "out") -> Path:
    """``path`` may be created as a folder: not an existing file, nor under one, nor a path too long to
    write (:func:`check_path_length`), nor a symlink loop (a :class:`ConfigError` about ``key``). What it
    may replace is :func:`check_output`'s rule."""
    check_path_length(path, key)
    resolved(path, key)  # a symlink loop is one line here, not a FileExistsError from mkdir later
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                what = "is a file" if p == path else f"is under {p}, which is a file"
                raise ConfigError.about(key, path, f"{what}; pass a folder path")
            break
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


def _homes() -> list[Path]:
    """The home directories to protect, resolved: ``$HOME``'s and the account's own (the password
    database's), which differ when ``HOME`` points elsewhere (issue 39: ``HOME=/tmp`` left the real home
    unprotected)."""
    homes = []
    with contextlib.suppress(RuntimeError, OSError, KeyError):
        homes.append(Path.home().resolve())
    with contextlib.suppress(RuntimeError, OSError, KeyError, ImportError):
        import pwd  # not on Windows

        homes.append(Path(pwd.getpwuid(os.getuid()).pw_dir).resolve())
    return homes


#: What each kind of output is called in messages: the ``kind`` a folder's :data:`MARKER` records.
KINDS = {"dataset": "a dataset (cerberus data generate)", "run": "a training run (cerberus train)",
         "eval": "evaluation results (cerberus eval)", "reconstruct": "reconstructions (cerberus reconstruct)",
         "demo": "demo pictures (cerberus demo)"}


def write_marker(folder: Path, kind: str) -> None:
    """Mark ``folder`` as an output of ``kind`` the toolkit wrote (:data:`MARKER`): the one proof
    :func:`check_output` accepts before anything in it may be replaced."""
    atomic_write_text(folder / MARKER, json.dumps({"written_by": "cerberus", "kind": kind}) + "\n")  # no time: datasets stay byte-identical


def output_kind(folder: Path) -> str | None:
    """The kind of output ``folder`` holds by its marker (:data:`MARKER`, or an earlier version's
    :data:`LEGACY_RESULT_MARKER` of eval and reconstruct), or ``None``: no marker, or one that does not read."""
    for name in (MARKER, LEGACY_RESULT_MARKER):
        marker = folder / name
        if not marker.is_file() or marker.is_symlink():
            continue
        try:
            record = json.loads(marker.read_text(encoding="utf-8")[:4096])
        except (OSError, ValueError):
            return None
        if not isinstance(record, dict):
            return None
        kind = record.get("kind") if name == MARKER else str(record.get("command", "")).removeprefix("cerberus ")
        return kind if kind in KINDS else None
    return None


def check_output(path: Path, kind: str, key: str = "out", *, keep: Sequence[str | os.PathLike] = (),
                 legacy: Callable[[Path], bool] | None = None, holding_lock: bool = False) -> bool:
    """The one rule for an output folder (``docs/outputs.md``), checked before anything is written or
    removed: ``path`` may be new or empty, or hold an output of the same ``kind`` the toolkit wrote
    (its :data:`MARKER`; ``legacy``: the caller recognises its own output of an earlier version, written
    before the marker). Anything else is refused, whatever ``overwrite`` a caller was given: a folder
    holding other files is never replaced nor written into.

    Second line (refused even then): a folder that is or holds one of ``keep`` (the inputs), the current
    directory or a home directory, or is a file system's root; a folder a live process is writing into
    (unless the caller is that process: ``holding_lock``); what :func:`output_folder` refuses. A destination that is read-only or not writable is an
    :class:`~cerberus_core.errors.OutputError` now, before the work starts.

    Returns:
        ``True`` when ``path`` holds an earlier output of ``kind``, ``False`` when it is new or empty.
    Raises:
        ConfigError: about ``key``, naming what is there and the fix.
    """
    output_folder(path, key)
    whole = f"an output folder is replaced whole: write to a folder of its own, e.g. " \
            f"`{key}={printable(path / 'results')}`"
    check_apart(path, keep, key, what=whole)
    where = resolved(path, key)
    for place, name in ((Path.cwd(), "the current directory"), *((h, "a home directory") for h in _homes())):
        if place.is_relative_to(where):
            raise ConfigError.about(key, path, f"holds {name}, and {whole}")
    if where.is_dir() and os.path.ismount(where):
        raise ConfigError.about(key, path, f"is the root of a file system, and {whole}")
    ours = False
    if path.is_dir():
        if not holding_lock:
            check_unlocked(path)
        held = sorted(p.name for p in path.iterdir() if not is_lock_file(p) and not is_temporary(p))
        found = output_kind(path)
        if held and found not in (None, kind):
            raise ConfigError.about(key, path, f"holds {KINDS[found]}, and an output is only ever replaced by one "
                                    f"of the same kind ({KINDS[kind]}); choose another `{key}`")
        ours = bool(held) and (found == kind or (found is None and legacy is not None and legacy(path)))
        if held and not ours:
            shown = ", ".join(printable(n) for n in held[:3]) + (f" and {len(held) - 3} more" if len(held) > 3 else "")
            raise ConfigError.about(key, path, f"is not empty (it holds {shown}) and is not {KINDS[kind]} written by "
                                    f"Cerberus (no {MARKER}); Cerberus never replaces or writes into a folder of "
                                    f"other files, overwrite or not (docs/outputs.md): choose a new or empty "
                                    f"`{key}`, or move those files away")
    existing = next(p for p in (path.parent.absolute(), *path.parent.absolute().parents) if p.exists())
    if not os.access(existing, os.W_OK | os.X_OK):  # also false on a read-only file system, even for root
        raise OutputError(f"cannot write {printable(path)}: {printable(existing)} is not writable (read-only "
                          f"file system or no permission); choose a writable `{key}`")
    return ours


@contextlib.contextmanager
def writing_results(path: Path, kind: str) -> Iterator[Path]:
    """Write a result folder of ``kind`` whole (checked first with :func:`check_output`): yields a
    temporary folder beside ``path`` to write into; when the block ends it gets :data:`MARKER` and
    replaces ``path`` in one rename (:func:`cerberus_core.plumbing.atomic.atomic_folder`). An error or a
    signal leaves ``path`` as it was."""
    with atomic_folder(path) as tmp:
        yield tmp
        write_marker(tmp, kind)
