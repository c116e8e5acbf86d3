"""Bring your own meshes: a folder of posed meshes becomes a dataset."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from cerberus_core.bodies.body import FILL
from cerberus_core.bodies.folder import FolderSource
from cerberus_core.bodies.primitives import PrimitiveBodySource, sample_subjects
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.format import DatasetError
from cerberus_core.datasets.manifest import Manifest, SourceRecord
from cerberus_core.datasets.plan import GenerationRequest, preset_config


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
    request = GenerationRequest("folder", preset, {"image_size": 32}, options)
    Dataset.generate(request, tmp_path / "ds", progress=False, log=lambda s: None)
    assert Dataset.open(tmp_path / "ds").verify() == []
    quads = Dataset.open(tmp_path / "ds").quadruplets()
    names = {quads.subject_names[int(quads[i]["subject"])] for i in range(len(quads))}
    assert names == {"alice", "bob"}
    test = Dataset.open(tmp_path / "ds").views()
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


# ------------------------------------------------------------------ up axis, units, degenerate meshes, test-only
def _figures(root, transform=lambda v: v, ext="ply", poses=(1, 2), subjects=2):
    """``subjects`` capsule-figure subjects (``alice``, ``bob``, ...) in +Y-up 'metres', each vertex
    array passed through ``transform`` (float64) before it is written."""
    src = PrimitiveBodySource()
    for name, subject in zip(["alice", "bob", "carol"][:subjects], sample_subjects(subjects, 7, "train"), strict=True):
        (root / name).mkdir(parents=True)
        for b in src.posed_bodies(subject, list(poses)):
            _export(root / name / f"pose{b.pose_id}.{ext}", transform(b.vertices.astype(np.float64) * 1.7), b.faces)
    return root


def _all_bodies(source):
    return [b for split in ("train", "test") for s in source.subjects(split, None, 0)
            for b in source.bodies(s, source.pose_pool(s, split, None))]


@pytest.mark.parametrize("axis", ["+y", "-y", "+z", "-z", "+x", "-x"])
def test_up_axis_rotation_is_proper_and_lifts_the_axis(axis):
    from cerberus_core.bodies.folder import up_axis_rotation

    r = up_axis_rotation(axis)
    unit = np.zeros(3)
    unit["xyz".index(axis[1])] = 1.0 if axis[0] == "+" else -1.0
    np.testing.assert_array_equal(r @ unit, [0.0, 1.0, 0.0])
    assert np.linalg.det(r) == pytest.approx(1.0)  # no mirroring: faces keep their orientation


def test_z_up_meshes_give_the_y_up_bodies_with_up_axis_z(tmp_path):
    # Blender's convention: +Y up becomes +Z up, the front (+Z) becomes -Y: (x, y, z) -> (x, -z, y)
    y_up = FolderSource(_figures(tmp_path / "y"), test_fraction=0.5)
    z_root = _figures(tmp_path / "z", transform=lambda v: np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1))
    z_up = FolderSource(z_root, test_fraction=0.5, up_axis="+z")
    for a, b in zip(_all_bodies(y_up), _all_bodies(z_up), strict=True):
        np.testing.assert_allclose(a.vertices, b.vertices, atol=1e-6)
        np.testing.assert_array_equal(a.faces, b.faces)
    lying = FolderSource(z_root, test_fraction=0.5)  # read as +Y up, the bodies lie on their backs
    assert not np.allclose(_all_bodies(lying)[0].vertices, _all_bodies(y_up)[0].vertices, atol=1e-2)
    assert y_up.describe()["up_axis"] == "+y" and z_up.describe()["up_axis"] == "+z"  # part of the config hash
    assert y_up.up_axis_warning() is None and z_up.up_axis_warning() is None
    hint = lying.up_axis_warning()
    assert "`up_axis=+z`" in hint and "4 of 4 meshes" in hint
    with pytest.raises(ValueError, match="up_axis = 'z': must be one of"):
        FolderSource(z_root, up_axis="z")


def test_generate_warns_about_the_up_axis_and_records_the_choice(tmp_path, capsys):
    import warnings

    from cerberus_core.cli import main

    y_root = _figures(tmp_path / "y")
    z_root = _figures(tmp_path / "z", transform=lambda v: np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1))
    base = ["data", "generate", "--dataset", "folder", "--image-size", "32", "--quiet", "--test-fraction", "0.5"]
    with pytest.warns(UserWarning, match=r"tallest along z.*pass `up_axis=\+z`"):
        assert main([*base, "--source", str(z_root), "--out", str(tmp_path / "d0"), "--dry-run"]) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning fails
        assert main([*base, "--source", str(y_root), "--out", str(tmp_path / "d1"), "--dry-run"]) == 0
        assert main([*base, "--source", str(z_root), "--out", str(tmp_path / "dz"), "--up-axis", "+z"]) == 0
        assert main([*base, "--source", str(y_root), "--out", str(tmp_path / "dy")]) == 0
    manifest = Manifest.read(tmp_path / "dz")
    assert manifest.source.options["up_axis"] == "+z"
    assert manifest.config.source["up_axis"] == "+z"
    z_test, y_test = Dataset.open(tmp_path / "dz").views(), Dataset.open(tmp_path / "dy").views()
    np.testing.assert_allclose(z_test.gt_mesh(0).vertices, y_test.gt_mesh(0).vertices, atol=1e-6)
    capsys.readouterr()
    assert main([*base[:3], "primitives", "--out", str(tmp_path / "p"), "--up-axis", "+z", "--dry-run"]) == 2
    assert "--up-axis +z: not an option of the primitives body source (it takes none)" in capsys.readouterr().err


@pytest.mark.parametrize("scale", [1e6, 1e-6])
def test_meshes_in_huge_or_tiny_units_render_like_metres(tmp_path, scale):
    options = {"test_fraction": 0.5}
    metres = _figures(tmp_path / "m")
    scaled = _figures(tmp_path / "s", transform=lambda v: v * scale + 3.0 * scale)
    for b, ref in zip(_all_bodies(FolderSource(scaled, **options)), _all_bodies(FolderSource(metres, **options)),
                      strict=True):
        np.testing.assert_allclose(b.vertices, ref.vertices, atol=1e-6)
    for root, out in ((metres, "dm"), (scaled, "ds")):
        Dataset.generate(GenerationRequest("folder", "pairs", {"image_size": 32}, {"root": str(root), **options}),
                         tmp_path / out, progress=False, log=lambda s: None)
    a, b = Dataset.open(tmp_path / "dm").views(), Dataset.open(tmp_path / "ds").views()
    for i in range(len(a)):
        body_pixels = float((a[i]["images"] < 0.99).float().mean())
        assert body_pixels > 0.03  # not blank
        assert float((a[i]["images"] - b[i]["images"]).abs().mean()) < 1e-3


def _one_mesh_folder(tmp_path, ext):
    """A folder of one subject with a good pose (``pose1.ply``); returns the path of a second pose to write."""
    (tmp_path / "m" / "alice").mkdir(parents=True)
    good = _figures(tmp_path / "g", poses=(1,), subjects=1)
    path = tmp_path / "m" / "alice" / f"pose9.{ext}"
    (tmp_path / "m" / "alice" / "pose1.ply").write_bytes((good / "alice" / "pose1.ply").read_bytes())
    return path


@pytest.mark.parametrize(("case", "problem"), [
    ("one point", r"pose9\.obj: degenerate mesh: all 4 vertices of its 2 triangles are at one point"),
    ("line", r"pose9\.obj: degenerate mesh: all 2 triangles have zero area"),
    ("no faces", r"pose9\.obj: no triangles found"),
    ("collapsed by float32", r"pose9\.ply: degenerate mesh: all \d+ vertices of its \d+ triangles are at one point"),
])
def test_degenerate_meshes_are_refused_naming_the_file(tmp_path, case, problem):
    path = _one_mesh_folder(tmp_path, ext="ply" if case == "collapsed by float32" else "obj")
    if case == "one point":
        path.write_text("v 1 2 3\nv 1 2 3\nv 1 2 3\nv 1 2 3\nf 1 2 3\nf 2 3 4\n")
    elif case == "line":
        path.write_text("v 0 0 0\nv 1 1 1\nv 2 2 2\nv 3 3 3\nf 1 2 3\nf 2 3 4\n")
    elif case == "no faces":
        path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    else:  # a small body 1e8 units from the origin, in a file that stores float32: every vertex rounds together
        body = PrimitiveBodySource().posed_bodies(sample_subjects(1, 7, "train")[0], [1])[0]
        _export(path, body.vertices.astype(np.float64) + 1e8, body.faces)
    with pytest.raises(DatasetError, match=problem) as err:
        FolderSource(tmp_path / "m")
    assert "\n" not in str(err.value)  # one line: the file, the problem, the fix


def test_a_test_only_folder_dataset_is_generated_and_read_but_not_trained_on(tmp_path, capsys):
    from cerberus_core.cli import main

    root = _figures(tmp_path / "m", poses=(0, 1, 2))
    for subject in ("alice", "bob"):
        (root / subject / "pose0.ply").rename(root / subject / "rest.ply")
    with pytest.raises(DatasetError, match=r"alice: no pose file 'still'.*\['pose1', 'pose2', 'rest'\]"):
        FolderSource(root, test_fraction=1.0, canonical="still")
    source = FolderSource(root, test_fraction=1.0, canonical="rest")
    assert source.subjects("train", None, 0) == [] and len(source.subjects("test", None, 0)) == 2
    assert source.describe()["canonical"] == "rest"
    logs = []
    manifest = Dataset.generate(GenerationRequest("folder", "pairs", {"image_size": 32},
                                                  {"root": str(root), "test_fraction": 1.0, "canonical": "rest"}),
                                tmp_path / "ds",
                                progress=False, log=logs.append).manifest
    assert logs == ["split 'train' has no subject and is left empty"]
    assert manifest.split("train").planned_shards == 0 and Dataset.open(tmp_path / "ds").verify() == []
    test = Dataset.open(tmp_path / "ds").views()
    assert len(test) == 2 * 3 * 4  # 2 poses + the canonical one, 4 views each
    canon = test.canonical_indices()
    assert sorted(len(v) for v in canon.values()) == [4, 4]
    assert all(int(test.records["pose"][i]) == 2 for v in canon.values() for i in v)  # 'rest' sorts last
    with pytest.raises(DatasetError, match=r"split 'train' is empty: the dataset has no train subjects.*cerberus eval"):
        Dataset.open(tmp_path / "ds").quadruplets()
    capsys.readouterr()
    run = tmp_path / "run"
    assert main(["train", "--preset", "tiny", "--set", f"data.root={tmp_path / 'ds'}", "--out", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "split 'train' is empty" in err
    assert not run.exists()  # nothing written
    with pytest.raises(ValueError, match="no split has a subject"):
        Dataset.generate(preset_config("folder", "pairs", image_size=32, splits={"train": preset_config(
            "folder", "pairs").splits["train"]}), tmp_path / "ds2",
            source=FolderSource(root, test_fraction=1.0), progress=False, log=lambda s: None)


@pytest.mark.parametrize("factor, unit", [(1000.0, "millimetres among metres"), (1e-2, "centimetres among metres")])
def test_a_subject_mixing_units_is_refused_with_the_reason(tmp_path, factor, unit):
    """One pose in millimetres among poses in metres used to set the subject's one scale, shrinking the
    other poses 1000x (views that render empty). The folder source refuses it, naming file and factor."""
    root = _figures(tmp_path / "m", poses=(1, 2, 3))
    odd = root / "alice" / "pose2.ply"
    mesh = trimesh.load(odd, process=False)
    _export(odd, np.asarray(mesh.vertices) * factor, mesh.faces)
    with pytest.raises(DatasetError) as info:
        FolderSource(root, test_fraction=0.5)
    msg = str(info.value)
    assert str(odd) in msg and unit in msg and "re-export it" in msg and "\n" not in msg
    assert ("larger" if factor > 1 else "smaller") in msg and "subject 'alice'" in msg
    # Posing alone (the same figure in other poses, same unit) never trips it, nor units across subjects.
    root2 = _figures(tmp_path / "ok", poses=(0, 1, 2, 3), subjects=1)
    carol = root2 / "bob"
    _figures(tmp_path / "tmp", poses=(1, 2), subjects=2)
    (tmp_path / "tmp" / "bob").rename(carol)
    for f in carol.iterdir():
        m = trimesh.load(f, process=False)
        _export(f, np.asarray(m.vertices) * 1000.0, m.faces)  # a whole subject in millimetres is fine
    FolderSource(root2, test_fraction=0.5)


def test_the_empty_test_split_hint_gives_the_right_count(tmp_path):
    """One subject at the default test_fraction 0.3 gives round(0.3 x 1) = 0 test subjects. The hint
    used to blame test_fraction 1, which empties the *train* split instead."""
    root = _figures(tmp_path / "m", poses=(1, 2), subjects=1)
    out = tmp_path / "ds"
    Dataset.generate(GenerationRequest("folder", "pairs", {"image_size": 32}, {"root": str(root), "test_fraction": 0.3}),
                     out, progress=False, log=lambda s: None)
    with pytest.raises(DatasetError) as info:
        Dataset.open(out).views()
    msg = str(info.value)
    assert "split 'test' is empty" in msg and "`test_fraction=0.3` of its 1 subject gives round(0.3 x 1) = 0 test" in msg
    assert "`test_fraction=1` (every subject a test subject" in msg and "made with" not in msg
    hint = SourceRecord("folder", {"test_fraction": 0.0}).empty_split_hint(3, "test", out)
    assert "`test_fraction=0` of its 3 subjects gives 0 (a fraction of 0) test subjects" in hint
    hint = FolderSource.empty_split_hint({"test_fraction": 1.0}, 1, "train", out)
    assert "(its only subject is a test subject, `test_fraction=1`)" in hint


def test_a_source_that_is_a_file_or_missing_is_named(tmp_path):
    """Issue 34 campaign: `--source FILE` said the mesh folder "does not exist"."""
    (tmp_path / "meshes.obj").write_text("v 0 0 0\n")
    with pytest.raises(DatasetError, match=r"meshes.obj is a file, not a folder; pass the folder that holds"):
        FolderSource(tmp_path / "meshes.obj")
    with pytest.raises(DatasetError, match=r"nope does not exist; pass the folder"):
        FolderSource(tmp_path / "nope")
