"""Bring your own meshes: a folder of posed meshes becomes a dataset."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from cerberus_core.bodies.body import FILL
from cerberus_core.bodies.folder import FolderSource
from cerberus_core.bodies.primitives import PrimitiveBodySource, sample_subjects
from cerberus_core.datasets.format import DatasetError, verify_dataset
from cerberus_core.datasets.generate import generate
from cerberus_core.datasets.plan import preset_config
from cerberus_core.datasets.readers import QuadrupletDataset, ViewDataset


def _export(path, vertices, faces):
    trimesh.Trimesh(vertices, faces, process=False).export(path)


@pytest.fixture(scope="module")
def mesh_folder(tmp_path_factory):
    """3 subjects in 3 formats, in 'metres' with arbitrary offsets; labels per pose, per subject, and
    a canonical pose for the test subject."""
    root = tmp_path_factory.mktemp("meshes")
    src = PrimitiveBodySource()
    (root / "part_names.txt").write_text("\n".join(src.part_names) + "\n")
    layout = {"alice": ("obj", "pose"), "bob": ("ply", "subject"), "carol": ("off", "pose")}
    for (name, (ext, labels)), subject in zip(layout.items(), sample_subjects(3, 5, "train"), strict=True):
        folder = root / name
        folder.mkdir()
        bodies = src.posed_bodies(subject, [1, 2, 3, 0])
        for k, b in enumerate(bodies):
            stem = "canonical" if (name == "carol" and b.pose_id == 0) else f"frame{k * 5}"
            _export(folder / f"{stem}.{ext}", b.vertices * 1.8 + [10.0, 0.3 * k, -2.0], b.faces)
            if labels == "pose":
                np.save(folder / f"{stem}.parts.npy", b.vertex_parts.astype(np.int64))
        if labels == "subject":
            np.save(folder / "parts.npy", bodies[0].vertex_parts)
    (root / "carol" / "README.txt").write_text("ignored")
    return root


def test_folder_source_normalises_each_subject_once(mesh_folder):
    src = FolderSource(mesh_folder)
    assert src.part_names[:2] == ["head", "torso"]
    assert [s.name for s in src.subjects("train", None, 0)] == ["alice", "bob"]
    assert [s.name for s in src.subjects("test", None, 0)] == ["carol"]  # the last 30 %, at least one
    assert src.subjects("train", None, 0)[0].info["poses"] == ["frame0", "frame5", "frame10", "frame15"]
    who = {s.name: s for split in ("train", "test") for s in src.subjects(split, None, 0)}
    assert src.canonical_pose(who["carol"]) == 0 and src.canonical_pose(who["alice"]) is None
    bodies = src.bodies(who["alice"], [0, 1, 2, 3])
    extents = [float((b.vertices.max(0) - b.vertices.min(0)).max()) for b in bodies]
    assert max(extents) == pytest.approx(FILL, abs=1e-5)  # one scale, the largest pose fills FILL
    for b in bodies:
        np.testing.assert_allclose(0.5 * (b.vertices.max(0) + b.vertices.min(0)), 0.0, atol=1e-6)  # centred
    raw = [trimesh.load(mesh_folder / "alice" / f"frame{k}.obj", process=False).vertices for k in (0, 5)]
    ratio = (bodies[1].vertices[7] - bodies[1].vertices[3]) / (raw[1][7] - raw[1][3])
    ratio0 = (bodies[0].vertices[7] - bodies[0].vertices[3]) / (raw[0][7] - raw[0][3])
    np.testing.assert_allclose(ratio, ratio0, rtol=1e-4)  # the same scale for every pose
    labels = np.load(mesh_folder / "alice" / "frame5.parts.npy")
    np.testing.assert_array_equal(bodies[1].vertex_parts, labels)
    bob = src.bodies(who["bob"], [2])[0]
    np.testing.assert_array_equal(bob.vertex_parts, np.load(mesh_folder / "bob" / "parts.npy"))


@pytest.mark.parametrize("preset", ["pairs", "grid"])
def test_folder_dataset_end_to_end(mesh_folder, tmp_path, preset):
    options = {"root": str(mesh_folder), "test_subjects": ["carol"]}
    cfg = preset_config("folder", preset, image_size=32)
    generate(cfg, tmp_path / "ds", source_options=options, progress=False, log=lambda s: None)
    assert verify_dataset(tmp_path / "ds")[1] == []
    quads = QuadrupletDataset(tmp_path / "ds")
    names = {quads.subject_names[int(quads[i]["subject"])] for i in range(len(quads))}
    assert names == {"alice", "bob"}
    test = ViewDataset(tmp_path / "ds")
    assert {test.subject_names[s] for s in test.subjects()} == {"carol"}
    canon = test.canonical_indices()
    if preset == "pairs":
        assert len(next(iter(canon.values()))) == 4
    body = test.gt_mesh(0)
    folder = FolderSource(mesh_folder, test_subjects=["carol"])
    direct = folder.bodies(folder.subjects("test", None, 0)[0], [body.pose_id])[0]
    np.testing.assert_array_equal(body.vertices, direct.vertices)
    np.testing.assert_array_equal(body.vertex_parts, direct.vertex_parts)


def _copy(src, dst):
    import shutil

    shutil.copytree(src, dst)
    return dst


def test_unreadable_mesh_is_named(mesh_folder, tmp_path):
    root = _copy(mesh_folder, tmp_path / "m")
    (root / "bob" / "frame20.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\ngarbage")
    with pytest.raises(DatasetError, match=r"bob/frame20\.ply"):
        FolderSource(root)
    (root / "bob" / "frame20.ply").unlink()
    (root / "alice" / "frame20.obj").write_text("this is not a mesh\n")
    with pytest.raises(DatasetError, match=r"alice/frame20\.obj: no triangles"):
        FolderSource(root)


def test_bad_labels_and_layouts_are_named(mesh_folder, tmp_path):
    root = _copy(mesh_folder, tmp_path / "m")
    np.save(root / "alice" / "frame5.parts.npy", np.zeros(3, np.int64))
    with pytest.raises(DatasetError, match=r"frame5\.parts\.npy: part labels must be"):
        FolderSource(root)
    (root / "alice" / "frame5.parts.npy").unlink()
    with pytest.raises(DatasetError, match=r"frame5\.obj: no part labels"):
        FolderSource(root)
    root2 = _copy(mesh_folder, tmp_path / "m2")
    (root2 / "alice" / "frame5.ply").write_bytes((root2 / "bob" / "frame5.ply").read_bytes())
    with pytest.raises(DatasetError, match="several formats"):
        FolderSource(root2)
    with pytest.raises(DatasetError, match="test subject.*dave"):
        FolderSource(mesh_folder, test_subjects=["dave"])
    with pytest.raises(DatasetError, match="no subject folders"):
        FolderSource(tmp_path)
