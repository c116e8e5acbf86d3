"""Issue 11: batch working directory, silent loader repairs, degenerate/absurd scales, CLI errors and help."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import warnings

import numpy as np
import pytest
import trimesh

from cerberus_metrics import MeshInputError, MeshQualityWarning, chamfer_l2, inspect_mesh, load_parts, voxel_iou
from cerberus_metrics.batch import BatchResult, write_results
from cerberus_metrics.cli import build_parser, main

CLI = [sys.executable, "-m", "cerberus_metrics.cli"]


def _files(root) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


# --------------------------------------------------------------------------- 1. working directory


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


# --------------------------------------------------------------------------- 2. what the loader used to drop

TETRA = "v 0 0 0\nv 0.3 0 0\nv 0 0.3 0\nv 0 0 0.3\n"
PLY_HEAD = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 4\nproperty list uchar int vertex_indices\nend_header\n")


def _binary_ply(path, vertices, faces):
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\nproperty float y\n"
            "property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n")
    with open(path, "wb") as fh:
        fh.write((head % (len(vertices), len(faces))).encode())
        fh.write(np.asarray(vertices, "<f4").tobytes())
        for f in faces:
            fh.write(struct.pack("<B3i", 3, *f))


def _binary_stl(path, triangles):
    with open(path, "wb") as fh:
        fh.write(b"\0" * 80 + struct.pack("<I", len(triangles)))
        for t in triangles:
            fh.write(struct.pack("<12fH", 0, 0, 0, *np.ravel(t), 0))


TETRA_V = [[0, 0, 0], [0.3, 0, 0], [0, 0.3, 0], [0, 0, 0.3]]
TETRA_F = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
INF_TRI = [[0, 0, 0], [1, 0, 0], [0, 0, -np.inf]]


@pytest.mark.parametrize(
    "name,write,words",
    [
        ("oob.obj", lambda p: p.write_text(TETRA + "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 99\n"),
         ["line 8", "'f 2 3 99'", "vertex 99", "4 vertices"]),
        ("neg.obj", lambda p: p.write_text(TETRA + "f -4 -2 -3\nf 1 2 4\nf 1 4 3\nf 2 3 -5\n"),
         ["line 8", "vertex -5", "4 vertices"]),
        ("zero.obj", lambda p: p.write_text(TETRA + "f 0 3 2\n"), ["line 5", "vertex 0", "4 vertices"]),
        ("oob.off", lambda p: p.write_text("OFF\n4 4 0\n" + TETRA.replace("v ", "")
                                           + "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 99\n"),
         ["face 3", "line 10", "vertex 99", "4 vertices"]),
        ("oob_a.ply", lambda p: p.write_text(PLY_HEAD + TETRA.replace("v ", "")
                                             + "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 99\n"),
         ["face 3", "vertex 99", "4 vertices"]),
        ("oob_b.ply", lambda p: _binary_ply(p, TETRA_V, TETRA_F[:3] + [[1, 2, 99]]),
         ["face 3", "vertex 99", "4 vertices"]),
        ("nan.obj", lambda p: p.write_text(TETRA.replace("0 0 0.3", "0 0 nan") + "f 1 3 2\nf 2 3 4\n"),
         ["NaN or non-finite", "1 of 4 vertices", "line 4"]),
        ("allnan.obj", lambda p: p.write_text("v nan nan nan\nv nan 0 0\nv 0 inf 0\nf 1 2 3\n"),
         ["NaN or non-finite", "3 of 3 vertices"]),
        ("nan.off", lambda p: p.write_text("OFF\n4 4 0\n0 0 0\n0.3 0 0\n0 0.3 0\n0 0 nan\n"
                                           "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"),
         ["NaN or non-finite", "1 of 4 vertices", "vertex 3"]),
        ("nan_a.ply", lambda p: p.write_text(PLY_HEAD + "0 0 0\n0.3 0 0\n0 0.3 0\n0 0 nan\n"
                                             "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"),
         ["NaN or non-finite", "1 of 4 vertices", "vertex 3"]),
        ("nan_b.ply", lambda p: _binary_ply(p, TETRA_V[:3] + [[0, np.nan, 0.3]], TETRA_F),
         ["NaN or non-finite", "1 of 4 vertices", "vertex 3"]),
        ("nan_b.stl", lambda p: _binary_stl(p, [[[0, 0, 0], [1, 0, 0], [0, 1, 0]], INF_TRI]),
         ["NaN or non-finite", "1 of 2 triangles", "triangle 1"]),
        ("nan_a.stl", lambda p: p.write_text("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                                             "vertex 0 nan 0\nendloop\nendfacet\nendsolid t\n"),
         ["NaN or non-finite", "1 of 3 vertices", "line 6"]),
        ("degenerate.obj", lambda p: p.write_text("v 0.1 0.1 0.1\n" * 4 + "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"),
         ["degenerate mesh", "all 4 vertices are the same point", "[0.1, 0.1, 0.1]"]),
        ("empty.obj", lambda p: p.write_text(""), ["empty (0 bytes)"]),
    ],
)
def test_loader_defects_are_errors_naming_file_and_place(tmp_path, name, write, words):
    path = tmp_path / name
    write(path)
    with pytest.raises(MeshInputError) as info:
        inspect_mesh(str(path), "gt")
    msg = str(info.value)
    assert f"gt ('{path}')" in msg, msg
    for w in words:
        assert w in msg, (w, msg)
    assert "\n" not in msg


def test_cli_check_rejects_out_of_range_face(tmp_path, capsys):
    path = tmp_path / "oob.obj"
    path.write_text(TETRA + "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 99\n")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "vertex 99" in err and "4 vertices" in err and "removed" not in err
    assert main(["iou", str(path), str(path)]) == 2


def test_valid_obj_index_forms_still_load(tmp_path, helpers):
    box = helpers.box((-0.2, -0.2, -0.2), (0.2, 0.2, 0.2))
    lines = [f"v {x} {y} {z}" for x, y, z in box.vertices] + ["vt 0 0", "vn 0 0 1"]
    n = len(box.vertices)
    for k, (a, b, c) in enumerate(box.faces):
        if k % 3 == 0:
            lines.append(f"f {a + 1}/1/1 {b + 1}/1/1 {c + 1}/1/1")
        elif k % 3 == 1:
            lines.append(f"f {a - n} {b - n} {c - n}")  # negative: counted back from the last vertex
        else:
            lines.append(f"f {a + 1}//1 {b + 1}//1 {c + 1}//1")
    (tmp_path / "forms.obj").write_text("\n".join(lines) + "\n")
    assert voxel_iou(str(tmp_path / "forms.obj"), box) == 1.0


def test_absurd_scales_give_clear_messages(helpers):
    gt = helpers.blob(1)
    huge = trimesh.Trimesh(gt.vertices * 1e6, gt.faces)
    with pytest.raises(MeshInputError, match=r"pred: mesh reaches .* ground-truth sizes .* same units"):
        voxel_iou(huge, gt, "gt_bbox")
    with pytest.raises(MeshInputError, match=r"pred .* and gt .* times apart in scale or position"):
        chamfer_l2(huge, gt, n_samples=500, normalize=True)
    far = trimesh.Trimesh(gt.vertices + 1e13, gt.faces, process=False)  # size ~0.6 at 1e13: ~300 float steps
    with pytest.raises(MeshInputError, match=r"too small to normalise relative to its position"):
        voxel_iou(gt, far, "gt_bbox")
    speck = trimesh.Trimesh(gt.vertices * 1e-3, gt.faces)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeshQualityWarning)
        iou = voxel_iou(speck, gt)
    assert 0 < iou < 0.01
    assert any("pred: mesh spans only" in str(w.message) for w in caught)


# --------------------------------------------------------------------------- 3. help


def test_every_subcommand_has_description_and_examples():
    parser = build_parser()
    subs = next(a for a in parser._actions if a.dest == "command").choices
    assert set(subs) == {"iou", "chamfer", "fscore", "check", "batch", "protocols"}
    for name, sub in subs.items():
        text = sub.format_help()
        assert sub.description and "Examples:" in text and f"cerberus-metrics {name}" in text, name
    assert "watertight" in subs["check"].format_help()
    top = parser.format_help()
    assert "COMMAND --help" in top and "Exit codes" in top


# --------------------------------------------------------------------------- 4. bad CLI input


@pytest.fixture
def bad_inputs(tmp_path, helpers):
    helpers.blob(1).export(tmp_path / "gt.ply")
    helpers.blob(2).export(tmp_path / "pred.ply")
    (tmp_path / "adir").mkdir()
    (tmp_path / "cols.csv").write_text("prediction,groundtruth\npred.ply,gt.ply\n")
    (tmp_path / "binary.csv").write_bytes(b"\xff\xfe\x00\x81garbage\x00")
    (tmp_path / "bad.json").write_text("{not json")
    (tmp_path / "pairs.txt").write_text("pred,gt\npred.ply,gt.ply\n")
    (tmp_path / "ok.csv").write_text("pred,gt\npred.ply,gt.ply\n")
    (tmp_path / "afile").write_text("x")
    return tmp_path


OUTS = ["--out", "out.json", "--csv", "out.csv"]
BATCH = ["batch", "--pairs", "ok.csv", "--no-progress"]

BAD_CLI = [
    ("no command", [], "required"),
    ("unknown option", ["iou", "pred.ply", "gt.ply", "--bogus"], "unrecognized"),
    ("iou missing file", ["iou", "missing.ply", "gt.ply"], "does not exist"),
    ("iou directory", ["iou", "adir", "gt.ply"], "is a directory"),
    ("iou one mesh", ["iou", "gt.ply"], "at least two meshes"),
    ("iou resolution 0", ["iou", "pred.ply", "gt.ply", "--resolution", "0"], "--resolution"),
    ("iou resolution text", ["iou", "pred.ply", "gt.ply", "--resolution", "abc"], "not an integer"),
    ("iou bad protocol", ["iou", "pred.ply", "gt.ply", "--protocol", "nope"], "invalid choice"),
    ("fscore threshold -1", ["fscore", "pred.ply", "gt.ply", "--threshold", "-1"], "--threshold"),
    ("fscore threshold nan", ["fscore", "pred.ply", "gt.ply", "--threshold", "nan"], "--threshold"),
    ("chamfer samples 0", ["chamfer", "pred.ply", "gt.ply", "--samples", "0"], "--samples"),
    ("check missing", ["check", "missing.obj"], "does not exist"),
    ("check directory", ["check", "adir"], "is a directory"),
    ("pairs missing", ["batch", "--pairs", "missing.csv", *OUTS], "does not exist"),
    ("pairs directory", ["batch", "--pairs", "adir", *OUTS], "is a directory"),
    ("pairs not text", ["batch", "--pairs", "binary.csv", *OUTS], "not UTF-8"),
    ("pairs bad columns", ["batch", "--pairs", "cols.csv", *OUTS], "missing column"),
    ("pairs bad json", ["batch", "--pairs", "bad.json", *OUTS], "not valid JSON"),
    ("pairs unknown type", ["batch", "--pairs", "pairs.txt", *OUTS], "use .csv or .json"),
    ("jobs negative", [*BATCH, "--jobs", "-2", *OUTS], "--jobs"),
    ("jobs zero", [*BATCH, "--jobs", "0", *OUTS], "--jobs"),
    ("batch resolution negative", [*BATCH, "--resolution", "-5", *OUTS], "--resolution"),
    ("unknown metric", [*BATCH, "--metrics", "voxel_iou,nope", *OUTS], "unknown metric"),
    ("out in missing folder", [*BATCH, "--out", "nofolder/out.json", "--csv", "out.csv"], "does not exist"),
    ("out is a folder", [*BATCH, "--out", "adir", "--csv", "out.csv"], "is a folder"),
    ("out equals csv", [*BATCH, "--out", "out.json", "--csv", "out.json"], "same file"),
    ("cache dir is a file", [*BATCH, "--cache-dir", "afile", *OUTS], "--cache-dir"),
    ("pred-dir without gt-dir", ["batch", "--pred-dir", "adir", *OUTS], "--gt-dir"),
    ("pred-dir missing", ["batch", "--pred-dir", "nope", "--gt-dir", "adir", *OUTS], "does not exist"),
    ("pairs and gt-dir", ["batch", "--pairs", "ok.csv", "--gt-dir", "adir", *OUTS], "--gt-dir"),
]


@pytest.mark.parametrize("case,argv,words", BAD_CLI, ids=[c[0] for c in BAD_CLI])
def test_bad_cli_input_is_one_line_exit_2_and_writes_nothing(bad_inputs, monkeypatch, capsys, case, argv, words):
    monkeypatch.chdir(bad_inputs)
    before = _files(bad_inputs)
    assert main(argv) == 2, case
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err and words in err, err
    assert _files(bad_inputs) == before  # no output (and no temporary) file created


def test_bad_cli_input_through_the_console_script(bad_inputs):
    for argv in (["batch", "--pairs", "ok.csv", "--jobs", "-1", *OUTS], ["iou", "missing.ply", "gt.ply"]):
        proc = subprocess.run(CLI + argv, cwd=bad_inputs, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1 and "Traceback" not in proc.stderr
    assert not (bad_inputs / "out.json").exists() and not (bad_inputs / "out.csv").exists()


def test_results_are_written_atomically(tmp_path):
    result = BatchResult([{"id": "a", "status": "ok", "voxel_iou": 0.5, "warnings": []}], {"pairs": 1})
    with pytest.raises(OSError):
        write_results(result, tmp_path / "r.json", tmp_path / "missing" / "r.csv")
    assert list(tmp_path.iterdir()) == []  # neither the JSON nor a temporary file is left
    (tmp_path / "r.json").write_text("old")
    write_results(result, tmp_path / "r.json", tmp_path / "r.csv")
    assert json.loads((tmp_path / "r.json").read_text())["summary"] == {"pairs": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv", "r.json"]
