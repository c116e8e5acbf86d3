"""Held-out pose families for the anny humans: poses the training generators do not make.

The human training poses come from two generators: independent draws uniform within the joint
limits with a support leg (:func:`cerberus_core.bodies.human.sample_poses`, the ``independent`` mode of
every human preset) and frames of six everyday motions (:mod:`cerberus_core.bodies.human_motion`, the
``motion`` mode). The families here (:data:`FAMILIES`) are whole-body poses that neither makes: several
joints held together near their limits in a coordinated pattern (both arms up and both legs apart, a
deep crouch with the torso upright and the arms raised ...), where the independent sampler's density is
``2^k`` times lower for ``k`` joints at a limit and where none of the motion primitives goes.
Every angle stays within :data:`~cerberus_core.bodies.human_joints.DOF_LIMITS`. How far they are from the
training draws is measured, not assumed: :func:`nearest_distance` (RMS joint-angle difference, degrees)
against a large sample of either generator, tested in ``tests/core/bodies/test_human_heldout.py``.

Families (each a function of the pose's generator, which draws its amplitudes; ``s`` is the side that
moves, ``o`` the other, each with probability 1/2):

* ``kick``: one leg kicks forward, nearly straight (hip flexion 75-100, knee 0-20, toes pointed), the
  support leg straight, the torso leaning back, both arms out to the sides for balance.
* ``jumping_jack``: the top of a jumping jack: both arms up and out (abduction 65-80), straight; both
  legs apart (hip abduction 25-40), straight, on the toes.
* ``lunge``: a deep lunge: front hip 75-100 and knee 85-115, the back hip extended (-12 to -20) with
  the knee bent 40-90 and the foot on its toes, the torso upright and turned toward the front leg, both
  arms out to the sides.
* ``crouch_arms_up``: a deep crouch (hips 90-100, knees 100-115, knees out) with the torso upright
  and both arms raised forward and up, straight, the head looking up.
* ``side_lean``: a cartwheel-like sideways lean: the spine and neck bent to one side as far as they
  go, both arms up and out, the leg opposite the lean lifted sideways (hip abduction 30-40).
* ``arms_crossed``: standing with both forearms folded across the chest (shoulders forward and
  inward, turned in, elbows bent 110-140).

Each pose adds an independent jitter of :data:`JITTER_SD` degrees per joint and is clipped to the
joint limits.

Pose ids (reproducible from the manifest alone): held-out poses have ids ``>=`` :data:`HELDOUT_POSE_BASE`
(above the motion ids, below 2^31 so they fit the int32 ``pose`` field); id ``HELDOUT_POSE_BASE + k``
is family ``FAMILIES[k % len(FAMILIES)]`` (so a grid of ``n`` poses per subject covers the families in
turn) drawn from ``numpy.random.default_rng([pose_seed, pose_id])`` (plus ``attempt`` for a redraw, as for
sampled poses; :meth:`cerberus_core.bodies.human.HumanBodySource.posed_bodies`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cerberus_core.bodies.human_joints import DOF_INDEX, DOF_LIMITS, DOF_NAMES, random_side
from cerberus_core.errors import BodyError

HELDOUT_POSE_BASE: int = 2_000_000_000
"""Pose ids ``>=`` this are held-out family poses (module docstring); fits the int32 ``pose`` field."""

JITTER_SD: float = 3.0
"""Standard deviation (degrees) of the independent noise added to every joint of a held-out pose."""


Family = Callable[[np.random.Generator], dict[str, float]]


def is_heldout_id(pose_id: int) -> bool:
    """Whether a pose id names a held-out family pose."""
    return int(pose_id) >= HELDOUT_POSE_BASE


def heldout_pose_id(k: int) -> int:
    """The pose id of held-out pose ``k >= 0`` (family ``FAMILIES[k % len(FAMILIES)]``)."""
    if k < 0:
        raise BodyError(f"held-out poses are numbered from 0, got {k}")
    return HELDOUT_POSE_BASE + int(k)


def family_of(pose_id: int) -> str:
    """The family of a held-out pose id."""
    if not is_heldout_id(pose_id):
        raise BodyError(f"pose id {pose_id} is not a held-out pose (held-out ids start at {HELDOUT_POSE_BASE})")
    return FAMILIES[(int(pose_id) - HELDOUT_POSE_BASE) % len(FAMILIES)]


# ----------------------------------------------------------------------------------------------
# Families: rng -> {dof name: degrees}; joints not named stay at 0 (the canonical pose) plus jitter.
# ----------------------------------------------------------------------------------------------


def _kick(rng: np.random.Generator) -> dict[str, float]:
    s, o = random_side(rng)
    out = {
        f"hip_flex.{s}": rng.uniform(75.0, 100.0), f"knee_flex.{s}": rng.uniform(0.0, 20.0),
        f"ankle_flex.{s}": rng.uniform(-30.0, -15.0), f"hip_abd.{s}": rng.uniform(0.0, 10.0),
        f"hip_flex.{o}": rng.uniform(-10.0, 0.0), f"knee_flex.{o}": rng.uniform(0.0, 10.0),
        "spine_flex": rng.uniform(-15.0, -8.0), "neck_flex": rng.uniform(5.0, 20.0),
    }
    for side in ("L", "R"):
        out[f"shoulder_abd.{side}"] = rng.uniform(50.0, 80.0)
        out[f"shoulder_flex.{side}"] = rng.uniform(-10.0, 20.0)
        out[f"elbow_flex.{side}"] = rng.uniform(0.0, 30.0)
    return out


def _jumping_jack(rng: np.random.Generator) -> dict[str, float]:
    out = {"neck_flex": rng.uniform(-15.0, 0.0)}
    for side in ("L", "R"):
        out[f"shoulder_abd.{side}"] = rng.uniform(65.0, 80.0)
        out[f"shoulder_flex.{side}"] = rng.uniform(-10.0, 10.0)
        out[f"elbow_flex.{side}"] = rng.uniform(0.0, 15.0)
        out[f"hip_abd.{side}"] = rng.uniform(25.0, 40.0)
        out[f"hip_flex.{side}"] = rng.uniform(-5.0, 10.0)
        out[f"knee_flex.{side}"] = rng.uniform(0.0, 15.0)
        out[f"ankle_flex.{side}"] = rng.uniform(-25.0, -10.0)
    return out


def _lunge(rng: np.random.Generator) -> dict[str, float]:
    s, o = random_side(rng)
    out = {
        f"hip_flex.{s}": rng.uniform(75.0, 100.0), f"knee_flex.{s}": rng.uniform(85.0, 115.0),
        f"ankle_flex.{s}": rng.uniform(10.0, 20.0),
        f"hip_flex.{o}": rng.uniform(-20.0, -12.0), f"knee_flex.{o}": rng.uniform(40.0, 90.0),
        f"ankle_flex.{o}": rng.uniform(-30.0, -15.0),
        "spine_flex": rng.uniform(-10.0, 5.0),
        "spine_twist": (1.0 if s == "L" else -1.0) * rng.uniform(15.0, 30.0),
    }
    for side in ("L", "R"):
        out[f"shoulder_abd.{side}"] = rng.uniform(60.0, 80.0)
        out[f"elbow_flex.{side}"] = rng.uniform(0.0, 15.0)
    return out


def _crouch_arms_up(rng: np.random.Generator) -> dict[str, float]:
    out = {"spine_flex": rng.uniform(-15.0, 5.0), "neck_flex": rng.uniform(-30.0, -15.0)}
    for side in ("L", "R"):
        out[f"hip_flex.{side}"] = rng.uniform(90.0, 100.0)
        out[f"knee_flex.{side}"] = rng.uniform(100.0, 115.0)
        out[f"ankle_flex.{side}"] = rng.uniform(12.0, 20.0)
        out[f"hip_abd.{side}"] = rng.uniform(15.0, 35.0)
        out[f"shoulder_flex.{side}"] = rng.uniform(65.0, 90.0)
        out[f"shoulder_abd.{side}"] = rng.uniform(55.0, 80.0)
        out[f"elbow_flex.{side}"] = rng.uniform(0.0, 15.0)
    return out


def _side_lean(rng: np.random.Generator) -> dict[str, float]:
    s, o = random_side(rng)  # lean toward s; the leg on the other side lifts
    sign = 1.0 if s == "L" else -1.0  # spine_side > 0 leans to the body's left
    out = {
        "spine_side": sign * rng.uniform(15.0, 20.0), "neck_side": sign * rng.uniform(15.0, 25.0),
        f"hip_abd.{o}": rng.uniform(30.0, 40.0), f"hip_abd.{s}": rng.uniform(10.0, 25.0),
    }
    for side in ("L", "R"):
        out[f"shoulder_abd.{side}"] = rng.uniform(65.0, 80.0)
        out[f"shoulder_flex.{side}"] = rng.uniform(-10.0, 10.0)
        out[f"elbow_flex.{side}"] = rng.uniform(0.0, 10.0)
        out[f"knee_flex.{side}"] = rng.uniform(0.0, 10.0)
    return out


def _arms_crossed(rng: np.random.Generator) -> dict[str, float]:
    out = {"neck_flex": rng.uniform(0.0, 10.0)}
    for side in ("L", "R"):
        out[f"shoulder_flex.{side}"] = rng.uniform(25.0, 45.0)
        out[f"shoulder_abd.{side}"] = rng.uniform(-20.0, -12.0)
        out[f"shoulder_twist.{side}"] = rng.uniform(30.0, 45.0)
        out[f"elbow_flex.{side}"] = rng.uniform(110.0, 140.0)
        out[f"hip_abd.{side}"] = rng.uniform(5.0, 15.0)
        out[f"knee_flex.{side}"] = rng.uniform(0.0, 10.0)
    return out


_FAMILIES: dict[str, Family] = {
    "kick": _kick, "jumping_jack": _jumping_jack, "lunge": _lunge, "crouch_arms_up": _crouch_arms_up,
    "side_lean": _side_lean, "arms_crossed": _arms_crossed,
}
FAMILIES: tuple[str, ...] = tuple(_FAMILIES)
"""The held-out pose families, in the order pose ids cycle through them."""


def family_pose(family: str, rng: np.random.Generator) -> np.ndarray:
    """One pose of a held-out family.

    Args:
        family: one of :data:`FAMILIES`.
        rng: the pose's generator (consumed: the family's amplitudes, then the jitter).

    Returns:
        ``(len(DOF_NAMES),)`` float64 joint angles in degrees, within ``DOF_LIMITS``.
    """
    if family not in _FAMILIES:
        raise BodyError(f"unknown held-out pose family {family!r}; choose one of {', '.join(FAMILIES)}")
    pose = np.zeros(len(DOF_NAMES))
    for name, angle in _FAMILIES[family](rng).items():
        pose[DOF_INDEX[name]] = angle
    pose += rng.normal(0.0, JITTER_SD, len(DOF_NAMES))
    return np.clip(pose, DOF_LIMITS[:, 0], DOF_LIMITS[:, 1])


def heldout_pose(pose_seed: int, pose_id: int, attempt: int = 0) -> np.ndarray:
    """Joint angles of a held-out pose by id (module docstring, "Pose ids").

    Args:
        pose_seed: the subject's pose seed.
        pose_id: a held-out pose id (``>=`` :data:`HELDOUT_POSE_BASE`).
        attempt: 0, or ``a >= 1`` for the pose's ``a``-th redraw.

    Returns:
        ``(len(DOF_NAMES),)`` float64 degrees of family :func:`family_of` ``(pose_id)``.
    """
    key = [int(pose_seed), int(pose_id)] + ([int(attempt)] if attempt else [])
    return family_pose(family_of(pose_id), np.random.default_rng(key))


def nearest_distance(poses: np.ndarray, reference: np.ndarray, chunk: int = 256) -> np.ndarray:
    """Each pose's distance to its nearest reference pose: the RMS joint-angle difference.

    Args:
        poses: ``(N, D)`` joint angles in degrees.
        reference: ``(M, D)`` joint angles in degrees (e.g. a large sample of training draws).
        chunk: poses compared at a time (memory ``chunk * M`` floats).

    Returns:
        ``(N,)`` float64 degrees: ``min_m sqrt(mean_d (poses[n, d] - reference[m, d])^2)``.
    """
    poses, reference = np.asarray(poses, dtype=np.float64), np.asarray(reference, dtype=np.float64)
    if poses.ndim != 2 or reference.ndim != 2 or poses.shape[1] != reference.shape[1] or not len(reference):
        raise BodyError(f"nearest_distance needs (N, D) poses and a non-empty (M, D) reference, got "
                        f"{poses.shape} and {reference.shape}")
    ref_sq = (reference**2).sum(1)
    out = np.empty(len(poses))
    for start in range(0, len(poses), chunk):
        p = poses[start:start + chunk]
        sq = (p**2).sum(1)[:, None] + ref_sq[None] - 2.0 * p @ reference.T
        out[start:start + chunk] = np.sqrt(np.maximum(sq.min(1), 0.0) / poses.shape[1])
    return out


__all__ = [
    "FAMILIES",
    "HELDOUT_POSE_BASE",
    "JITTER_SD",
    "family_of",
    "family_pose",
    "heldout_pose",
    "heldout_pose_id",
    "is_heldout_id",
    "nearest_distance",
]
