"""Tests of the held-out human pose families (cerberus_core.bodies.human_heldout): no anny, no rendering.

What "poses the generator never made" means here is measured, against both training generators:
the motion clips (a real distribution: a fresh motion frame lies within a few degrees of a sample of
frames, a held-out pose far outside) and the independent sampler (uniform over the joint-limit box, so
it has no gaps inside the limits: a held-out pose is as far from its draws as a fresh draw is, and the
test says so rather than claiming more).
"""
from __future__ import annotations

import numpy as np
import pytest

from cerberus_core.bodies import human_heldout as hh
from cerberus_core.bodies import human_motion
from cerberus_core.bodies.human import SUPPORT_LEG_LIMITS, pose_params, sample_poses, sample_subjects
from cerberus_core.bodies.human_joints import DOF_LIMITS, DOF_NAMES
from cerberus_core.datasets.plan import load_generation_config


def _preset_poses() -> tuple[np.ndarray, list[str]]:
    """The joint angles ``(72, D)`` and families of the ``heldout_poses`` size: 36 per test subject."""
    n = load_generation_config("human", "heldout_poses").splits["test"].poses
    ids = [hh.heldout_pose_id(k) for k in range(n)]
    poses = np.concatenate([pose_params(s, ids) for s in sample_subjects(2, 0, "test")])
    return poses, [hh.family_of(i) for i in ids] * 2


def test_heldout_poses_are_within_limits_deterministic_by_id_and_cycle_the_families():
    subject = sample_subjects(1, 0, "test")[0]
    ids = [hh.heldout_pose_id(k) for k in range(24)]
    poses = pose_params(subject, ids)
    assert poses.shape == (24, len(DOF_NAMES))
    assert (poses >= DOF_LIMITS[:, 0]).all() and (poses <= DOF_LIMITS[:, 1]).all()
    np.testing.assert_array_equal(pose_params(subject, ids[::-1]), poses[::-1])  # by id, whatever the others
    np.testing.assert_array_equal(pose_params(subject, ids[5:6])[0], poses[5])
    assert not np.array_equal(pose_params(subject, ids[:1], attempt=1)[0], poses[0])  # a redraw differs
    assert [hh.family_of(i) for i in ids] == list(hh.FAMILIES) * 4
    other = sample_subjects(2, 0, "test")[1]
    assert not np.allclose(pose_params(other, ids), poses)  # each subject draws its own amplitudes
    # The id ranges do not overlap: a held-out id is neither a sampled pose nor a motion frame.
    assert hh.HELDOUT_POSE_BASE == human_motion.MOTION_POSE_END < 2**31
    assert not human_motion.is_motion_id(ids[0]) and human_motion.is_motion_id(hh.HELDOUT_POSE_BASE - 1)
    with pytest.raises(ValueError, match="motion clips are numbered from 0 to 499999999"):
        human_motion.motion_pose_id(500_000_000, 0)
    with pytest.raises(ValueError, match="unknown held-out pose family 'cartwheel'"):
        hh.family_pose("cartwheel", np.random.default_rng(0))
    with pytest.raises(ValueError, match="not a held-out pose"):
        hh.family_of(7)


def test_each_family_is_its_pose():
    """The families do what their names say (spot checks of the defining joints, in degrees)."""
    poses, families = _preset_poses()
    col = {name: j for j, name in enumerate(DOF_NAMES)}

    def both(pose, name):
        return np.array([pose[col[f"{name}.L"]], pose[col[f"{name}.R"]]])

    for pose, family in zip(poses, families, strict=True):
        if family == "kick":
            assert both(pose, "hip_flex").max() > 65 and both(pose, "knee_flex")[both(pose, "hip_flex").argmax()] < 30
        elif family == "jumping_jack":
            assert both(pose, "shoulder_abd").min() > 55 and both(pose, "hip_abd").min() > 15
        elif family == "lunge":
            assert both(pose, "hip_flex").max() > 65 and both(pose, "hip_flex").min() < -8
            assert both(pose, "knee_flex").min() > 30
        elif family == "crouch_arms_up":
            assert both(pose, "knee_flex").min() > 90 and both(pose, "shoulder_flex").min() > 55
        elif family == "side_lean":
            assert abs(pose[col["spine_side"]]) > 8 and both(pose, "hip_abd").max() > 22
        else:
            assert family == "arms_crossed"
            assert both(pose, "elbow_flex").min() > 100 and both(pose, "shoulder_abd").max() < -5


def test_heldout_poses_are_far_from_every_motion_frame():
    """Against 2,000 motion clips (4,000 frames) of a training subject, a fresh motion frame of a test
    subject is within 11 degrees RMS of the nearest frame (measured: at most 8.5); every held-out pose of
    the preset is farther than any of them (measured: at least 11.1, the sideways lean and the jumping
    jack, whose arms the both-arms-sideways arm raise comes near; lunges and crouches 20 and more)."""
    seed, other = sample_subjects(1, 0, "train")[0].pose_seed, sample_subjects(1, 0, "test")[0].pose_seed
    reference = np.concatenate([human_motion.clip_of(seed, human_motion.motion_pose_id(c, 0))[1]
                                for c in range(2000)])
    fresh = np.stack([human_motion.clip_of(other, human_motion.motion_pose_id(c, 0))[1][0] for c in range(100)])
    poses, _ = _preset_poses()
    fresh_far = hh.nearest_distance(fresh, reference).max()
    heldout_near = hh.nearest_distance(poses, reference).min()
    assert fresh_far < 11.0
    assert heldout_near > fresh_far + 2.0, (heldout_near, fresh_far)


def test_the_independent_sampler_has_no_gap_inside_the_limits_but_rarely_stands_without_a_support_leg():
    """The honest half: the independent sampler is uniform over the joint-limit box, so a held-out pose is
    no farther from its nearest of 20,000 draws than a fresh draw is (both 10-25 degrees RMS: in 26
    angles every pose is far from every finite sample). What the families add is structure: jumping
    jacks, lunges and crouches stand on no support leg (neither leg within SUPPORT_LEG_LIMITS), which
    only the sampler's 30 % of free-leg draws allow."""
    reference = sample_poses(np.random.default_rng(1), 20000)
    fresh = sample_poses(np.random.default_rng(2), 100)
    poses, families = _preset_poses()
    d_fresh, d_heldout = hh.nearest_distance(fresh, reference), hh.nearest_distance(poses, reference)
    assert 10.0 < d_fresh.min() and d_fresh.max() < 25.0
    assert 10.0 < d_heldout.min() and d_heldout.max() < 25.0
    col = {name: j for j, name in enumerate(DOF_NAMES)}

    def supports(pose, side):
        return all(lo <= pose[col[f"{name}.{side}"]] <= hi for name, (lo, hi) in SUPPORT_LEG_LIMITS.items())

    for pose, family in zip(poses, families, strict=True):
        if family in ("jumping_jack", "lunge", "crouch_arms_up"):
            assert not supports(pose, "L") and not supports(pose, "R"), family


def test_nearest_distance_is_the_rms_angle_difference():
    reference = np.array([[0.0, 0.0], [10.0, 0.0]])
    np.testing.assert_allclose(hh.nearest_distance(np.array([[9.0, 2.0], [0.0, 4.0]]), reference),
                               [np.sqrt((1 + 4) / 2), np.sqrt(16 / 2)])
    with pytest.raises(ValueError, match="non-empty"):
        hh.nearest_distance(np.zeros((2, 2)), np.zeros((0, 2)))
