"""Tests of the anny human body source (cerberus_core.bodies.human).

The first test needing anny builds anny's model cache if this machine has none (about 90 s, once);
later runs load it in well under a second.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cerberus_core.bodies import human_motion
from cerberus_core.bodies.body import FILL, PosedBody
from cerberus_core.bodies.human import (
    CANONICAL_POSE_ID,
    DEFAULT_SUBJECT_COUNTS,
    DOF_LIMITS,
    DOF_NAMES,
    PART_NAMES,
    HumanSubject,
    canonical_pose,
    knee_angle_deg,
    pose_params,
    sample_poses,
    sample_subjects,
)
from cerberus_core.bodies.human_motion import MOTION_POSE_BASE, motion_clip, motion_pose_id

GOLDEN = Path(__file__).parent / "golden_independent_poses.json"

# ---------------------------------------------------------------------------------------------
# No anny needed
# ---------------------------------------------------------------------------------------------


def test_subjects_deterministic_defaults_and_disjoint_splits():
    train, test = sample_subjects(split="train"), sample_subjects(split="test")
    assert len(train) == DEFAULT_SUBJECT_COUNTS["train"] == 5
    assert len(test) == DEFAULT_SUBJECT_COUNTS["test"] == 2
    assert sample_subjects(split="train") == train  # deterministic
    assert sample_subjects(3, 0, "train") == train[:3]  # subject i does not depend on n
    assert not {s.subject_id for s in train} & {s.subject_id for s in test}
    train_shapes = {tuple(sorted(s.phenotype.items())) for s in train}
    assert not train_shapes & {tuple(sorted(s.phenotype.items())) for s in test}
    assert sample_subjects(5, 1, "train") != train  # the seed matters
    for s in train + test:
        assert set(s.phenotype) == {"gender", "age", "muscle", "weight", "height", "proportions"}
        assert all(0.0 <= v <= 1.0 for v in s.phenotype.values())
        assert s.phenotype["age"] >= 0.77  # adults (anny age 0.77 is about 18 years)
    assert {s.phenotype["gender"] > 0.5 for s in test} == {True, False}  # both sexes, even in 2
    with pytest.raises(ValueError, match="unknown split"):
        sample_subjects(2, 0, "holdout")


def test_pose_sampling_deterministic_within_limits_and_varied():
    a = sample_poses(np.random.default_rng(5), 200)
    b = sample_poses(np.random.default_rng(5), 200)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (200, len(DOF_NAMES))
    assert (a >= DOF_LIMITS[:, 0]).all() and (a <= DOF_LIMITS[:, 1]).all()
    assert ((canonical_pose() >= DOF_LIMITS[:, 0]) & (canonical_pose() <= DOF_LIMITS[:, 1])).all()
    for joint in ("knee_flex.L", "knee_flex.R", "elbow_flex.L", "elbow_flex.R"):
        angle = a[:50, DOF_NAMES.index(joint)]
        assert (angle < 10).sum() >= 5 and (angle > 60).sum() >= 5, joint
    assert a.std(0).min() > 5.0  # every degree of freedom really moves


def test_independent_poses_are_those_of_the_code_before_motion_pairs():
    """Golden check: the ``independent`` mode (ids 1..10^9 - 1) still draws exactly the poses of the
    commit recorded in the JSON file (computed there, with the old code)."""
    golden = json.loads(GOLDEN.read_text())
    subject = sample_subjects(1, 0, "train")[0]
    assert (subject.subject_id, subject.pose_seed) == (golden["subject"], golden["pose_seed"])
    assert golden["dof_names"] == DOF_NAMES
    np.testing.assert_array_equal(pose_params(subject, [0, 1, 2, 3, 4]), golden["pose_params_ids_0_4"])
    np.testing.assert_array_equal(pose_params(subject, [1, 2], attempt=1), golden["pose_params_ids_1_2_attempt_1"])
    np.testing.assert_array_equal(sample_poses(np.random.default_rng(7), 3), golden["sample_poses_rng7_n3"])


def test_motion_pose_ids_are_deterministic_and_chunk_independent():
    subject = sample_subjects(1, 0, "train")[0]
    ids = [motion_pose_id(c, f) for c in (0, 1, 7) for f in (0, 1)]
    assert ids[:2] == [MOTION_POSE_BASE, MOTION_POSE_BASE + 1]
    all_at_once = pose_params(subject, ids)
    np.testing.assert_array_equal(all_at_once, pose_params(subject, ids))
    for i, pid in enumerate(ids):  # one id at a time, in another order: the same angles
        np.testing.assert_array_equal(pose_params(subject, [pid])[0], all_at_once[i])
    np.testing.assert_array_equal(all_at_once[0:2], motion_clip(np.random.default_rng([subject.pose_seed,
                                                                                          MOTION_POSE_BASE]))[1])
    other = sample_subjects(2, 0, "train")[1]
    assert not np.allclose(pose_params(other, ids), all_at_once)  # each subject has its own clips
    redraw = pose_params(subject, ids[:2], attempt=1)
    assert not np.allclose(redraw, all_at_once[:2]) and np.abs(redraw[0] - redraw[1]).mean() < 15
    assert human_motion.clip_frame(ids[5]) == (7, 1) and human_motion.clip_key(ids[5]) == ids[4]
    with pytest.raises(ValueError, match="frames 0 and 1"):
        motion_pose_id(0, 2)


# ---------------------------------------------------------------------------------------------
# anny
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def source():
    pytest.importorskip("anny")
    from cerberus_core.bodies.human import HumanBodySource

    return HumanBodySource()


@pytest.fixture(scope="module")
def subject():
    return sample_subjects(split="train")[0]


@pytest.fixture(scope="module")
def canonical(source, subject) -> PosedBody:
    return source.posed_bodies(subject, [CANONICAL_POSE_ID])[0]


def test_mesh_is_closed_triangle_mesh(source, canonical):
    trimesh = pytest.importorskip("trimesh")
    v, f = canonical.vertices, canonical.faces
    assert f.dtype == np.int64 and f.shape[1] == 3 and 10_000 <= len(f) <= 30_000
    assert f.min() == 0 and f.max() == len(v) - 1
    assert len(np.unique(f)) == len(v)  # no unreferenced vertex
    assert (np.sort(f, 1)[:, :2] != np.sort(f, 1)[:, 1:]).all()  # no degenerate index triple
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume > 0  # outward (counter-clockwise) orientation
    assert len(mesh.split(only_watertight=False)) == 1  # eyes and tongue removed
    assert canonical.part_names == PART_NAMES == source.part_names


def test_parts_cover_and_sit_where_expected(canonical):
    parts, v = canonical.vertex_parts, canonical.vertices
    assert parts.shape == (len(v),) and parts.dtype == np.int16
    assert set(np.unique(parts)) == set(range(len(PART_NAMES)))
    c = {name: v[parts == i].mean(0) for i, name in enumerate(PART_NAMES)}
    assert max(c, key=lambda k: c[k][1]) == "head"
    assert c["head"][1] > c["neck"][1] > c["torso"][1] > c["pelvis"][1] > c["thigh.L"][1] > c["shin.L"][1]
    for part in ("upper_arm", "lower_arm", "thigh", "shin"):
        assert c[f"{part}.L"][0] > 0.02 and c[f"{part}.R"][0] < -0.02, part  # body's left at +X
    assert abs(c["upper_arm.L"][0]) < abs(c["lower_arm.L"][0])  # arms slightly apart, hands outside


def test_canonical_upright_facing_plus_z(canonical):
    v = canonical.vertices
    extent = v.max(0) - v.min(0)
    assert np.argmax(extent) == 1  # tallest along +Y
    joints = dict(zip(canonical.meta["joint_names"], canonical.meta["joints"], strict=True))
    assert joints["head"][1] > joints["root"][1] > joints["foot.L"][1]
    soles = v[v[:, 1] < v[:, 1].min() + 0.02]
    toes = soles[:, 2].max()
    assert toes > max(joints["foot.L"][2], joints["foot.R"][2]) + 0.02  # feet point to +Z


def _check_in_cube(source, subj, ids):
    bodies = source.posed_bodies(subj, ids)
    scale = source.subject_scale(subj)
    for b in bodies:
        assert np.abs(b.vertices).max() <= 0.5
        assert b.meta["scale"] == scale and b.subject == subj.subject_id
        assert np.allclose(0.5 * (b.vertices.max(0) + b.vertices.min(0)), 0.0, atol=1e-5)  # centred
    return [float((b.vertices.max(0) - b.vertices.min(0)).max()) for b in bodies]


def test_unit_cube_and_shared_scale(source):
    for subj in (sample_subjects(split="train")[0], sample_subjects(split="test")[0]):
        extents = _check_in_cube(source, subj, list(range(16)))
        assert 0.6 < max(extents) <= 1.0 and extents[0] <= FILL + 1e-5  # extents[0]: canonical


@pytest.mark.slow
def test_unit_cube_many_poses_all_subjects(source):
    for subj in sample_subjects(split="train") + sample_subjects(split="test"):
        _check_in_cube(source, subj, list(range(1, 101)))
        _check_in_cube(source, subj, [motion_pose_id(c, f) for c in range(50) for f in (0, 1)])


def test_determinism_and_chunking(source, subject):
    first = source.posed_bodies(subject, [0, 1, 2, 3, 4])
    again = source.posed_bodies(subject, [0, 1, 2, 3, 4])
    chunk = source.posed_bodies(subject, [3, 4])
    for x, y in zip(first, again, strict=True):
        np.testing.assert_array_equal(x.vertices, y.vertices)
    for x, y in zip(first[3:], chunk, strict=True):
        assert x.pose_id == y.pose_id
        np.testing.assert_allclose(x.vertices, y.vertices, atol=1e-6)


def test_poses_articulate(source, subject):
    bodies = source.posed_bodies(subject, list(range(1, 51)))
    joints = np.stack([b.meta["joints"] for b in bodies])
    knees = np.concatenate([knee_angle_deg(joints, "L"), knee_angle_deg(joints, "R")])
    assert (knees < 15).sum() >= 10 and (knees > 60).sum() >= 10
    v = np.stack([b.vertices for b in bodies])
    # Poses differ far more than numerical noise: mean vertex displacement between pose pairs.
    assert np.linalg.norm(v[1:] - v[:-1], axis=-1).mean() > 0.03
    assert not np.allclose(bodies[0].meta["pose_params"], bodies[1].meta["pose_params"])


def test_subjects_differ_in_shape(source):
    subjects = sample_subjects(split="train") + sample_subjects(split="test")
    canon = []
    for s in subjects:  # raw canonical meshes (metres), each scaled to unit height
        v = source.posed_vertices(s, canonical_pose()[None])[0][0]
        canon.append((v - v.mean(0)) / np.ptp(v[:, 1]))
    for i in range(len(canon)):
        for j in range(i + 1, len(canon)):
            diff = np.abs(canon[i] - canon[j])
            assert diff.mean() > 5e-4 and diff.max() > 3e-3  # same mesh, different body shapes


def test_oversized_sampled_poses_are_redrawn_deterministically(source, subject):
    # Give a copy of the subject a scale so large that exactly its 2 largest poses no longer fit.
    ids = list(range(1, 25))
    extents = np.array([np.ptp(b.vertices, 0).max() for b in source.posed_bodies(subject, ids)])
    limit = np.sort(extents)[-3]  # normalised extent that will just fit
    tight = HumanSubject("tight-" + subject.subject_id, subject.phenotype, subject.split, subject.pose_seed)
    key = (tight.subject_id, tuple(sorted(tight.phenotype.items())))
    source._scale_cache[key] = source.subject_scale(subject) / (limit + 1e-6)
    bodies = source.posed_bodies(tight, ids)
    redrawn = [i for i, b in enumerate(bodies) if b.meta["redraws"] > 0]
    assert sorted(redrawn) == sorted(np.argsort(extents)[-2:].tolist())
    assert all(np.abs(b.vertices).max() <= 0.5 for b in bodies)
    redrawn_ids = [ids[i] for i in redrawn]
    again = source.posed_bodies(tight, redrawn_ids)  # another chunk, same poses
    for i, b in zip(redrawn, again, strict=True):
        np.testing.assert_array_equal(b.meta["pose_params"], bodies[i].meta["pose_params"])
        np.testing.assert_allclose(b.vertices, bodies[i].vertices, atol=1e-6)
    with pytest.raises(ValueError, match="reaches"):  # explicit angles are never altered
        source.pose(tight, source.pose_params(tight, redrawn_ids), redrawn_ids)


def test_motion_pairs_move_the_body_less_and_chunk_like_sampled_poses(source, subject):
    ids = [motion_pose_id(c, f) for c in range(8) for f in (0, 1)]
    motion = source.posed_bodies(subject, ids)
    independent = source.posed_bodies(subject, list(range(1, 17)))

    def displacement(bodies):  # mean vertex distance within each pair (a, b), normalised units
        return np.mean([np.linalg.norm(a.vertices - b.vertices, axis=1).mean()
                        for a, b in zip(bodies[0::2], bodies[1::2], strict=True)])

    assert displacement(motion) < 0.5 * displacement(independent)
    assert all(np.abs(b.vertices).max() <= 0.5 for b in motion)
    for pid, b in zip(ids, motion, strict=True):
        assert b.pose_id == pid
        np.testing.assert_array_equal(b.meta["pose_params"], pose_params(subject, [pid])[0])
    alone = source.posed_bodies(subject, [ids[3]])[0]  # frame b without its frame a
    np.testing.assert_allclose(alone.vertices, motion[3].vertices, atol=1e-6)


def test_a_motion_clip_is_redrawn_as_a_whole(source, subject):
    # Give a copy of the subject a scale at which exactly one frame of the largest clip no longer fits.
    ids = [motion_pose_id(c, f) for c in range(6) for f in (0, 1)]
    extents = np.array([np.ptp(b.vertices, 0).max() for b in source.posed_bodies(subject, ids)])
    largest = int(np.argmax(extents))
    partner = largest ^ 1  # the other frame of that clip
    limit = max(np.sort(extents)[-2], extents[partner])
    assert extents[largest] > limit  # one frame is strictly the largest (for this subject and clip)
    tight = HumanSubject("tight-motion-" + subject.subject_id, subject.phenotype, subject.split, subject.pose_seed)
    key = (tight.subject_id, tuple(sorted(tight.phenotype.items())))
    source._scale_cache[key] = source.subject_scale(subject) / (limit + 1e-6)
    bodies = source.posed_bodies(tight, ids)
    redrawn = sorted(i for i, b in enumerate(bodies) if b.meta["redraws"] > 0)
    assert redrawn == sorted([largest, partner])  # both frames, though only one did not fit
    assert all(np.abs(b.vertices).max() <= 0.5 for b in bodies)
    for i in redrawn:
        attempt = bodies[i].meta["redraws"]
        np.testing.assert_array_equal(bodies[i].meta["pose_params"], pose_params(tight, [ids[i]], attempt)[0])
    assert bodies[largest].meta["redraws"] == bodies[partner].meta["redraws"]
    alone = source.posed_bodies(tight, [ids[partner]])[0]  # the partner alone: the same redraw
    np.testing.assert_array_equal(alone.meta["pose_params"], bodies[partner].meta["pose_params"])


def test_bad_input_is_rejected(source, subject):
    with pytest.raises(ValueError, match="joint angles"):
        source.pose(subject, np.zeros((2, 3)), [0, 1])
    with pytest.raises(ValueError, match="one pose id per pose"):
        source.pose(subject, np.zeros((2, len(DOF_NAMES))), [0])
    with pytest.raises(ValueError, match=">= 0"):
        source.pose_params(subject, [-1])


def test_loading_the_body_model_prints_nothing():
    """anny skins with Warp; its banner and the CUDA-driver note must not reach the user."""
    import subprocess
    import sys

    code = ("from cerberus_core.bodies.human import HumanBodySource, sample_subjects\n"
            "s = HumanBodySource()\n"
            "(b,) = s.posed_bodies(sample_subjects(1, 0, 'test')[0], [0])\n"
            "assert len(b.vertices) > 1000\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert res.stdout == "" and res.stderr == "", (res.stdout, res.stderr)


def test_the_anny_cache_build_is_announced_and_shows_its_progress(tmp_path, capsys):
    """Issue 34: anny builds its model cache for two minutes without a word. The source says what it builds,
    where and about how long first, then shows the bytes of blend shapes anny has read (each ``*.target.gz``
    file anny opens, seen through Python's audit hook); once the cache is there, it says nothing."""
    import gzip

    from anny.models.model_data import CURRENT_DATA_VERSION
    from anny.paths import get_anny_cache_path, set_anny_cache_path

    from cerberus_core.bodies import human

    target = tmp_path / "arms-elbow-decr.target.gz"  # a blend shape, read the way anny reads one
    with gzip.open(target, "wt") as f:
        f.write("0 0.1 0.2 0.3\n")
    before = get_anny_cache_path()
    set_anny_cache_path(tmp_path / "cache")
    try:
        with human._anny_cache_build():
            with gzip.open(target, "rt") as f:
                f.read()
            (tmp_path / "notes.txt").write_text("not a blend shape")
            assert human._cache_bar.n == target.stat().st_size
        err = capsys.readouterr().err
        announced = err.index(f"building anny's model cache in {tmp_path / 'cache' / f'v{CURRENT_DATA_VERSION}'}: "
                              "once per machine")
        assert "about 2 minutes" in err and announced < err.index("anny's model cache: ")
        assert human._cache_bar is None  # the build is over: later opens count nowhere
        folder = tmp_path / "cache" / f"v{CURRENT_DATA_VERSION}"
        folder.mkdir(parents=True)
        (folder / "build_model_data_0123.safetensors").write_bytes(b"")
        with human._anny_cache_build():
            with gzip.open(target, "rt") as f:
                f.read()
        assert capsys.readouterr().err == ""
    finally:
        set_anny_cache_path(before)
