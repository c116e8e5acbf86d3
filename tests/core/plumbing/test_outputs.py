"""cerberus_core.plumbing.outputs: where a command may write, checked before it writes anything."""
from __future__ import annotations

import os
import pwd
from pathlib import Path

import pytest

from cerberus_core.errors import ConfigError
from cerberus_core.plumbing.outputs import (
    LEGACY_RESULT_MARKER,
    MARKER,
    NAME_MAX,
    check_output,
    check_path_length,
    output_file,
    output_folder,
    output_kind,
    write_marker,
    writing_results,
)


def test_path_length_limits_name_the_option(tmp_path: Path):
    assert check_path_length(tmp_path / "ok") == tmp_path / "ok"
    with pytest.raises(ConfigError, match=r"^out: the name n+\.\.\. is \d+ bytes long"):
        check_path_length(tmp_path / ("n" * (NAME_MAX - 10)))
    with pytest.raises(ConfigError, match="^dst = .* choose a shorter path") as err:
        check_path_length(tmp_path.joinpath(*["d" * 200] * 25), "dst")
    assert err.value.key == "dst"


def test_output_folder_and_file_refuse_files_and_folders(tmp_path: Path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(ConfigError, match="is a file; pass a folder path"):
        output_folder(tmp_path / "f")
    with pytest.raises(ConfigError, match="which is a file"):
        output_folder(tmp_path / "f" / "sub")
    (tmp_path / "ds").mkdir()
    with pytest.raises(ConfigError, match="is a folder; pass a file path"):
        output_file(tmp_path / "ds")
    with pytest.raises(ConfigError, match="which is a file; pass a path inside a folder"):
        output_file(tmp_path / "f" / "x.png")
    assert output_file(tmp_path / "new" / "x.png") == tmp_path / "new" / "x.png"


def test_check_output_protects_inputs_and_the_current_directory(tmp_path: Path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run = tmp_path / "run"
    run.mkdir()
    with pytest.raises(ConfigError, match="holds .*run.* an output folder is replaced whole"):
        check_output(tmp_path, "eval", keep=[run])
    with pytest.raises(ConfigError, match="the current directory"):
        check_output(Path("."), "eval")


def test_only_an_output_of_the_same_kind_is_ever_replaced(tmp_path: Path):
    """Issue 39: ``overwrite`` replaced any folder not on a list (a venv, the installed zoo, a dataset's split).
    The rule now: new, empty, or an output of the same kind the toolkit marked; anything else is refused."""
    assert check_output(tmp_path / "new", "eval") is False
    (tmp_path / "empty").mkdir()
    assert check_output(tmp_path / "empty", "eval") is False
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("precious")
    for kind in ("eval", "reconstruct", "dataset", "run", "demo"):
        with pytest.raises(ConfigError, match=r"is not empty \(it holds notes.txt\) and is not .* written by Cerberus "
                           r"\(no \.cerberus-output\.json\); .*choose a new or empty `out`"):
            check_output(mine, kind)
    with writing_results(tmp_path / "res", "eval") as tmp:
        (tmp / "a.txt").write_text("a")
    assert output_kind(tmp_path / "res") == "eval"
    assert check_output(tmp_path / "res", "eval") is True  # an earlier result may be replaced
    with pytest.raises(ConfigError, match=r"holds evaluation results \(cerberus eval\), and an output is only ever "
                       r"replaced by one of the same kind \(reconstructions"):
        check_output(tmp_path / "res", "reconstruct")
    (mine / MARKER).write_text("not json")  # a marker that does not read proves nothing
    with pytest.raises(ConfigError, match="is not empty"):
        check_output(mine, "eval")
    old = tmp_path / "old"  # what eval and reconstruct marked before issue 39
    old.mkdir()
    (old / LEGACY_RESULT_MARKER).write_text('{"command": "cerberus reconstruct", "written": 0}')
    assert check_output(old, "reconstruct") is True
    assert check_output(mine, "eval", legacy=lambda p: (p / "notes.txt").is_file()) is True  # the caller knows its own
    (tmp_path / "only").mkdir()
    write_marker(tmp_path / "only", "dataset")
    assert check_output(tmp_path / "only", "dataset") is True
    assert (mine / "notes.txt").read_text() == "precious"


def test_writing_results_leaves_the_old_results_on_error(tmp_path: Path):
    with writing_results(tmp_path / "res", "eval") as tmp:
        (tmp / "old.txt").write_text("old")
    with pytest.raises(RuntimeError), writing_results(tmp_path / "res", "eval") as tmp:
        (tmp / "new.txt").write_text("new")
        raise RuntimeError("midway")
    assert sorted(p.name for p in (tmp_path / "res").iterdir()) == sorted([MARKER, "old.txt"])
    assert [p.name for p in tmp_path.iterdir()] == ["res"]  # no temporary left beside it


def test_overwrite_never_replaces_the_home_directory_or_a_file_system(tmp_path: Path, monkeypatch):
    """Issue 34 campaign: ``cerberus reconstruct ... --out ~ --overwrite`` replaced the whole home directory with
    the results (its files deleted). A folder holding a home directory, or a mount point, is refused even when it
    carries a marker (the second line of the rule). Issue 39: with ``HOME`` pointing elsewhere the account's own
    home (the password database's) was unprotected. Nothing here writes: only the checks run."""
    home = tmp_path / "home" / "me"
    (home / "notes").mkdir(parents=True)
    write_marker(home, "eval")  # even a home that reads as results
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(tmp_path)
    for out in (home, home.parent):
        with pytest.raises(ConfigError, match="holds a home directory, and an output folder is replaced whole"):
            check_output(out, "eval")
    with pytest.raises(ConfigError, match="is the root of a file system"):
        check_output(Path("/proc"), "eval")
    assert (home / "notes").is_dir()
    assert check_output(home / "results", "eval") is False
    real = Path(pwd.getpwuid(os.getuid()).pw_dir)
    for elsewhere in (str(tmp_path / "other"), "/", ".", ""):
        monkeypatch.setenv("HOME", elsewhere)
        with pytest.raises(ConfigError, match="holds a home directory"):
            check_output(real, "eval")


def test_an_output_folder_that_is_a_symlink_loop_is_named(tmp_path: Path):
    """Issue 34 campaign: `cerberus data generate --out LOOP` said only "File exists: LOOP"."""
    (tmp_path / "loop").symlink_to(tmp_path / "loop")
    with pytest.raises(ConfigError, match="out = .*loop.*: cannot be resolved: a symlink loop"):
        output_folder(tmp_path / "loop")


def test_the_places_issue_39_lost_are_refused_by_the_rule(tmp_path: Path):
    """Issue 39: ``--out PLACE --overwrite`` replaced the installed zoo (every later command failed to import), the
    venv the command ran from, the folder its package is imported from, a run's ``checkpoints/`` and a dataset's
    ``train/``. None carries the marker of the kind written there, so each is refused by the one rule; the
    installed places are only checked here (nothing is written), the run and dataset are made under ``tmp_path``."""
    import sys

    import cerberus_core
    import cerberus_core.zoo

    package = Path(cerberus_core.__file__).parent
    for place in (Path(cerberus_core.zoo.__file__).parent, Path(sys.prefix), package, package.parent):
        for kind in ("eval", "reconstruct", "dataset", "run", "demo"):
            with pytest.raises(ConfigError, match=r"is not empty \(it holds .*\) and is not .* written by Cerberus"):
                check_output(place, kind)
    run, data = tmp_path / "run", tmp_path / "data"
    for folder, kind, inner in ((run, "run", "checkpoints"), (data, "dataset", "train")):
        (folder / inner).mkdir(parents=True)
        (folder / inner / "last.pt").write_bytes(b"weights")
        write_marker(folder, kind)
        for other in ("eval", "reconstruct", "demo", "run", "dataset"):
            with pytest.raises(ConfigError, match=r"is not empty \(it holds last.pt\)"):
                check_output(folder / inner, other)
            if other != kind:
                with pytest.raises(ConfigError, match="an output is only ever replaced by one of the same kind"):
                    check_output(folder, other)
        assert (folder / inner / "last.pt").read_bytes() == b"weights"
