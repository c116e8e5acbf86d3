"""Everyday motion clips of the human source (cerberus_core.bodies.human_motion): within the joint limits,
plausible, and pairs of nearby frames that move correlated joints."""
from __future__ import annotations

import numpy as np

from cerberus_core.bodies import human_motion
from cerberus_core.bodies.human import (
    DOF_LIMITS,
    DOF_NAMES,
    sample_poses,
)
from cerberus_core.bodies.human_motion import motion_clip


def _motion_clips(n: int, seed: int = 11) -> tuple[list[str], np.ndarray]:
    names, poses = zip(*(motion_clip(np.random.default_rng([seed, c])) for c in range(n)), strict=True)
    return list(names), np.stack(poses)  # (n, 2, D)


def test_motion_poses_within_limits_plausible_and_every_motion_drawn():
    names, clips = _motion_clips(600)
    assert set(names) == set(human_motion.MOTIONS)
    assert (clips >= DOF_LIMITS[:, 0]).all() and (clips <= DOF_LIMITS[:, 1]).all()
    wild = sample_poses(np.random.default_rng(3), 600)
    pose_a = clips[:, 0]
    # Everyday poses are closer to standing than uniform draws within the joint limits ...
    assert np.abs(pose_a).mean() < 0.6 * np.abs(wild).mean()
    # ... and the arms are mostly down (abduction below the A-pose's) or forward, seldom raised sideways
    # (waving and sideways arm raises do).
    sides = [DOF_NAMES.index("shoulder_abd.L"), DOF_NAMES.index("shoulder_abd.R")]
    abd, wild_abd = pose_a[:, sides], wild[:, sides]
    assert (abd < 0).mean() > 0.7 and (abd > 40).mean() < 0.5 * (wild_abd > 40).mean()
    assert np.median(abd) < np.median(wild_abd) - 20


def test_motion_pairs_are_close_and_correlated_unlike_independent_pairs():
    names, clips = _motion_clips(600)
    motion = np.abs(clips[:, 1] - clips[:, 0])
    wild = sample_poses(np.random.default_rng(3), 1200)
    independent = np.abs(wild[0::2] - wild[1::2])
    assert motion.mean() < 0.35 * independent.mean()
    assert 3.0 < motion.mean() < 12.0  # nearby frames, but the body does move
    walks = np.array([n == "walk" for n in names])
    assert (motion[walks] > 5.0).sum(1).mean() >= 8  # a walk moves many joints at once
    # Correlated, not independent noise: in a walk, the hips swing in anti-phase, each arm opposite its leg.
    step = clips[walks, 1] - clips[walks, 0]
    hip_l, hip_r, arm_l = (DOF_NAMES.index(n) for n in ("hip_flex.L", "hip_flex.R", "shoulder_flex.L"))
    assert np.corrcoef(step[:, hip_l], step[:, hip_r])[0, 1] < -0.8
    assert np.corrcoef(step[:, hip_l], step[:, arm_l])[0, 1] < -0.5
    noise = wild[1::2] - wild[0::2]
    assert abs(np.corrcoef(noise[:, hip_l], noise[:, hip_r])[0, 1]) < 0.2  # (independent pairs: none)
