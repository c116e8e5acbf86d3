"""Mesh files read strictly (cerberus_metrics.filecheck, issue 11): what the loader used to repair silently
is an error naming the file and the place; valid OBJ index forms still load."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from cerberus_metrics import MeshInputError, inspect_mesh, voxel_iou
from cerberus_metrics.cli import main
from cerberus_metrics.filecheck import FileDefect, scan_mesh_file

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


def test_an_stl_neither_ascii_nor_a_whole_binary_is_refused_before_pymeshlab(tmp_path):
    """Issue 34 campaign: a binary STL header claiming 10^9 triangles over 50 bytes of data made pymeshlab run for
    minutes (the check's 60 s timeout); it is now one line naming the claim and the file's size."""
    path = tmp_path / "cut.stl"
    path.write_bytes(b"\0" * 80 + struct.pack("<I", 10**9) + b"\0" * 50)
    with pytest.raises(FileDefect, match=r"neither an ASCII STL .* nor a whole binary STL \(its header claims "
                                         r"1000000000 triangles \(50000000084 bytes\), the file has 134 bytes\)"):
        scan_mesh_file(path)
    path.write_bytes(b"\0" * 20)
    with pytest.raises(FileDefect, match="shorter than a header"):
        scan_mesh_file(path)
