"""Forward kinematics of the procedural quadruped: shape parameters + pose -> posed SDF primitives.

Body frame (body units, see :mod:`cerberus_core.bodies.animal_shape`): +Y up, head towards +Z, the
animal's left is +X, ground at ``y = 0`` in the rest pose. The skeleton is

* torso: belly ellipsoid at the root, chest and rump ellipsoids on two spine joints that share the
  spine bend (``spine_yaw``/``spine_pitch``) half each;
* neck: one tapered capsule from inside the chest; head: cranium ellipsoid, snout capsule, two
  ellipsoid ears and optional two-segment horns;
* four legs of three tapered capsules (upper, lower, foot) plus a paw/hoof ellipsoid, with a
  zig-zag hind leg;
* tail: five tapered capsules.

Each primitive belongs to one semantic part (:data:`PART_GROUPS`).

A pose (:class:`AnimalPose`, defined here with the kinematics that give its angles a meaning; the
generator is :mod:`cerberus_core.bodies.animal_pose`) is a handful of joint angles (radians).
Sign conventions (body frame: +Y up, head towards +Z, the animal's left is +X):

* leg ``swing`` > 0 moves the foot forward (+Z); ``bend`` >= 0 flexes knee/elbow and ankle/wrist;
  ``abduct`` > 0 moves the foot away from the body midline.
* ``body_pitch`` > 0 raises the front (sitting); ``spine_yaw`` > 0 curves both ends to the animal's
  left; ``spine_pitch`` > 0 sways the back (both ends up).
* ``neck_raise`` > 0 lifts the neck; ``head_pitch`` > 0 lifts the nose; ``*_yaw`` > 0 turns left.
* ``tail_lift`` > 0 raises the tail; ``tail_curl`` > 0 curls it upwards along its length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cerberus_core.bodies.animal_sdf import Ellipsoid, Primitive, RoundCone
from cerberus_core.errors import BodyError


@dataclass(frozen=True)
class AnimalPose:
    """Joint angles of one quadruped pose (radians; conventions in the module docstring).

    Attributes:
        kind: the behaviour it was drawn from (a key of :data:`~cerberus_core.bodies.animal_pose.POSE_KINDS`, or ``"rest"``).
        legs: four ``(swing, bend, abduct)`` triples: front left, front right, back left, back right.
    """

    kind: str = "rest"
    legs: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),) * 4
    body_pitch: float = 0.0
    spine_yaw: float = 0.0
    spine_pitch: float = 0.0
    neck_raise: float = 0.0
    neck_yaw: float = 0.0
    head_pitch: float = 0.0
    head_yaw: float = 0.0
    tail_lift: float = 0.0
    tail_yaw: float = 0.0
    tail_curl: float = 0.0

    def __post_init__(self) -> None:
        if len(self.legs) != 4 or any(len(leg) != 3 for leg in self.legs):
            raise BodyError(f"AnimalPose.legs must be 4 (swing, bend, abduct) triples, got {self.legs}")


PART_GROUPS: tuple[str, ...] = (
    "head",
    "neck",
    "torso",
    "tail",
    "front_left_leg",
    "front_right_leg",
    "back_left_leg",
    "back_right_leg",
)
"""Semantic parts; a primitive's ``group`` indexes this tuple. Head includes snout, ears and horns;
each leg includes its paw/hoof; left is the animal's left (+X)."""

HEAD, NECK, TORSO, TAIL = 0, 1, 2, 3
LEG_GROUPS = (4, 5, 6, 7)
N_TAIL_SEGMENTS = 5


def pitch_up(t: float) -> np.ndarray:
    """Rotation about -X by ``t``: lifts a +Z vector towards +Y and swings a -Y vector towards +Z."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])


def yaw(t: float) -> np.ndarray:
    """Rotation about +Y by ``t``: turns a +Z vector towards +X (the animal's left)."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def roll(t: float) -> np.ndarray:
    """Rotation about +Z by ``t``: swings a -Y vector towards +X."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


class _Builder:
    """Collects primitives while clamping every radius to ``min_radius``."""

    def __init__(self, min_radius: float) -> None:
        self.min_radius = float(min_radius)
        self.prims: list[Primitive] = []

    def cone(self, a: np.ndarray, b: np.ndarray, ra: float, rb: float, group: int, blend: float) -> None:
        r0, r1 = max(ra, self.min_radius), max(rb, self.min_radius)
        a, b = np.asarray(a, float), np.asarray(b, float)
        self.prims.append(RoundCone(a, b, float(r0), float(r1), group, float(blend)))

    def ellipsoid(self, centre: np.ndarray, axes: np.ndarray, radii: np.ndarray, group: int, blend: float) -> None:
        r = np.maximum(np.asarray(radii, float), self.min_radius)
        self.prims.append(Ellipsoid(np.asarray(centre, float), np.asarray(axes, float), r, group, float(blend)))


@dataclass(frozen=True)
class _Trunk:
    """Where the trunk is: the root (centre of the torso), its frame and those of the front and back
    halves (the spine bends between them), and the torso's size."""

    root: np.ndarray
    r_root: np.ndarray
    r_front: np.ndarray
    r_back: np.ndarray
    length: float
    height: float
    width: float


def _trunk(p: dict[str, float], pose: AnimalPose) -> _Trunk:
    r_root = pitch_up(pose.body_pitch)
    return _Trunk(
        root=np.array([0.0, p["leg_length"] + p["torso_height"], 0.0]),  # belly bottom at y = leg_length
        r_root=r_root,
        r_front=r_root @ yaw(0.5 * pose.spine_yaw) @ pitch_up(0.5 * pose.spine_pitch),
        r_back=r_root @ yaw(-0.5 * pose.spine_yaw) @ pitch_up(-0.5 * pose.spine_pitch),
        length=p["torso_length"], height=p["torso_height"], width=p["torso_width"],
    )


def _torso(b: _Builder, p: dict[str, float], t: _Trunk) -> None:
    """Three ellipsoids: the middle, the chest (``chest_scale``) and the rump."""
    lt, h, w, cs = t.length, t.height, t.width, p["chest_scale"]
    k_torso = 0.4 * h
    b.ellipsoid(t.root, t.r_root, np.array([w, h, 0.36 * lt]), TORSO, 0.0)
    chest, rump = t.root + t.r_front @ [0.0, 0.05 * h, 0.22 * lt], t.root + t.r_back @ [0.0, 0.03 * h, -0.22 * lt]
    b.ellipsoid(chest, t.r_front, np.array([w * cs, h * cs, 0.28 * lt]), TORSO, k_torso)
    b.ellipsoid(rump, t.r_back, np.array([0.95 * w, 0.97 * h, 0.28 * lt]), TORSO, k_torso)


def _neck_and_head(b: _Builder, p: dict[str, float], pose: AnimalPose, t: _Trunk) -> None:
    """The neck (a cone), the cranium, the snout, then each side's ear and horn."""
    lt, h = t.length, t.height
    nl, nr = p["neck_length"], p["neck_radius"]
    neck_base = t.root + t.r_front @ [0.0, 0.3 * h, 0.36 * lt]
    r_neck = t.r_front @ yaw(pose.neck_yaw) @ pitch_up(p["neck_angle"] + pose.neck_raise)
    neck_end = neck_base + r_neck @ [0.0, 0.0, nl]
    b.cone(neck_base, neck_end, nr, 0.72 * nr, NECK, 0.6 * nr)

    hs = p["head_size"]
    r_head = t.r_front @ yaw(pose.neck_yaw + pose.head_yaw) @ pitch_up(-0.35 + 0.4 * pose.neck_raise + pose.head_pitch)
    cranium = neck_end + r_head @ [0.0, 0.2 * hs, 0.3 * hs]
    b.ellipsoid(cranium, r_head, np.array([0.85 * hs, 0.9 * hs, 1.05 * hs]), HEAD, 0.5 * min(nr, hs))
    sl, sw = p["snout_length"] * hs, p["snout_width"] * hs
    snout_base = cranium + r_head @ [0.0, -0.15 * hs, 0.35 * hs]
    snout_tip = cranium + r_head @ [0.0, -0.25 * hs - 0.1 * sl, 0.4 * hs + sl]
    b.cone(snout_base, snout_tip, sw, 0.8 * sw, HEAD, 0.4 * sw)
    for side in (1.0, -1.0):
        _ear(b, p, cranium, r_head, side)
        _horn(b, p, cranium, r_head, side)


def _ear(b: _Builder, p: dict[str, float], cranium: np.ndarray, r_head: np.ndarray, side: float) -> None:
    """A flat ellipsoid between pricked up (``ear_droop`` 0) and hanging (1)."""
    hs = p["head_size"]
    el, droop = p["ear_length"] * hs, p["ear_droop"]
    up = _unit(np.array([0.45 * side, 1.0, -0.35]))
    hang = _unit(np.array([0.75 * side, -0.8, 0.1]))
    d = _unit((1 - droop) * up + droop * hang)
    face = (1 - droop) * np.array([0.0, 0.0, 1.0]) + droop * np.array([side, 0.0, 0.0])
    thin = _unit(face - (face @ d) * d)
    wide = np.cross(d, thin)
    half_w = 0.5 * p["ear_width"] * el
    centre = np.array([0.5 * side * hs, 0.7 * hs, -0.2 * hs]) + 0.45 * el * d
    b.ellipsoid(
        cranium + r_head @ centre,
        r_head @ np.stack([wide, d, thin], axis=1),
        np.array([half_w, 0.5 * el, max(0.22 * half_w, 0.1 * hs)]),
        HEAD,
        0.25 * half_w,
    )


def _horn(b: _Builder, p: dict[str, float], cranium: np.ndarray, r_head: np.ndarray, side: float) -> None:
    """Two cones curving up and back (none when ``horn_length`` is 0)."""
    hs = p["head_size"]
    horn = p["horn_length"] * hs
    if horn > 0:
        h0 = np.array([0.35 * side * hs, 0.75 * hs, 0.05 * hs])
        h1 = h0 + 0.5 * horn * _unit(np.array([0.35 * side, 0.85, -0.45]))
        h2 = h1 + 0.5 * horn * _unit(np.array([0.3 * side, 0.3, -0.9]))
        b.cone(cranium + r_head @ h0, cranium + r_head @ h1, 0.16 * hs, 0.1 * hs, HEAD, 0.05 * hs)
        b.cone(cranium + r_head @ h1, cranium + r_head @ h2, 0.1 * hs, 0.04 * hs, HEAD, 0.02 * hs)


def _leg(b: _Builder, p: dict[str, float], pose: AnimalPose, t: _Trunk, leg: int, group: int) -> None:
    """Leg ``leg`` (0, 1 front; 2, 3 hind; even: left): three tapered cones and a paw."""
    lt, h, w = t.length, t.height, t.width
    lr, taper, hz = p["leg_radius"], p["leg_taper"], p["hind_angle"]
    r_paw = lr * taper * p["paw_size"]
    front = leg < 2
    side = 1.0 if leg % 2 == 0 else -1.0
    swing, bend, abduct = pose.legs[leg]
    if front:
        frame, joint_local = t.r_front, np.array([0.55 * side * w, -0.1 * h, 0.25 * lt])
        rest, frac, fold = np.array([0.0, -0.05, 0.3]), np.array([0.48, 0.38, 0.14]), -0.7
        radii = [min(1.6 * lr, 0.45 * h), 0.5 * (1 + taper) * lr, taper * lr, 0.9 * taper * lr]
    else:
        frame, joint_local = t.r_back, np.array([0.5 * side * w, 0.1 * h, -0.27 * lt])
        rest, frac, fold = np.array([0.45, -0.6, 0.12]) * hz, np.array([0.42, 0.34, 0.24]), 1.0
        radii = [min(2.1 * lr, 0.5 * h), 0.6 * (1 + taper) * lr, taper * lr, 0.9 * taper * lr]
    # segment lengths chosen so that the rest pose stands on y = 0
    joint_height = t.root[1] + joint_local[1]
    scale = (joint_height - 0.7 * r_paw) / float(frac @ np.cos(rest))
    lengths = scale * frac
    a1 = rest[0] + swing
    a2 = a1 + (rest[1] - rest[0]) - bend
    a3 = a2 + (rest[2] - rest[1]) + fold * bend
    r_leg = frame @ roll(side * abduct)
    pos = t.root + frame @ joint_local
    blends = [(0.7 if front else 0.8) * lr, 0.25 * lr, 0.2 * lr]
    for i, ang in enumerate((a1, a2, a3)):
        nxt = pos + r_leg @ pitch_up(ang) @ [0.0, -lengths[i], 0.0]
        b.cone(pos, nxt, radii[i], radii[i + 1], group, blends[i])
        pos = nxt
    r_foot = r_leg @ pitch_up(a3 - rest[2])
    paw = pos + r_foot @ [0.0, 0.0, 0.3 * r_paw]
    b.ellipsoid(paw, r_foot, np.array([0.9, 0.7, 1.25]) * r_paw, group, 0.3 * taper * lr)


def _tail(b: _Builder, p: dict[str, float], pose: AnimalPose, t: _Trunk) -> None:
    """:data:`N_TAIL_SEGMENTS` cones that thin (and bush out with ``tail_bush``), droop and curl."""
    tl, tr, bush = p["tail_length"], p["tail_radius"], p["tail_bush"]
    seg = tl / N_TAIL_SEGMENTS
    pos = t.root + t.r_back @ [0.0, 0.45 * t.height, -0.45 * t.length]
    r_t = t.r_back @ yaw(-pose.tail_yaw / N_TAIL_SEGMENTS) @ pitch_up(p["tail_droop"] - pose.tail_lift)
    curl = -(0.25 * p["tail_droop"] + pose.tail_curl) / N_TAIL_SEGMENTS

    def tail_r(u: float) -> float:
        return tr * (1 - 0.55 * u) * (1 + 0.8 * bush * np.sin(np.pi * u))

    for i in range(N_TAIL_SEGMENTS):
        if i > 0:
            r_t = r_t @ yaw(-pose.tail_yaw / N_TAIL_SEGMENTS) @ pitch_up(curl)
        nxt = pos + r_t @ [0.0, 0.0, -seg]
        t0, t1 = i / N_TAIL_SEGMENTS, (i + 1) / N_TAIL_SEGMENTS
        b.cone(pos, nxt, tail_r(t0), tail_r(t1), TAIL, (0.8 if i == 0 else 0.4) * tr)
        pos = nxt


def animal_primitives(params: dict[str, float], pose: AnimalPose, min_radius: float = 0.0) -> list[Primitive]:
    """Posed primitives of one animal, in smooth-union merge order.

    Args:
        params: species shape parameters (``animal_shape.SHAPE_PARAMS``).
        pose: joint angles.
        min_radius: every radius/semi-axis is raised to at least this (body units); the mesher
            passes ~0.6 grid steps so that thin ears, tails and hooves survive sampling.

    Returns:
        primitives in body units (torso first, then neck, head, legs, tail).
    """
    b = _Builder(min_radius)
    trunk = _trunk(params, pose)
    _torso(b, params, trunk)
    _neck_and_head(b, params, pose, trunk)
    for leg, group in enumerate(LEG_GROUPS):
        _leg(b, params, pose, trunk, leg, group)
    _tail(b, params, pose, trunk)
    return b.prims
