"""cerberus_core.plumbing.atomic: temporaries carry their writer's pid, and those of dead writers are removed by the
next write beside them (issue 26: SIGKILL during `cerberus reconstruct` left hidden folders forever); a result
folder is written whole (atomic_folder, issue 20)."""
from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cerberus_core.errors import OutputError
from cerberus_core.plumbing.atomic import TEMP_MARKER, atomic_folder, atomic_write_text, remove_stale


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_a_killed_writers_temporary_folder_is_removed_by_the_next_write(tmp_path: Path):
    script = textwrap.dedent("""
        import os, signal, sys
        from cerberus_core.plumbing.atomic import atomic_folder
        with atomic_folder(sys.argv[1]) as tmp:
            (tmp / "half.txt").write_text("half")
            os.kill(os.getpid(), signal.SIGKILL)
    """)
    res = subprocess.run([sys.executable, "-c", script, str(tmp_path / "out")], capture_output=True)
    assert res.returncode == -signal.SIGKILL
    stale = [p for p in tmp_path.iterdir() if p.name.startswith(".out.")]
    assert len(stale) == 1 and stale[0].is_dir() and not (tmp_path / "out").exists()
    with atomic_folder(tmp_path / "out") as tmp:
        (tmp / "whole.txt").write_text("whole")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert (tmp_path / "out" / "whole.txt").read_text() == "whole"


def _marked(path: Path) -> Path:
    path.mkdir()
    (path / TEMP_MARKER).write_text("")
    (path / "half").write_text("half")
    return path


def test_remove_stale_keeps_live_writers_other_names_and_anything_unmarked(tmp_path: Path):
    """Issue 39: a user's folder named like a dead process's temporary (``.res.999999.mine.tmp`` beside ``res``)
    was deleted by the next write, without a word. Only a temporary that carries the writer's marker goes."""
    dead, live = _dead_pid(), os.getppid()
    _marked(tmp_path / f".res.{dead}.abc123.tmp")
    _marked(tmp_path / f".res.{dead}.abc124.old")
    (tmp_path / f".res.{dead}.mine.tmp").mkdir()  # a user's folder: no marker
    (tmp_path / f".res.{dead}.mine.tmp" / "thesis.tex").write_text("precious")
    (tmp_path / f".res.{dead}.def456.tmp").write_text("x")  # a file: never a temporary of this module
    (tmp_path / f".res.{dead}.empty.tmp").mkdir()  # empty, unmarked: nothing proves it is ours
    _marked(tmp_path / f".res.{live}.ghi789.tmp")  # a writer that still runs
    _marked(tmp_path / f".other.{dead}.jkl.tmp")  # another target's
    (tmp_path / f".res.{dead}.link.tmp").symlink_to(tmp_path / f".res.{live}.ghi789.tmp")
    removed = remove_stale(tmp_path, "res")
    assert sorted(p.name for p in removed) == sorted([f".res.{dead}.abc123.tmp", f".res.{dead}.abc124.old"])
    assert (tmp_path / f".res.{dead}.mine.tmp" / "thesis.tex").read_text() == "precious"
    atomic_write_text(tmp_path / "res", "ok")  # files go the same way
    with atomic_folder(tmp_path / "folder") as tmp:
        (tmp / "a").write_text("a")
    assert (tmp_path / "res").read_text() == "ok"
    assert sorted(p.name for p in (tmp_path / "folder").iterdir()) == ["a"]  # the marker stays with temporaries
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([
        "res", "folder", f".res.{dead}.mine.tmp", f".res.{dead}.def456.tmp", f".res.{dead}.empty.tmp",
        f".res.{live}.ghi789.tmp", f".other.{dead}.jkl.tmp", f".res.{dead}.link.tmp"])


def test_atomic_folder_is_complete_or_untouched(tmp_path) -> None:
    target = tmp_path / "out"
    with atomic_folder(target) as tmp:
        atomic_write_text(tmp / "a.txt", "old")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    with pytest.raises(KeyboardInterrupt), atomic_folder(target) as tmp:
        atomic_write_text(tmp / "b.txt", "new")
        raise KeyboardInterrupt
    assert [p.name for p in target.iterdir()] == ["a.txt"] and (target / "a.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    with atomic_folder(target) as tmp:
        atomic_write_text(tmp / "b.txt", "new")
    assert [p.name for p in target.iterdir()] == ["b.txt"]  # replaced whole: no mix
    assert oct(target.stat().st_mode & 0o777) == oct(0o777 & ~_umask())


def test_a_name_too_long_is_an_output_error(tmp_path) -> None:
    with pytest.raises(OutputError, match="file name is too long") as info, atomic_folder(tmp_path / "o") as tmp:
        atomic_write_text(tmp / ("x" * 300), "text")
    assert info.value.errno == errno.ENAMETOOLONG and str(tmp_path / "o") in str(info.value)
    assert ".tmp" not in str(info.value)  # the results' real place is named, not the temporary folder
    assert not any(tmp_path.iterdir())


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_numpys_short_write_is_a_full_disk_naming_the_file(tmp_path) -> None:
    """Issue 34: on a full disk ``np.save`` raises ``OSError("393216 requested and 298880 written")`` with no
    errno; the write is an OutputError naming the path and the full disk, and leaves nothing behind."""
    import pytest

    from cerberus_core.errors import OutputError
    from cerberus_core.plumbing.atomic import atomic_write

    def short_write(fh):
        raise OSError("393216 requested and 298880 written")

    with pytest.raises(OutputError, match=r"cannot write .*shard.npy: No space left on device; the disk is full"):
        atomic_write(tmp_path / "shard.npy", short_write)
    assert list(tmp_path.iterdir()) == []
