"""The commands' tables (cerberus_core.cli.tables): columns sized to their cells and to the terminal."""
from __future__ import annotations

from cerberus_core.cli.tables import GAP, MIN_COLUMN, column_widths, table


def test_columns_take_their_widest_cell_when_they_fit():
    lines = table([["a", "bb", "ccc"], ["dddd", "e", "f"]], width=80)
    assert lines == ["a     bb  ccc", "dddd  e   f"]


def test_the_widest_column_gives_way_and_wraps():
    assert column_widths([10, 50, 5], 40) == [10, 25, 5]
    assert column_widths([30, 30], 10) == [MIN_COLUMN, MIN_COLUMN]  # never below the minimum
    long = "one two three four five six seven eight nine ten eleven twelve"
    lines = table([["name", long, "end"]], indent="  ", width=30)
    assert all(len(line) <= 30 for line in lines)
    start = lines[0].index("one")
    assert lines[0].startswith("  name") and lines[0].rstrip().endswith("end")
    assert " ".join(line[start:].replace("end", "") for line in lines).split() == long.split()
    assert start == 2 + 4 + GAP


def test_paragraphs_paths_and_control_characters():
    path = "/a/rather/long/folder/name/and/a/file.md"
    lines = table([["x", ["first", f"card: {path}"]]], width=20)
    assert lines[:2] == ["x  first", "   card:"] and "".join(line[3:] for line in lines[2:]) == path
    assert all(line[3:].endswith("/") for line in lines[2:-1])  # broken between folders
    assert table([["\x1b[2J", "a\nb"]], width=80) == ["\\x1b[2J  a\\nb"]  # escaped, one line
    assert table([]) == []
