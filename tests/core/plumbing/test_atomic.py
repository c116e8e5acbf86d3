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
from cerberus_core.plumbing.atomic import atomic_folder, atomic_write_text, remove_stale


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


def test_remove_stale_keeps_live_writers_and_other_names(tmp_path: Path):
    dead, live = _dead_pid(), os.getppid()
    (tmp_path / f".res.{dead}.abc123.tmp").mkdir()
    (tmp_path / f".res.{dead}.def456.tmp").write_text("x")
    (tmp_path / f".res.{live}.ghi789.tmp").mkdir()  # a writer that still runs
    (tmp_path / f".other.{dead}.jkl.tmp").mkdir()  # another target's
    (tmp_path / ".res.abcdefgh.tmp").mkdir()  # no pid: an earlier version's, left alone
    removed = remove_stale(tmp_path, "res")
    assert sorted(p.name for p in removed) == sorted([f".res.{dead}.abc123.tmp", f".res.{dead}.def456.tmp"])
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [f".res.{live}.ghi789.tmp", f".other.{dead}.jkl.tmp", ".res.abcdefgh.tmp"])
    atomic_write_text(tmp_path / "res", "ok")  # files go the same way
    assert (tmp_path / "res").read_text() == "ok"



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
