"""The on-disk format: shard round trip, checksums, path safety, verification (the manifest's own
tests are in test_manifest.py)."""
from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pytest

from cerberus_core.bodies.body import PosedBody
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.format import (
    VIEW_DTYPE,
    DatasetError,
    atomic_save_npy,
    pack_meshes,
    resolve_inside,
    unpack_mesh,
    write_shard,
)
from cerberus_core.datasets.manifest import MANIFEST


def _body(rng, n_verts, n_faces, pose, faces=None, parts=None):
    faces = rng.integers(0, n_verts, (n_faces, 3)) if faces is None else faces
    parts = rng.integers(0, 4, n_verts) if parts is None else parts
    return PosedBody(rng.uniform(-0.4, 0.4, (n_verts, 3)), faces, parts, ["a", "b", "c", "d"], "s", pose,
                     meta={"pose_params": rng.normal(size=5)})


def test_pack_meshes_round_trip_and_topology_dedup():
    rng = np.random.default_rng(0)
    shared_faces, shared_parts = rng.integers(0, 20, (30, 3)), rng.integers(0, 4, 20)
    bodies = [_body(rng, 20, 30, 1, shared_faces, shared_parts), _body(rng, 20, 30, 2, shared_faces, shared_parts),
              _body(rng, 11, 7, 3)]
    verts, arrays = pack_meshes(bodies, [4, 4, 5])
    assert len(arrays["face_offsets"]) == 3  # two topologies: the shared one stored once
    assert arrays["topology"].tolist() == [0, 0, 1]
    assert arrays["subject"].tolist() == [4, 4, 5] and arrays["pose"].tolist() == [1, 2, 3]
    for i, b in enumerate(bodies):
        v, f, p = unpack_mesh(verts, arrays, i)
        np.testing.assert_array_equal(v, b.vertices)
        np.testing.assert_array_equal(f, b.faces)
        np.testing.assert_array_equal(p, b.vertex_parts)
        np.testing.assert_allclose(arrays["pose_params"][i], b.meta["pose_params"], rtol=1e-6)


def _write_example(root):
    rng = np.random.default_rng(1)
    images = rng.integers(0, 256, (8, 3, 16, 16), dtype=np.uint8)
    views = np.zeros(8, VIEW_DTYPE)
    views["pose"] = np.arange(8) // 2
    views["azimuth"] = rng.uniform(0, 360, 8)
    views["mesh"] = np.arange(8) // 2
    quads = np.array([[0, 1, 2, 3], [4, 5, 6, 7]])
    meshes = pack_meshes([_body(rng, 10, 12, p) for p in range(4)], [0] * 4)
    return images, views, quads, write_shard(root, "train", 0, images, views, quads, meshes)


def test_write_shard_round_trip_and_records(tmp_path):
    images, views, quads, rec = _write_example(tmp_path)
    assert (rec.index, rec.name, rec.images, rec.quadruplets, rec.meshes) == (0, "shard-00000", 8, 2, 4)
    assert set(rec.files) == {"images", "views", "quads", "vertices", "meshes"}
    for f in rec.files.values():
        assert not f.path.startswith("/") and len(f.sha256) == 64
        assert (tmp_path / f.path).stat().st_size == f.bytes
    assert rec.files["images"].shape == (8, 3, 16, 16) and rec.files["images"].dtype == "|u1"
    assert rec.files["meshes"].shape is None  # an .npz: no array header to record
    back = np.load(tmp_path / rec.files["images"].path, mmap_mode="r")
    assert isinstance(back, np.memmap)
    np.testing.assert_array_equal(back, images)
    np.testing.assert_array_equal(np.load(tmp_path / rec.files["views"].path), views)
    np.testing.assert_array_equal(np.load(tmp_path / rec.files["quads"].path), quads)
    assert not list(tmp_path.rglob("*.tmp"))  # no temporaries left behind


def test_write_shard_rejects_bad_quads(tmp_path):
    images = np.zeros((4, 3, 8, 8), np.uint8)
    with pytest.raises(ValueError, match="quadruplet indices"):
        write_shard(tmp_path, "train", 0, images, np.zeros(4, VIEW_DTYPE), [[0, 1, 2, 4]], None)


def test_atomic_write_failure_leaves_nothing(tmp_path):
    target = tmp_path / "x.npy"
    with pytest.raises(ValueError):
        atomic_save_npy(target, np.array([object()], dtype=object))  # pickles are refused mid-write
    assert not target.exists() and not list(tmp_path.iterdir())


def test_resolve_inside_refuses_escapes(tmp_path):
    (tmp_path / "a").mkdir()
    assert resolve_inside(tmp_path, "a/b.npy") == tmp_path / "a" / "b.npy"
    for bad in ("../x.npy", "/etc/passwd", "a/../../x.npy", ""):
        with pytest.raises(DatasetError, match="escapes"):
            resolve_inside(tmp_path, bad)
    outside = tmp_path.parent / f"{tmp_path.name}-outside"
    outside.mkdir()
    (tmp_path / "link").symlink_to(outside)
    with pytest.raises(DatasetError, match="outside the dataset folder"):
        resolve_inside(tmp_path, "link/x.npy")


def test_path_escape_in_manifest_is_reported(pairs_dataset, tmp_path):
    ds = tmp_path / "ds"
    shutil.copytree(pairs_dataset, ds)
    m = json.loads((ds / MANIFEST).read_text())
    m["splits"]["train"]["shards"][0]["files"]["images"]["path"] = "../../etc/passwd"
    (ds / MANIFEST).write_text(json.dumps(m))
    problems = Dataset.open(ds).verify()
    assert any("escapes the dataset folder" in p for p in problems)

    with pytest.raises(DatasetError, match="escapes the dataset folder"):
        Dataset.open(ds).quadruplets()


def test_corruption_is_detected(pairs_dataset, tmp_path):
    ds = tmp_path / "ds"
    shutil.copytree(pairs_dataset, ds)
    dataset = Dataset.open(ds)
    manifest, problems = dataset.manifest, dataset.verify()
    assert problems == [] and manifest.complete
    shard = manifest.split("train").shards[1]
    images = ds / shard.files["images"].path
    data = bytearray(images.read_bytes())
    data[-5] ^= 0xFF  # one flipped pixel byte: same size, wrong sha256
    images.write_bytes(bytes(data))
    problems = Dataset.open(ds).verify()
    assert len(problems) == 1 and str(images) in problems[0] and "sha256" in problems[0]
    quick = Dataset.open(ds).verify(checksums=False)
    assert quick == []  # sizes alone cannot see a flipped byte
    views = ds / shard.files["views"].path
    views.write_bytes(views.read_bytes()[:-3])  # truncated
    problems = Dataset.open(ds).verify(checksums=False)
    assert any(str(views) in p and "bytes" in p for p in problems)
    (ds / shard.files["quads"].path).unlink()
    problems = Dataset.open(ds).verify(checksums=False)
    assert any("missing" in p for p in problems)


def test_data_check_flags_views_that_render_empty(pairs_dataset, tmp_path, capsys):
    """A view with no body on the background (e.g. a pose shrunk to nothing by a unit mix-up) is a
    problem of `cerberus data check`, naming the file, subject, pose and view; sound views are not."""
    from cerberus_core.cli import main
    from cerberus_core.datasets.format import sha256_file

    root = tmp_path / "ds"
    shutil.copytree(pairs_dataset, root)
    assert Dataset.open(root).verify() == []
    manifest = json.loads((root / MANIFEST).read_text())
    shard = manifest["splits"]["test"]["shards"][0]
    path = resolve_inside(root, shard["files"]["images"]["path"])
    images = np.load(path)
    views = np.load(resolve_inside(root, shard["files"]["views"]["path"]))
    background = np.round(np.asarray(manifest["scene"]["background"]) * 255).astype(np.uint8)
    images[2] = background[:, None, None]  # the view as rendered when the body is out of the frame
    images[3] = background[:, None, None]
    np.save(path, images)
    shard["files"]["images"]["sha256"] = sha256_file(path)  # a consistent dataset: only the views are wrong
    (root / MANIFEST).write_text(json.dumps(manifest))
    problems = Dataset.open(root).verify()
    assert len(problems) == 1
    subject = manifest["subjects"][int(views[2]["subject"])]["name"]
    assert str(path) in problems[0] and "2 of" in problems[0] and "render empty" in problems[0]
    assert f"image 2: subject {subject} pose {int(views[2]['pose'])}" in problems[0]
    assert "0 foreground pixels" in problems[0] and "regenerate" in problems[0]
    assert main(["data", "check", str(root)]) == 1
    out = capsys.readouterr()
    assert "render empty" in out.err and "1 problem(s)" in out.out


def _rewritten(pairs_dataset, tmp_path, role: str, change) -> tuple:
    """A copy of the dataset whose first training shard's ``role`` array is replaced by ``change(array)`` (its size and
    sha256 recorded anew, so only the numbers contradict the manifest)."""
    from cerberus_core.datasets.format import sha256_file

    root = tmp_path / "ds"
    shutil.copytree(pairs_dataset, root)
    manifest = json.loads((root / MANIFEST).read_text())
    record = manifest["splits"]["train"]["shards"][0]["files"][role]
    path = resolve_inside(root, record["path"])
    if path.suffix == ".npz":
        with np.load(path) as z:
            arrays = change({k: z[k] for k in z.files})
        np.savez(path, **arrays)  # allow_pickle is numpy's default when saving: an object array is stored
    else:
        array = change(np.load(path))
        np.save(path, array)
        record["shape"], record["dtype"] = list(array.shape), array.dtype.str
    record["bytes"], record["sha256"] = path.stat().st_size, sha256_file(path)
    (root / MANIFEST).write_text(json.dumps(manifest))
    return root, path


def _subject(views):
    views = views.copy()
    views["subject"][1] = 99
    return views


def _mesh_index(views):
    views = views.copy()
    views["mesh"][0] = 1000
    return views


@pytest.mark.parametrize(("role", "change", "expected"), [
    ("views", _subject, "views name subjects 0..99, the manifest has"),
    ("views", _mesh_index, "views name meshes"),
    ("quads", lambda q: q + 1000, "quadruplets index images"),
    ("images", lambda a: a[:-1], "the manifest says uint8["),
    ("meshes", lambda z: z | {"pose": np.array([object()] * len(z["pose"]), dtype=object)},
     "meshes.npz holds an array numpy cannot read without pickle"),
    ("meshes", lambda z: {k: v for k, v in z.items() if k != "faces"}, "meshes.npz lacks the array 'faces'"),
    ("meshes", lambda z: z | {"vertex_offsets": z["vertex_offsets"] + 7}, "vertex_offsets run over"),
    ("meshes", lambda z: z | {"vertex_parts": z["vertex_parts"] + 100}, "part labels index the manifest's"),
], ids=["subject", "mesh-index", "quads", "images-count", "npz-object", "npz-missing", "npz-offsets", "part-labels"])
def test_data_check_verifies_the_manifest_numbers_against_the_arrays(pairs_dataset, tmp_path, capsys, role, change,
                                                                     expected):
    """Issue 34: a shard whose files are whole (sizes and checksums agree) but whose arrays contradict the
    manifest's numbers is a problem of `cerberus data check` (exit 1) and a DatasetError of every reader; no
    pickle is ever run (the object array is refused unread)."""
    from cerberus_core.cli import main

    root, path = _rewritten(pairs_dataset, tmp_path, role, change)
    before = {p: p.read_bytes() for p in root.rglob("*") if p.is_file()}
    problems = Dataset.open(root).verify(checksums=False)
    assert len(problems) == 1 and expected in problems[0] and "train/shard-00000" in problems[0], problems
    assert main(["data", "check", "--quick", str(root)]) == 1
    out = capsys.readouterr()
    assert expected in out.err and out.out.endswith("1 problem(s)\n")
    with pytest.raises(DatasetError, match="regenerate"):
        Dataset.open(root).quadruplets()
    assert {p: p.read_bytes() for p in root.rglob("*") if p.is_file()} == before


def test_data_check_says_what_stands_where_a_shard_file_should_be_and_escapes_hostile_names(pairs_dataset, tmp_path):
    """Issue 34 campaign: a folder or FIFO in place of a shard file was called "missing", and a shard path holding an
    escape sequence was printed raw by `cerberus data check` (a terminal control string)."""
    root = tmp_path / "ds"
    shutil.copytree(pairs_dataset, root)
    manifest = json.loads((root / MANIFEST).read_text())
    files = manifest["splits"]["train"]["shards"][0]["files"]
    images, views = root / files["images"]["path"], root / files["views"]["path"]
    images.unlink()
    images.mkdir()
    views.unlink()
    os.mkfifo(views)
    files["quads"]["path"] = "train/\x1b[31mred.npy"
    (root / MANIFEST).write_text(json.dumps(manifest))
    problems = Dataset.open(root).verify(checksums=False)
    assert any("a folder, not a file (images of shard-00000)" in p for p in problems), problems
    assert any("not a regular file (a FIFO, device or socket) (views of" in p for p in problems), problems
    assert any("\\x1b[31mred.npy: missing" in p for p in problems) and not any("\x1b" in p for p in problems)
