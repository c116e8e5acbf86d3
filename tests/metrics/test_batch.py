"""Batch evaluation (cerberus_metrics.batch): pairs from folders and files, multiprocessing, failures,
the working directory, and results written atomically."""

from __future__ import annotations

import csv
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cerberus_metrics import MeshInputError, load_parts, voxel_iou
from cerberus_metrics.batch import BatchResult, pairs_from_file, pairs_from_folders, run_batch, write_results
from cerberus_metrics.cli import main

CLI = [sys.executable, "-m", "cerberus_metrics.cli"]


def test_folder_batch_reports_every_failure(folders, tmp_path):
    pairs = pairs_from_folders(*folders)
    assert [p.id for p in pairs] == ["broken", "empty", "lonely", "parts", "s0", "s1", "s2"]
    res = run_batch(pairs, ["voxel_iou"], jobs=2, progress=False)
    s = res.summary
    assert (s["pairs"], s["succeeded"], s["failed"]) == (7, 4, 3)
    errors = {f["id"]: f["error"] for f in s["failures"]}
    assert "broken.obj" in errors["broken"] and "cannot read" in errors["broken"]
    assert "empty" in errors["empty"] and "no prediction named 'lonely'" in errors["lonely"]
    rows = {r["id"]: r for r in res.rows}
    pred, gt = folders
    assert rows["s1"]["voxel_iou"] == voxel_iou(str(pred / "s1.ply"), str(gt / "s1.ply"))
    assert rows["parts"]["voxel_iou"] == 1.0
    vals = [rows[k]["voxel_iou"] for k in ("parts", "s0", "s1", "s2")]
    assert s["metrics"]["voxel_iou"]["count"] == 4
    assert s["metrics"]["voxel_iou"]["mean_succeeded"] == pytest.approx(np.mean(vals))
    assert s["metrics"]["voxel_iou"]["mean_all_pairs"] == pytest.approx(np.sum(vals) / 7)  # 3 failed, scored 0
    assert s["metrics"]["voxel_iou"]["median"] == pytest.approx(np.median(vals))
    write_results(res, tmp_path / "r.json", tmp_path / "r.csv")
    assert json.loads((tmp_path / "r.json").read_text())["summary"]["failed"] == 3
    with open(tmp_path / "r.csv") as fh:
        assert len(list(csv.DictReader(fh))) == 7


def test_a_stem_claimed_twice_is_refused_not_silently_picked(folders, helpers):
    """Issue 26: `preds/c.obj` beside the part folder `preds/c/` (or two files `c.obj`, `c.ply`) scored one
    of them silently; the pair now fails naming both."""
    pred, gt = folders
    helpers.box((-0.3, -0.3, -0.3), (0.2, 0.2, 0.2)).export(pred / "parts.obj")  # and the folder parts/
    helpers.blob(30).export(gt / "s0.obj")  # two ground truths named s0
    pairs = {p.id: p for p in pairs_from_folders(pred, gt)}
    assert pairs["parts"].pred == () and "both 'parts.obj' and the part folder 'parts/'" in pairs["parts"].error
    assert "both 's0.obj' and 's0.ply'" in pairs["s0"].error or "both 's0.ply' and 's0.obj'" in pairs["s0"].error
    assert pairs["s1"].error is None


def test_pairs_files_csv_and_json(folders, tmp_path):
    pred, gt = folders
    (tmp_path / "pairs.csv").write_text(
        "id,pred,gt\n"
        "a,pred/s0.ply,gt/s0.ply\n"
        "b,pred/parts/a.obj;pred/parts/b.obj,gt/parts.obj\n"
    )
    (tmp_path / "pairs.json").write_text(json.dumps(
        {"pairs": [{"pred": ["pred/parts/a.obj", "pred/parts/b.obj"], "gt": "gt/parts.obj"},
                   {"id": "m", "pred": "pred/missing.obj", "gt": "gt/s0.ply"}]}))
    csv_pairs = pairs_from_file(tmp_path / "pairs.csv")
    assert csv_pairs[1].pred == (str(pred / "parts" / "a.obj"), str(pred / "parts" / "b.obj"))
    res = run_batch(csv_pairs + pairs_from_file(tmp_path / "pairs.json"), ["voxel_iou", "fscore"], jobs=1,
                    progress=False, n_samples=2000, threshold=0.05)
    assert [r["status"] for r in res.rows] == ["ok", "ok", "ok", "error"]
    assert res.rows[1]["voxel_iou"] == 1.0 and "fscore" in res.rows[0]
    assert "missing.obj" in res.rows[3]["error"]


def test_clamped_parts_are_counted_in_the_result_the_batch_and_the_cli(tmp_path, helpers, capsys):
    """--outside clamp: a part past the kato grid's corner is clamped, and every output says how many."""
    helpers.box((-0.3, -0.3, -0.3), (0.3, 0.3, 0.3)).export(tmp_path / "gt.obj")
    helpers.box((-0.3, -0.3, -0.3), (0.3, 0.3, 0.3)).export(tmp_path / "body.obj")
    helpers.box((0.7, 0.7, 0.7), (0.8, 0.8, 0.8)).export(tmp_path / "corner.obj")  # wholly past a corner
    (tmp_path / "pairs.csv").write_text("id,pred,gt\nc,body.obj;corner.obj,gt.obj\nplain,body.obj,gt.obj\n")
    pairs = pairs_from_file(tmp_path / "pairs.csv")
    res = run_batch(pairs, ["voxel_iou"], jobs=1, progress=False, outside="clamp")
    assert [(r["voxel_iou"], r["clamped_parts"]) for r in res.rows] == [(1.0, 1), (1.0, 0)]
    assert (res.summary["pairs_clamped"], res.summary["parts_clamped"]) == (1, 1)
    args = ["batch", "--pairs", str(tmp_path / "pairs.csv"), "--jobs", "1", "--no-progress", "--outside", "clamp",
            "--out", str(tmp_path / "o.json")]
    assert main(args) == 0
    assert "clamped: 1 pairs (1 prediction parts" in capsys.readouterr().out
    assert json.loads((tmp_path / "o.json").read_text())["summary"]["parts_clamped"] == 1
    pred = [str(tmp_path / "body.obj"), str(tmp_path / "corner.obj"), str(tmp_path / "gt.obj")]
    assert main(["iou", *pred, "--outside", "clamp", "--json"]) == 0
    out = capsys.readouterr()
    assert json.loads(out.out)["clamped_parts"] == 1 and "1 prediction part(s) reached outside" in out.err
    assert main(["iou", *pred]) == 2  # default: the kato grid's strictness, one line naming the part
    assert "outside the kato grid" in capsys.readouterr().err


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_results_get_the_permissions_of_a_plain_open(folders, tmp_path, umask):
    """write_results is atomic (temporary file, then rename) but must not leave results 0600: new files
    get 0666 less the umask, like open(); a replaced file keeps its mode."""
    pred, gt = folders
    res = run_batch(pairs_from_folders(pred, gt)[-1:], ["voxel_iou"], jobs=1, progress=False)
    old = os.umask(umask)
    try:
        write_results(res, tmp_path / "r.json", tmp_path / "r.csv")
        (tmp_path / "plain.txt").write_text("x")
    finally:
        os.umask(old)
    plain = stat.S_IMODE((tmp_path / "plain.txt").stat().st_mode)
    assert plain == 0o666 & ~umask
    for name in ("r.json", "r.csv"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == plain, name
    os.chmod(tmp_path / "r.json", 0o640)
    write_results(res, tmp_path / "r.json", None)
    assert stat.S_IMODE((tmp_path / "r.json").stat().st_mode) == 0o640
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


# --------------------------------------------------------------------------- the working directory (issue 11)


@pytest.fixture
def cwd_scenario(tmp_path, helpers):
    """An empty ground truth G/c.obj in the first pair, then eight good pairs with relative paths."""
    (tmp_path / "G").mkdir()
    (tmp_path / "P").mkdir()
    (tmp_path / "G" / "c.obj").write_text("")
    helpers.blob(1).export(tmp_path / "gt.obj")
    lines = ["id,pred,gt", "bad,P/p0.obj,G/c.obj"]
    for i in range(8):
        helpers.blob(100 + i).export(tmp_path / "P" / f"p{i}.obj")
        lines.append(f"g{i},P/p{i}.obj,gt.obj")
    (tmp_path / "pairs.csv").write_text("\n".join(lines) + "\n")
    return tmp_path


@pytest.mark.parametrize("jobs", [1, 2])
def test_batch_unreadable_file_does_not_move_relative_paths(cwd_scenario, jobs):
    root = cwd_scenario
    proc = subprocess.run(
        CLI + ["batch", "--pairs", "pairs.csv", "--jobs", str(jobs), "--no-progress", "--out", "out.json",
               "--csv", "out.csv"],
        cwd=root, capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 1, proc.stderr  # one failed pair
    assert (root / "out.json").is_file() and (root / "out.csv").is_file()
    assert not (root / "G" / "out.json").exists() and not (root / "G" / "out.csv").exists()
    data = json.loads((root / "out.json").read_text())
    s = data["summary"]
    assert (s["pairs"], s["succeeded"], s["failed"]) == (9, 8, 1)
    assert [f["id"] for f in s["failures"]] == ["bad"] and "c.obj" in s["failures"][0]["error"]
    assert "does not exist" not in proc.stderr
    assert proc.stderr.count("\n") == 1  # only the failed pair, on one line


def test_failed_read_restores_working_directory(cwd_scenario, monkeypatch):
    monkeypatch.chdir(cwd_scenario)
    (cwd_scenario / "G" / "d.obj").write_text("not a mesh\n")
    with pytest.raises(MeshInputError, match="cannot read mesh file"):
        load_parts("G/d.obj", "gt")
    assert os.getcwd() == str(cwd_scenario)
    assert len(load_parts("gt.obj", "gt")) == 1  # a relative path still resolves
    assert main(["batch", "--pairs", "pairs.csv", "--jobs", "1", "--no-progress", "--out", "o.json"]) == 1
    assert os.getcwd() == str(cwd_scenario) and (cwd_scenario / "o.json").is_file()


def test_results_are_written_atomically(tmp_path):
    result = BatchResult([{"id": "a", "status": "ok", "voxel_iou": 0.5, "warnings": []}], {"pairs": 1})
    with pytest.raises(OSError):
        write_results(result, tmp_path / "r.json", tmp_path / "missing" / "r.csv")
    assert list(tmp_path.iterdir()) == []  # neither the JSON nor a temporary file is left
    (tmp_path / "r.json").write_text("old")
    write_results(result, tmp_path / "r.json", tmp_path / "r.csv")
    assert json.loads((tmp_path / "r.json").read_text())["summary"] == {"pairs": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv", "r.json"]


@pytest.mark.parametrize(("text", "words"), [
    ("[" * 100_000 + "]" * 100_000, r"is not valid JSON \(nested too deeply\)"),
    ('[{"pred": 1' + "0" * 5000 + "}]", "is not valid JSON"),
], ids=["deep", "long-number"])
def test_a_pairs_file_json_can_not_read_is_one_mesh_input_error(tmp_path, text, words):
    """Issue 34 campaign: json.loads raises RecursionError and a plain ValueError besides JSONDecodeError; both
    were an 'internal error' exit."""
    (tmp_path / "pairs.json").write_text(text)
    with pytest.raises(MeshInputError, match=words):
        pairs_from_file(tmp_path / "pairs.json")


def test_a_rerun_replaces_only_results_batch_wrote(cwd_scenario, monkeypatch):
    """Issue 39: an output file is replaced only when ``batch`` wrote it (its JSON marker, the results columns of
    its CSV, or the JSON form before the marker); empty files may be used."""
    monkeypatch.chdir(cwd_scenario)
    args = ["batch", "--pairs", "pairs.csv", "--jobs", "1", "--no-progress", "--out", "o.json", "--csv", "o.csv"]
    assert main(args) == 1  # one failed pair
    first = json.loads(Path("o.json").read_text())
    assert next(iter(first)) == "written_by" and first["written_by"] == "cerberus-metrics batch"
    assert main(args) == 1  # its own results are replaced
    Path("o.json").write_text(json.dumps({"summary": first["summary"], "pairs": first["pairs"]}, indent=2))
    assert main(args) == 1  # the form an earlier version wrote
    Path("o.json").write_text("")
    assert main(args) == 1 and json.loads(Path("o.json").read_text())["summary"]["pairs"] == 9
    Path("o.csv").write_text("id,pred,gt\nmine,a.obj,b.obj\n")
    assert main(args) == 2
    assert Path("o.csv").read_text() == "id,pred,gt\nmine,a.obj,b.obj\n"


def test_the_summary_states_the_mean_over_all_pairs_beside_the_mean_over_the_succeeded(tmp_path, helpers, capsys):
    """Before: `batch` failed a prediction past the kato grid (--outside error by default) and left it out of its
    one `mean`: `succeeded: 1 failed: 1 ... voxel_iou: mean 1.000000 count 1`, where `cerberus eval` clamps the
    part and reports 0.5625 (a rejected prediction counting 0). Now batch clamps by default, as the evaluation
    does, and the summary names two means: over all pairs (failed = 0) and over the succeeded ones. The failure's
    message names the fix as a flag (`--outside clamp`), not `protocol='gt_bbox'`."""
    from cerberus_metrics.scoring import VoxelIoUScorer

    cube = helpers.box((-0.25, -0.25, -0.25), (0.25, 0.25, 0.25))
    cube.export(tmp_path / "gt.obj")
    cube.export(tmp_path / "same.obj")
    big = cube.copy()
    big.apply_scale(2.2)
    big.export(tmp_path / "big.obj")
    (tmp_path / "pairs.csv").write_text("id,pred,gt\nsame,same.obj,gt.obj\nbig,big.obj,gt.obj\n")
    scorer = VoxelIoUScorer()  # what the evaluation scores with
    as_evaluated = np.mean([scorer([(np.asarray(m.vertices), np.asarray(m.faces))],
                                   (np.asarray(cube.vertices), np.asarray(cube.faces)))[0] for m in (cube, big)])
    assert as_evaluated == pytest.approx(0.5625)
    args = ["batch", "--pairs", str(tmp_path / "pairs.csv"), "--jobs", "1", "--no-progress"]
    assert main([*args, "--out", str(tmp_path / "o.json")]) == 0
    out = capsys.readouterr().out
    assert "succeeded: 2  failed: 0" in out and "clamped: 1 pairs" in out
    assert "voxel_iou: mean over all 2 pairs (failed = 0) 0.562500  mean over the 2 succeeded 0.562500" in out
    st = json.loads((tmp_path / "o.json").read_text())["summary"]["metrics"]["voxel_iou"]
    assert st["mean_all_pairs"] == pytest.approx(as_evaluated) and "mean" not in st
    assert main([*args, "--outside", "error"]) == 1
    out, err = capsys.readouterr()
    assert "voxel_iou: mean over all 2 pairs (failed = 0) 0.500000  mean over the 1 succeeded 1.000000" in out
    assert "FAILED big:" in err and "outside the kato grid" in err and "pass --outside clamp" in err
    assert "gt_bbox" not in err
    res = run_batch(pairs_from_file(tmp_path / "pairs.csv"), ["voxel_iou"], jobs=1, progress=False, outside="error")
    error = res.rows[1]["error"]
    assert "pass outside='clamp' to clamp it to the grid" in error and "protocol='gt_bbox'" not in error
    assert run_batch(pairs_from_file(tmp_path / "pairs.csv"), ["voxel_iou"], jobs=1,
                     progress=False).summary["metrics"]["voxel_iou"]["mean_all_pairs"] == pytest.approx(0.5625)


def test_a_metric_without_a_worst_value_has_no_mean_over_failed_pairs(folders, capsys):
    """Chamfer-L2 has no value that stands for a failure (0 is the best), so with a failed pair its mean over all
    pairs is None, and the text summary says so; F-score, precision and recall count a failure as 0."""
    from cerberus_metrics.cli import _print_summary

    res = run_batch(pairs_from_folders(*folders), ["chamfer_l2", "fscore"], jobs=1, progress=False, n_samples=500,
                    threshold=0.05)
    m = res.summary["metrics"]
    assert m["chamfer_l2"]["mean_all_pairs"] is None and m["chamfer_l2"]["mean_succeeded"] > 0
    for name in ("fscore", "precision", "recall"):
        assert m[name]["mean_all_pairs"] == pytest.approx(m[name]["mean_succeeded"] * 4 / 7)
    _print_summary(res.summary, "kato")
    out = capsys.readouterr().out
    assert "chamfer_l2: no mean over all 7 pairs (a failed pair has no chamfer_l2)  mean over the 4 succeeded" in out
    assert "fscore: mean over all 7 pairs (failed = 0)" in out
