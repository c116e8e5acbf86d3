"""Batch evaluation (multiprocessing), the CLI and the entry points."""

from __future__ import annotations

import csv
import json
import os
import stat
import subprocess
import sys
from importlib.metadata import entry_points

import numpy as np
import pytest
import trimesh

from cerberus_metrics import voxel_iou
from cerberus_metrics.batch import pairs_from_file, pairs_from_folders, run_batch, write_results
from cerberus_metrics.cli import main


@pytest.fixture
def folders(tmp_path, helpers):
    pred, gt = tmp_path / "pred", tmp_path / "gt"
    pred.mkdir()
    gt.mkdir()
    for i in range(3):
        helpers.blob(10 + i).export(gt / f"s{i}.ply")
        helpers.blob(20 + i).export(pred / f"s{i}.ply")
    (pred / "parts").mkdir()  # a prediction made of parts, matched by folder name
    helpers.box((-0.3, -0.3, -0.3), (0.0, 0.2, 0.2)).export(pred / "parts" / "a.obj")
    helpers.box((-0.1, -0.3, -0.3), (0.2, 0.2, 0.2)).export(pred / "parts" / "b.obj")
    helpers.box((-0.3, -0.3, -0.3), (0.2, 0.2, 0.2)).export(gt / "parts.obj")
    (pred / "broken.obj").write_text("this is not a mesh\nv 1\n")  # unreadable prediction
    helpers.blob(1).export(gt / "broken.obj")
    (pred / "empty.obj").write_text("# no faces\nv 0 0 0\nv 1 0 0\nv 0 1 0\n")
    helpers.blob(2).export(gt / "empty.obj")
    helpers.blob(3).export(gt / "lonely.ply")  # no prediction
    return pred, gt


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
    assert s["metrics"]["voxel_iou"]["mean"] == pytest.approx(np.mean(vals))
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


def test_cli_iou_json_and_errors(folders, capsys):
    pred, gt = folders
    assert main(["iou", str(pred / "s0.ply"), str(gt / "s0.ply")]) == 0
    out = capsys.readouterr().out
    assert float(out) == pytest.approx(voxel_iou(str(pred / "s0.ply"), str(gt / "s0.ply")), abs=1e-6)
    assert main(["iou", str(pred / "parts" / "a.obj"), str(pred / "parts" / "b.obj"), str(gt / "parts.obj"),
                 "--json", "--protocol", "gt_bbox", "--resolution", "64"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["voxel_iou"] == 1.0 and data["settings"]["resolution"] == 64 and len(data["pred"]) == 2
    assert main(["iou", str(pred / "broken.obj"), str(gt / "s0.ply")]) == 2
    err = capsys.readouterr().err
    assert "error:" in err and "broken.obj" in err
    assert main(["chamfer", str(pred / "s0.ply"), str(gt / "s0.ply"), "--samples", "2000", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["chamfer_l2"] > 0
    assert main(["check", str(gt / "s0.ply"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)[0]["watertight"] is True


def test_cli_batch_exit_code_and_outputs(folders, tmp_path, capsys):
    pred, gt = folders
    rc = main(["batch", "--pred-dir", str(pred), "--gt-dir", str(gt), "--jobs", "2", "--no-progress",
               "--out", str(tmp_path / "o.json"), "--csv", str(tmp_path / "o.csv"),
               "--cache-dir", str(tmp_path / "cache")])
    assert rc == 1  # some pairs failed: reported, counted, outputs written
    captured = capsys.readouterr()
    assert "failed: 3" in captured.out and "FAILED lonely" in captured.err
    assert json.loads((tmp_path / "o.json").read_text())["summary"]["succeeded"] == 4
    assert any((tmp_path / "cache").iterdir())


def test_console_script_help():
    exe = [sys.executable, "-m", "cerberus_metrics.cli"]
    out = subprocess.run(exe + ["--help"], capture_output=True, text=True, check=True).stdout
    assert "kato" in out and "gt_bbox" in out and "batch" in out
    out = subprocess.run(exe + ["iou", "--help"], capture_output=True, text=True, check=True).stdout
    assert "PRED [PRED ...] GT" in out


def test_entry_points_discover_metrics(helpers):
    eps = {ep.name: ep for ep in entry_points(group="cerberus.metrics")}
    assert {"voxel_iou", "chamfer_l2", "fscore"} <= set(eps)
    voxel = eps["voxel_iou"].load()
    a = helpers.box((-0.3, -0.3, -0.3), (0.1, 0.1, 0.1))
    parts = [(np.asarray(a.vertices), np.asarray(a.faces)), trimesh.creation.icosphere(radius=0.1)]
    iou = voxel(parts, a, protocol="kato", resolution=32)
    assert isinstance(iou, float) and 0 < iou <= 1
    assert isinstance(eps["fscore"].load()(a, a, n_samples=1000), float)


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
