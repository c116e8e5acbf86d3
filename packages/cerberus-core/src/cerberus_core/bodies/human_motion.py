"""Motion pose pairs for the anny humans: two nearby frames of one everyday motion.

The paper's Human training pairs are "two frames from a video" of motion capture; two independent
draws within the joint limits (:func:`cerberus_core.bodies.human.sample_poses`, the
``independent`` mode) are much further apart and much wilder. A *motion clip* here is one draw of
a small library of motion primitives, and its two frames are the primitive at phase ``phi`` (frame
``a``) and at ``phi + dt / period`` (frame ``b``), ``dt`` uniform in :data:`FRAME_STEP_S` seconds.

Primitives (:data:`MOTIONS`; each is a function of the phase ``t = 2*pi*phi`` and a few amplitudes
drawn per clip; ``psi = (1 - cos t) / 2`` is a raise-and-lower ramp in ``[0, 1]``):

* ``walk`` (period 0.9-1.2 s, stroll to brisk): hips swing in anti-phase, each knee bends while
  its leg swings forward, each arm swings opposite to its own leg with the elbow bending as the arm
  comes forward, the torso counter-rotates and leans over the support leg, arms hang near the body.
* ``arm_raise`` (1.2-2.2 s): one or both arms rise forward and/or sideways by 40-90 degrees and come
  back down, elbows bending with shoulder flexion.
* ``reach`` (1.2-2 s): one arm reaches forward (high or low), straightening its elbow as it goes,
  with a forward lean at the spine and hips, a twist of the torso and a counter-swing of the other
  arm.
* ``squat`` (1.6-2.8 s; also sitting down and standing up): hips flex by up to 40-100 degrees, knees
  by 1.15 times that, ankles dorsiflex, the torso leans forward, arms come forward to balance.
* ``turn`` (1.2-2.2 s): the torso twists left and right by 15-35 degrees, the head follows, the arms
  swing loosely with the rotation.
* ``wave`` (0.5-0.9 s): one arm held up to the side, the forearm waving at the elbow (with some
  upper-arm and forearm twist).

Asymmetric primitives pick their side at random. Every clip adds a secondary *sway* with its own
phase and a period of 0.8-1.6 s (:func:`_sway`: weight shift from leg to leg with the unloaded knee
bending, a loose swing and twist of both arms, the head looking around by up to 24 degrees, a
slight bend of the spine), a static *posture* shared by both frames (normal,
:data:`POSTURE_SD` degrees per joint: the person's stance, head tilt, knee bend) and to each frame
an independent jitter of :data:`JITTER_SD` degrees per joint. Both frames are clipped to
:data:`~cerberus_core.bodies.human_joints.DOF_LIMITS`, so every pose stays within the joint limits.

Pose ids (reproducible from the manifest alone): motion frames have ids ``>=`` :data:`MOTION_POSE_BASE`;
clip ``c`` has frames ``MOTION_POSE_BASE + 2c`` (``a``) and ``MOTION_POSE_BASE + 2c + 1`` (``b``),
both computed from ``numpy.random.default_rng([pose_seed, MOTION_POSE_BASE + 2c])`` (plus ``attempt``
for a redraw, as for sampled poses; a clip is always redrawn as a whole, see
:meth:`cerberus_core.bodies.human.HumanBodySource.posed_bodies`). Ids below the base keep their old
meaning (0 canonical, ``k >= 1`` independent samples), so datasets generated before motion pairs
existed rebuild identically.
"""

from __future__ import annotations

import numpy as np

from cerberus_core.bodies.human_joints import DOF_INDEX, DOF_LIMITS, DOF_NAMES, random_side
from cerberus_core.errors import BodyError

MOTION_POSE_BASE: int = 1_000_000_000
"""Pose ids ``>=`` this (and below :data:`MOTION_POSE_END`) are motion-clip frames (module docstring); fits
the int32 ``pose`` field."""

MOTION_POSE_END: int = 2_000_000_000
"""Where the motion ids end: ids from here on are held-out family poses
(:data:`cerberus_core.bodies.human_heldout.HELDOUT_POSE_BASE`), so clips number below 5 * 10^8."""

MOTIONS: tuple[str, ...] = ("walk", "arm_raise", "reach", "squat", "turn", "wave")
"""The motion primitives, drawn with equal probability."""

PERIODS_S: dict[str, tuple[float, float]] = {
    "walk": (0.9, 1.2),
    "arm_raise": (1.2, 2.2),
    "reach": (1.2, 2.0),
    "squat": (1.6, 2.8),
    "turn": (1.2, 2.2),
    "wave": (0.5, 0.9),
}
"""Uniform range of each primitive's period (seconds): a full cycle of the motion."""

FRAME_STEP_S: tuple[float, float] = (0.1, 0.3)
"""Uniform range of the time between the two frames of a clip (seconds)."""

POSTURE_SD: float = 3.0
"""Standard deviation (degrees) of the static per-clip offset of every joint (shared by both frames)."""

JITTER_SD: float = 1.0
"""Standard deviation (degrees) of the independent per-frame noise of every joint."""

SWAY_PERIOD_S: tuple[float, float] = (0.8, 1.6)
SWAY_AMPLITUDE: tuple[float, float] = (0.5, 1.2)
"""The secondary movement of every clip (:func:`_sway`), on top of its primitive, with its own phase:
a period uniform in ``SWAY_PERIOD_S`` seconds and a scale ``s`` uniform in ``SWAY_AMPLITUDE``."""



def is_motion_id(pose_id: int) -> bool:
    """Whether a pose id names a motion-clip frame."""
    return MOTION_POSE_BASE <= int(pose_id) < MOTION_POSE_END


def motion_pose_id(clip: int, frame: int) -> int:
    """The pose id of frame ``frame`` (0 = ``a``, 1 = ``b``) of motion clip ``clip >= 0``."""
    if not 0 <= clip < (MOTION_POSE_END - MOTION_POSE_BASE) // 2 or frame not in (0, 1):
        raise BodyError(f"motion clips are numbered from 0 to {(MOTION_POSE_END - MOTION_POSE_BASE) // 2 - 1} and have "
                        f"frames 0 and 1, got clip {clip}, frame {frame}")
    return MOTION_POSE_BASE + 2 * int(clip) + int(frame)


def clip_frame(pose_id: int) -> tuple[int, int]:
    """``(clip, frame)`` of a motion pose id (the inverse of :func:`motion_pose_id`)."""
    if not is_motion_id(pose_id):
        raise BodyError(f"pose id {pose_id} is not a motion frame (motion ids are {MOTION_POSE_BASE} to "
                        f"{MOTION_POSE_END - 1})")
    return divmod(int(pose_id) - MOTION_POSE_BASE, 2)


def clip_key(pose_id: int) -> int:
    """The id of frame ``a`` of the clip a motion pose id belongs to (its generator's key)."""
    return motion_pose_id(clip_frame(pose_id)[0], 0)


# ----------------------------------------------------------------------------------------------
# Primitives: (t (F,) radians, rng) -> {dof name: (F,) degrees}; rng draws the clip's amplitudes.
# ----------------------------------------------------------------------------------------------


def _ramp(t: np.ndarray) -> np.ndarray:
    """Raise-and-lower ramp ``(1 - cos t) / 2`` in ``[0, 1]``."""
    return 0.5 - 0.5 * np.cos(t)


def _arms_down(out: dict[str, np.ndarray], side: str, t: np.ndarray) -> None:
    """An idle arm hanging near the body, elbow slightly bent."""
    out[f"shoulder_abd.{side}"] = np.full_like(t, -15.0)
    out[f"elbow_flex.{side}"] = np.full_like(t, 12.0)


def _walk(t: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    a = rng.uniform(0.5, 1.3)  # stride amplitude: stroll .. brisk walk
    out: dict[str, np.ndarray] = {}
    for side, sign in (("L", 1.0), ("R", -1.0)):
        swing = sign * np.sin(t)  # this leg's forward swing
        forward = sign * np.cos(t)  # > 0 while this leg moves forward
        out[f"hip_flex.{side}"] = 5.0 + 22.0 * a * swing
        out[f"hip_abd.{side}"] = 3.0 + 3.0 * a * forward  # the swing leg clears the support leg
        out[f"hip_twist.{side}"] = 5.0 * a * swing
        out[f"knee_flex.{side}"] = 8.0 + 50.0 * a * np.maximum(0.0, forward)
        out[f"ankle_flex.{side}"] = 8.0 * a * swing
        arm = -25.0 * a * swing  # the arm swings opposite to its own leg
        out[f"shoulder_flex.{side}"] = arm
        out[f"shoulder_abd.{side}"] = np.full_like(t, -15.0)
        out[f"elbow_flex.{side}"] = 15.0 + 10.0 * a + 0.8 * np.maximum(0.0, arm)
    out["spine_twist"] = 8.0 * a * np.sin(t)  # the shoulders counter-rotate against the hips
    out["spine_side"] = 3.0 * a * np.cos(t)  # lean over the support leg
    out["spine_flex"] = np.full_like(t, 3.0 + 4.0 * a)
    return out


def _arm_raise(t: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    peak = rng.uniform(40.0, 90.0)  # degrees of raise at the top
    forward = rng.uniform(0.0, 1.0)  # 1: straight forward (flexion), 0: sideways (abduction)
    rest_elbow = rng.uniform(5.0, 20.0)
    both = rng.random() < 0.5
    side, other = random_side(rng)
    psi = _ramp(t)
    out: dict[str, np.ndarray] = {}
    for s in (side, other) if both else (side,):
        out[f"shoulder_flex.{s}"] = -5.0 + forward * peak * psi
        out[f"shoulder_abd.{s}"] = -15.0 + (1.0 - forward) * (peak + 15.0) * psi
        out[f"elbow_flex.{s}"] = rest_elbow + 0.4 * np.maximum(0.0, out[f"shoulder_flex.{s}"])
    if not both:
        _arms_down(out, other, t)
    out["spine_flex"] = -3.0 * psi
    return out


def _reach(t: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    height = rng.uniform(0.0, 1.0)  # 0: reach low (lean), 1: reach high
    lean = rng.uniform(0.0, 30.0) * (1.0 - height)
    sideways = rng.uniform(0.0, 30.0)
    side, other = random_side(rng)
    psi = _ramp(t)
    twist = -12.0 if side == "L" else 12.0
    return {
        f"shoulder_flex.{side}": 10.0 + (40.0 + 45.0 * height) * psi,
        f"shoulder_abd.{side}": -10.0 + sideways * psi,
        f"elbow_flex.{side}": 90.0 - 75.0 * psi,  # the arm straightens as it reaches
        f"shoulder_flex.{other}": -10.0 * psi,
        f"shoulder_abd.{other}": np.full_like(t, -15.0),
        f"elbow_flex.{other}": np.full_like(t, 15.0),
        "spine_flex": lean * psi,
        "spine_twist": twist * psi,
        "hip_flex.L": 0.5 * lean * psi,
        "hip_flex.R": 0.5 * lean * psi,
        "knee_flex.L": 0.3 * lean * psi,
        "knee_flex.R": 0.3 * lean * psi,
    }


def _squat(t: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    depth = rng.uniform(40.0, 100.0)  # hip flexion at the bottom
    arms = rng.uniform(0.0, 80.0)  # arms forward for balance
    elbow = rng.uniform(0.0, 40.0)
    psi = _ramp(t)
    hip = depth * psi
    out: dict[str, np.ndarray] = {"spine_flex": 0.3 * hip, "neck_flex": -0.2 * hip}
    for s in ("L", "R"):
        out[f"hip_flex.{s}"] = hip
        out[f"knee_flex.{s}"] = 1.15 * hip
        out[f"ankle_flex.{s}"] = 0.15 * hip  # shin forward over the foot
        out[f"hip_abd.{s}"] = 10.0 * psi  # knees out
        out[f"shoulder_flex.{s}"] = arms * psi
        out[f"shoulder_abd.{s}"] = np.full_like(t, -10.0)
        out[f"elbow_flex.{s}"] = 10.0 + elbow * psi
    return out


def _turn(t: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    amp = rng.uniform(15.0, 35.0)
    s = np.sin(t)
    out: dict[str, np.ndarray] = {"spine_twist": amp * s, "neck_twist": 0.6 * amp * s, "spine_side": 0.2 * amp * s}
    for side, sign in (("L", 1.0), ("R", -1.0)):
        out[f"shoulder_flex.{side}"] = sign * 0.5 * amp * s  # arms swing loosely with the rotation
        out[f"shoulder_abd.{side}"] = -10.0 + 0.3 * amp * np.abs(s)
        out[f"elbow_flex.{side}"] = 20.0 + 20.0 * np.abs(s)
        out[f"hip_twist.{side}"] = 0.3 * amp * s
    return out


def _wave(t: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    abd = rng.uniform(40.0, 75.0)
    flex = rng.uniform(0.0, 30.0)
    elbow = rng.uniform(60.0, 100.0)
    side, other = random_side(rng)
    s = np.sin(t)
    out = {
        f"shoulder_abd.{side}": np.full_like(t, abd),
        f"shoulder_flex.{side}": np.full_like(t, flex),
        f"elbow_flex.{side}": elbow + 25.0 * s,
        f"shoulder_twist.{side}": 15.0 * s,
        f"forearm_twist.{side}": 10.0 * s,
    }
    _arms_down(out, other, t)
    return out


_PRIMITIVES = {"walk": _walk, "arm_raise": _arm_raise, "reach": _reach, "squat": _squat, "turn": _turn,
               "wave": _wave}


def _sway(t: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """The secondary movement added to every primitive: a weight shift from leg to leg, a loose
    swing of the arms (one half-cycle apart), the head looking around and a slight breathing of the
    spine, all at the sway's own phase ``t`` and scaled by ``s`` (:data:`SWAY_AMPLITUDE`)."""
    s = rng.uniform(*SWAY_AMPLITUDE)
    head = rng.uniform(0.0, 2.0 * np.pi)  # the head's own phase offset
    sin, cos = np.sin(t), np.cos(t)
    out = {
        "spine_side": 6.0 * s * sin,
        "spine_flex": 4.0 * s * cos,
        "neck_twist": 20.0 * s * np.sin(t + head),
        "neck_flex": 8.0 * s * np.cos(t + head),
        "neck_side": 5.0 * s * np.sin(t + head),
    }
    for side, sign in (("L", 1.0), ("R", -1.0)):
        out[f"hip_abd.{side}"] = 5.0 * s * sign * sin
        out[f"hip_twist.{side}"] = 6.0 * s * sin
        out[f"knee_flex.{side}"] = 8.0 * s * np.maximum(0.0, -sign * sin)  # the unloaded knee bends
        out[f"ankle_flex.{side}"] = 4.0 * s * np.maximum(0.0, -sign * sin)
        out[f"shoulder_flex.{side}"] = 10.0 * s * sign * cos
        out[f"shoulder_twist.{side}"] = 12.0 * s * sign * sin
        out[f"elbow_flex.{side}"] = 12.0 * s * (1.0 + sign * cos)
        out[f"forearm_twist.{side}"] = 15.0 * s * sign * sin
    return out


def motion_clip(rng: np.random.Generator) -> tuple[str, np.ndarray]:
    """Draw one motion clip: its primitive's name and its two frames.

    Args:
        rng: the clip's generator (consumed in a fixed order: primitive, phase, period, frame step,
            sway phase and period, the primitive's amplitudes, the sway's, posture, jitter).

    Returns:
        ``(motion, poses)``: one of :data:`MOTIONS`, and ``(2, len(DOF_NAMES))`` float64 joint
        angles in degrees (frames ``a`` and ``b``), within ``DOF_LIMITS``.
    """
    motion = MOTIONS[int(rng.integers(len(MOTIONS)))]
    phase = rng.uniform(0.0, 1.0)
    period = rng.uniform(*PERIODS_S[motion])
    step = rng.uniform(*FRAME_STEP_S)
    sway_phase, sway_period = rng.uniform(0.0, 1.0), rng.uniform(*SWAY_PERIOD_S)
    seconds = np.array([0.0, step])
    poses = np.zeros((2, len(DOF_NAMES)))
    for layer, t in ((_PRIMITIVES[motion], phase + seconds / period), (_sway, sway_phase + seconds / sway_period)):
        for name, angle in layer(2.0 * np.pi * t, rng).items():
            poses[:, DOF_INDEX[name]] += angle
    poses += rng.normal(0.0, POSTURE_SD, len(DOF_NAMES))
    poses += rng.normal(0.0, JITTER_SD, poses.shape)
    return motion, np.clip(poses, DOF_LIMITS[:, 0], DOF_LIMITS[:, 1])


def clip_of(pose_seed: int, pose_id: int, attempt: int = 0) -> tuple[str, np.ndarray]:
    """The motion clip a motion pose id belongs to (module docstring, "Pose ids").

    Args:
        pose_seed: the subject's pose seed.
        pose_id: a motion pose id (``>=`` :data:`MOTION_POSE_BASE`), either frame.
        attempt: 0, or ``a >= 1`` for the clip's ``a``-th redraw.

    Returns:
        :func:`motion_clip` of the clip's generator: ``(motion, (2, D) degrees)``.
    """
    key = [int(pose_seed), clip_key(pose_id)] + ([int(attempt)] if attempt else [])
    return motion_clip(np.random.default_rng(key))


def motion_frame(pose_seed: int, pose_id: int, attempt: int = 0) -> np.ndarray:
    """Joint angles of one motion frame by pose id: ``(len(DOF_NAMES),)`` float64 degrees, frame
    ``clip_frame(pose_id)[1]`` of :func:`clip_of`."""
    return clip_of(pose_seed, pose_id, attempt)[1][clip_frame(pose_id)[1]]


__all__ = [
    "FRAME_STEP_S",
    "JITTER_SD",
    "MOTIONS",
    "MOTION_POSE_BASE",
    "MOTION_POSE_END",
    "PERIODS_S",
    "POSTURE_SD",
    "SWAY_AMPLITUDE",
    "SWAY_PERIOD_S",
    "clip_frame",
    "clip_key",
    "clip_of",
    "is_motion_id",
    "motion_clip",
    "motion_frame",
    "motion_pose_id",
]
