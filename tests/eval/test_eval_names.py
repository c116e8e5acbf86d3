"""Names from outside in what the toolkit writes and prints (issue 20): results.md escapes subject names and
titles, terminal text never carries control characters, output stems are valid and short, and a result
folder is written whole (cerberus_core.plumbing.atomic.atomic_folder)."""
from __future__ import annotations

import errno
import os

import pytest

from cerberus_core.errors import OutputError
from cerberus_core.eval.report import markdown_report, md_text
from cerberus_core.plumbing.atomic import atomic_folder, atomic_write_text
from cerberus_core.plumbing.names import MAX_STEM_BYTES, printable, safe_stem

HOSTILE_SUBJECT = "<img src=x onerror=alert(1)>|`x`[link](http://e.x)\x1b[31m"


def _result(groups: dict[str, float]) -> dict:
    return {"protocol": "kato", "resolution": 32, "seconds": 1.0, "canonical": {s: 0 for s in groups},
            "standard": {"mean": 0.5, "count": len(groups), "per_group": groups, "clipped": 0, "failed": 0},
            "hard": {"mean": 0.4, "count": 1, "per_group": groups, "clipped": 0, "failed": 0},
            "part_quality": None, "part_visibility": None, "records": []}


def test_results_md_shows_hostile_names_as_text() -> None:
    md = markdown_report(_result({HOSTILE_SUBJECT: 0.5, "plain": 0.25}), title="Evaluation of runs/<b>x</b>")
    assert "<img" not in md and "<b>" not in md and "\x1b" not in md
    assert "# Evaluation of runs/&lt;b&gt;x&lt;/b&gt;" in md
    row = next(line for line in md.splitlines() if "onerror" in line)
    assert row.count(" | ") == 2  # the name's pipe does not open a cell: Subject | Standard | Hard Human
    assert "\\`x\\`" in row and "\\[link\\]" in row and "\\\\x1b" in row
    assert "| plain | 0.2500 | 0.2500 |" in md


def test_md_text_and_printable() -> None:
    assert md_text("a&b") == "a&amp;b"
    assert printable("ok \x1b[2J\r\n\u202e") == "ok \\x1b[2J\\r\\n\\u202e"
    assert printable(os.fsdecode(b"caf\xe9")) == "caf\\xe9"
    assert printable("café ü") == "café ü"


def test_safe_stem_is_short_valid_and_distinct() -> None:
    assert safe_stem(os.fsdecode(b"caf\xe9")) == "caf_"
    assert safe_stem("\x1b[31mred") == "_[31mred"
    assert safe_stem("..hidden") == "hidden" and safe_stem("") == "image"
    long_a, long_b = "é" * 200 + "a", "é" * 200 + "b"
    a, b = safe_stem(long_a), safe_stem(long_b)
    assert a != b and len(a.encode()) <= MAX_STEM_BYTES and len(b.encode()) <= MAX_STEM_BYTES
    a.encode("utf-8")


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
