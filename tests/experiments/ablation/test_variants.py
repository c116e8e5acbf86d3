"""experiments/ablation/variants.py and the run.sh that reads variants files through it (issue 39: run.sh ran
every row through ``eval``), and experiments/table1/run.sh's flags. ``cerberus`` is a stand-in on PATH that
records its arguments, so the scripts run in seconds and nothing is trained."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
ABLATION = REPO / "experiments" / "ablation" / "run.sh"


@pytest.fixture
def fake_bin(tmp_path: Path) -> Path:
    """A folder with ``cerberus`` (appends its argv, NUL-separated, one call per line, to $CALLS) and ``python``."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "cerberus").write_text('#!/usr/bin/env bash\nprintf "%s\\0" "$@" >> "$CALLS"; echo >> "$CALLS"\n')
    (bin_dir / "cerberus").chmod(0o755)
    (bin_dir / "python").symlink_to(sys.executable)
    return bin_dir


def _run(fake_bin: Path, tmp_path: Path, rows: str) -> tuple[subprocess.CompletedProcess, list[list[str]]]:
    variants = tmp_path / "variants.txt"
    variants.write_text(rows)
    calls = tmp_path / "calls"
    calls.unlink(missing_ok=True)
    env = {**os.environ, "PATH": f"{fake_bin}:{os.environ['PATH']}", "CALLS": str(calls), "VARIANTS": str(variants),
           "RUNS": str(tmp_path / "runs"), "DATA": str(tmp_path / "data"), "STEPS": "7", "JOBS": "1"}
    proc = subprocess.run(["bash", str(ABLATION)], env=env, capture_output=True, text=True, timeout=120)
    lines = calls.read_text().splitlines() if calls.exists() else []
    return proc, [line.split("\0")[:-1] for line in lines]


def test_legitimate_rows_run_as_before(fake_bin: Path, tmp_path: Path):
    dataset = tmp_path / "human_large"
    dataset.mkdir()
    (dataset / "manifest.json").write_text("{}")
    _, calls = _run(fake_bin, tmp_path, "# a comment, with an apostrophe: it's fine\n"
                    "cpu      | --size tiny | --preset cpu --set losses.coverage=1.0\n\n"
                    f"shared   | @{dataset}   | --preset cpu --set 'model.name=two words'\n")
    runs, data = tmp_path / "runs", tmp_path / "data"
    assert calls[0] == ["data", "generate", "--dataset", "human", "--size", "tiny", "--renderer", "warp", "--out",
                        f"{data}/cpu", "--quiet"]
    trains = [c for c in calls if c[0] == "train"]
    assert trains == [
        ["train", "--preset", "cpu", "--set", "losses.coverage=1.0", "--set", "renderer=warp", "--set",
         f"data.root={data}/cpu", "--set", "train.steps=7", "--set", "train.progress=false", "--out", f"{runs}/cpu"],
        ["train", "--preset", "cpu", "--set", "model.name=two words", "--set", "renderer=warp", "--set",
         f"data.root={dataset}", "--set", "train.steps=7", "--set", "train.progress=false", "--out", f"{runs}/shared"]]
    assert ["eval", f"{runs}/cpu"] in calls and ["eval", f"{runs}/shared"] in calls


@pytest.mark.parametrize("name", ["a$(touch pwned)b", "a`touch pwned`b", "a;touch pwned", "two words", "a*",
                                  "${HOME}", "../escape", "--help", "a..b"])
def test_a_name_that_is_not_plain_is_refused_before_anything_runs(fake_bin: Path, tmp_path: Path, name: str):
    proc, calls = _run(fake_bin, tmp_path, f"{name} | --size tiny | --preset cpu\n")
    assert proc.returncode == 2 and calls == []
    assert proc.stderr.count("\n") == 1 and "variants.txt:1: the name" in proc.stderr and "not a plain name" in proc.stderr
    assert not (REPO / "pwned").exists() and not (tmp_path / "pwned").exists()


def test_arguments_are_words_never_commands(fake_bin: Path, tmp_path: Path):
    proc, calls = _run(fake_bin, tmp_path, "x | --size tiny | --preset cpu --set a=$(touch pwned) `touch pwned` ; "
                       "touch pwned\n")
    trains = [c for c in calls if c[0] == "train"]
    assert trains[0][:9] == ["train", "--preset", "cpu", "--set", "a=$(touch", "pwned)", "`touch", "pwned`", ";"]
    assert not (REPO / "pwned").exists() and not (tmp_path / "pwned").exists()
    proc, calls = _run(fake_bin, tmp_path, "y | --size tiny | --preset 'cpu\n")
    assert proc.returncode == 2 and "close the quotes" in proc.stderr and calls == []


def test_table1_scale_without_a_value_says_so():
    proc = subprocess.run(["bash", str(REPO / "experiments" / "table1" / "run.sh"), "--scale"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 2 and proc.stderr == "run.sh: --scale needs a value: small or large\n"


@pytest.mark.parametrize("variants", sorted((REPO / "experiments" / "ablation").glob("*.txt")), ids=lambda p: p.name)
def test_every_shipped_variants_file_reads(variants: Path):
    """Each variants file in the repository (parts.txt came with issue 38, after variants.py) reads without error."""
    proc = subprocess.run([sys.executable, str(REPO / "experiments" / "ablation" / "variants.py"), "rows", str(variants)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert proc.stdout.count("\n") >= 2


@pytest.fixture
def failing_bin(fake_bin: Path) -> Path:
    """``fake_bin`` whose ``cerberus`` also acts: ``train --out .../broken*`` fails, ``eval RUN`` writes
    ``RUN/eval/results.json`` (and fails for a run named ``noeval*``), ``compare`` prints its arguments as the table."""
    (fake_bin / "cerberus").write_text(r'''#!/usr/bin/env bash
printf "%s\0" "$@" >> "$CALLS"; echo >> "$CALLS"
last="${!#}"
case "$1" in
  train) case "$last" in */broken*) echo "training diverged" >&2; exit 3;; esac ;;
  eval) case "$2" in */noeval*) echo "evaluation failed" >&2; exit 2;; esac
        mkdir -p "$2/eval" && echo '{}' > "$2/eval/results.json" ;;
  compare) echo "TABLE: $*" ;;
esac
''')
    return fake_bin


def test_the_variants_that_finished_are_tabled_when_others_fail(failing_bin: Path, tmp_path: Path):
    """Before: one variant that failed to train or evaluate stopped run.sh (set -e) before the table, so the ones
    that finished were not tabled. Now every variant runs, the table holds those with an evaluation (in the file's
    order), the failed ones are named after it, and the script still exits 1. A training that fails is not
    evaluated: its last checkpoint would be scored as if it had finished."""
    proc, calls = _run(failing_bin, tmp_path, "broken | --size tiny | --preset cpu\nbase | --size tiny | --preset cpu\n"
                       "noeval | --size tiny | --preset cpu\ngood | --size tiny | --preset cpu\n")
    runs = tmp_path / "runs"
    assert proc.returncode == 1, proc.stderr
    assert [c[0] for c in calls if c[0] == "train"] == ["train"] * 4  # every variant was trained
    assert ["eval", f"{runs}/broken"] not in calls and ["eval", f"{runs}/noeval"] in calls
    table = ["compare", f"base={runs}/base", f"good={runs}/good", "--columns", "parts,depth,training"]
    assert calls[-1] == table
    assert proc.stdout.endswith(f"TABLE: {' '.join(table)}\n")
    assert (runs / "ablation.md").read_text() == f"TABLE: {' '.join(table)}\n"
    for name, verdict in (("broken", "FAILED"), ("base", "done"), ("noeval", "FAILED"), ("good", "done")):
        assert f"{name}: {verdict}" in proc.stdout
    assert "training diverged" in (runs / "broken.log").read_text()
    assert "note: the first variant, broken, has no evaluation: the rows are paired with base" in proc.stderr
    assert proc.stderr.rstrip().endswith(f"failed, not in the table: broken noeval (each one's log: {runs}/NAME.log)")

    # run again once broken is mended (its model written): it is evaluated, not trained, and tabled; its mark is gone
    (runs / "broken").mkdir()
    (runs / "broken" / "model.safetensors").write_text("")
    proc, calls = _run(failing_bin, tmp_path,
                       "broken | --size tiny | --preset cpu\nbase | --size tiny | --preset cpu\n")
    assert proc.returncode == 0, proc.stderr
    assert not any(c[0] == "train" and c[-1] == f"{runs}/broken" for c in calls) and ["eval", f"{runs}/broken"] in calls
    assert calls[-1] == ["compare", f"broken={runs}/broken", f"base={runs}/base", "--columns", "parts,depth,training"]
    assert not (runs / "broken.failed").exists() and "failed" not in proc.stderr
