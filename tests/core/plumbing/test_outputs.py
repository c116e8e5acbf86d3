"""cerberus_core.plumbing.outputs: where a command may write, checked before it writes anything."""
from __future__ import annotations

from pathlib import Path

import pytest

from cerberus_core.errors import ConfigError
from cerberus_core.plumbing.outputs import (
    NAME_MAX,
    RESULT_MARKER,
    check_path_length,
    output_file,
    output_folder,
    result_folder,
    writing_results,
)


def test_path_length_limits_name_the_option(tmp_path: Path):
    assert check_path_length(tmp_path / "ok") == tmp_path / "ok"
    with pytest.raises(ConfigError, match=r"^out: the name n+\.\.\. is \d+ bytes long"):
        check_path_length(tmp_path / ("n" * (NAME_MAX - 10)))
    with pytest.raises(ConfigError, match="^dst = .* choose a shorter path") as err:
        check_path_length(tmp_path.joinpath(*["d" * 200] * 25), "dst")
    assert err.value.key == "dst"


def test_output_folder_and_file_refuse_files_folders_and_what_the_caller_refuses(tmp_path: Path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(ConfigError, match="is a file; pass a folder path"):
        output_folder(tmp_path / "f")
    with pytest.raises(ConfigError, match="which is a file"):
        output_folder(tmp_path / "f" / "sub")
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "mine.txt").write_text("{}")
    def refuse(path: Path) -> str | None:
        return "holds mine.txt; write elsewhere" if (path / "mine.txt").is_file() else None

    with pytest.raises(ConfigError, match="^out = .*ds'?: holds mine.txt; write elsewhere") as err:
        output_folder(tmp_path / "ds", refuse=refuse)
    assert err.value.key == "out"
    assert output_folder(tmp_path / "ds") == tmp_path / "ds"  # plumbing itself knows no kind of folder
    assert output_folder(tmp_path / "new", refuse=refuse) == tmp_path / "new"
    with pytest.raises(ConfigError, match="is a folder; pass a file path"):
        output_file(tmp_path / "ds")
    with pytest.raises(ConfigError, match="which is a file; pass a path inside a folder"):
        output_file(tmp_path / "f" / "x.png")
    assert output_file(tmp_path / "new" / "x.png") == tmp_path / "new" / "x.png"


def test_result_folder_protects_inputs_and_foreign_files(tmp_path: Path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run = tmp_path / "run"
    run.mkdir()
    with pytest.raises(ConfigError, match="holds .*run.* a result folder is replaced whole"):
        result_folder(tmp_path, keep=[run])
    with pytest.raises(ConfigError, match="the current directory"):
        result_folder(Path("."))
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("precious")
    with pytest.raises(ConfigError, match=r"is not empty \(it holds notes.txt\).*pass `overwrite=True`"):
        result_folder(mine)
    assert result_folder(mine, overwrite=True) == mine
    with writing_results(tmp_path / "res", "test") as tmp:
        (tmp / "a.txt").write_text("a")
    assert (tmp_path / "res" / RESULT_MARKER).is_file()
    assert result_folder(tmp_path / "res") == tmp_path / "res"  # an earlier result may be replaced


def test_writing_results_leaves_the_old_results_on_error(tmp_path: Path):
    with writing_results(tmp_path / "res", "test") as tmp:
        (tmp / "old.txt").write_text("old")
    with pytest.raises(RuntimeError), writing_results(tmp_path / "res", "test") as tmp:
        (tmp / "new.txt").write_text("new")
        raise RuntimeError("midway")
    assert sorted(p.name for p in (tmp_path / "res").iterdir()) == sorted([RESULT_MARKER, "old.txt"])
    assert [p.name for p in tmp_path.iterdir()] == ["res"]  # no temporary left beside it


def test_overwrite_never_replaces_the_home_directory_or_a_file_system(tmp_path: Path, monkeypatch):
    """Issue 34 campaign: ``cerberus reconstruct ... --out ~ --overwrite`` replaced the whole home directory with
    the results (its files deleted). A folder holding the home directory, or a mount point, is refused even with
    ``overwrite``."""
    home = tmp_path / "home" / "me"
    (home / "notes").mkdir(parents=True)
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(tmp_path)
    for out in (home, home.parent):
        with pytest.raises(ConfigError, match="holds your home directory, and a result folder is replaced whole"):
            result_folder(out, overwrite=True)
    with pytest.raises(ConfigError, match="is the root of a file system"):
        result_folder(Path("/proc"), overwrite=True)
    assert (home / "notes").is_dir()
    assert result_folder(home / "results", overwrite=True) == home / "results"


def test_an_output_folder_that_is_a_symlink_loop_is_named(tmp_path: Path):
    """Issue 34 campaign: `cerberus data generate --out LOOP` said only "File exists: LOOP"."""
    (tmp_path / "loop").symlink_to(tmp_path / "loop")
    with pytest.raises(ConfigError, match="out = .*loop.*: cannot be resolved: a symlink loop"):
        output_folder(tmp_path / "loop")
