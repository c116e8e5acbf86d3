"""Articulated capsule figures: a small, fast, dependency-free body source ("primitives").

Each subject is a stick figure of 10 capsules (head, torso, upper/lower arms, thighs, shins) with its
own proportions; a pose is a vector of joint angles in degrees (:data:`DOF_NAMES`) within joint
limits. Meshes are tiny (about 700 vertices), so datasets of these bodies generate in seconds: the
source behind the ``primitives`` dataset, handy for tests, debugging and quick experiments.

Frames and units follow :mod:`cerberus_core.bodies.body` (+Y up, facing +Z, normalised units).
Pose ids: ``0`` is the canonical pose (standing, arms 20 degrees from the body), ``k >= 1`` is drawn
from ``numpy.random.default_rng([subject.pose_seed, k])``. Scale rule (as for the anny humans): one
scale per subject, :func:`~cerberus_core.bodies.body.normalise_subject` over a fixed reference set
(the canonical pose plus :data:`REFERENCE_POSES` poses drawn from ``default_rng(REFERENCE_SEED)``);
each pose is centred on its own bounding-box centre.
"""
from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import trimesh

from cerberus_core.bodies.body import FILL, PosedBody, normalise_subject
from cerberus_core.errors import BodyError

PART_NAMES: list[str] = ["head", "torso", "upper_arm.L", "lower_arm.L", "upper_arm.R", "lower_arm.R",
                         "thigh.L", "shin.L", "thigh.R", "shin.R"]
"""One part per capsule (``.L`` is the figure's own left, at +X)."""

# (name, low, high) in degrees. Signs are anatomical: flexion swings a limb forward (+Z), knee
# flexion folds the shin backward, abduction lifts a limb sideways away from the body.
_DOFS: list[tuple[str, float, float]] = [
    ("spine_flex", -10.0, 30.0), ("spine_side", -15.0, 15.0), ("spine_twist", -30.0, 30.0),
    ("neck_flex", -20.0, 30.0), ("neck_twist", -40.0, 40.0),
    ("shoulder_flex.L", -40.0, 120.0), ("shoulder_abd.L", 10.0, 90.0), ("elbow_flex.L", 0.0, 120.0),
    ("shoulder_flex.R", -40.0, 120.0), ("shoulder_abd.R", 10.0, 90.0), ("elbow_flex.R", 0.0, 120.0),
    ("hip_flex.L", -20.0, 90.0), ("hip_abd.L", 0.0, 35.0), ("knee_flex.L", 0.0, 110.0),
    ("hip_flex.R", -20.0, 90.0), ("hip_abd.R", 0.0, 35.0), ("knee_flex.R", 0.0, 110.0),
]
DOF_NAMES: list[str] = [d[0] for d in _DOFS]
DOF_LIMITS: np.ndarray = np.array([[lo, hi] for _, lo, hi in _DOFS])
"""``(D, 2)`` joint limits in degrees."""

REFERENCE_SEED = 7_2024
REFERENCE_POSES = 32
CAPSULE_COUNT = (10, 8)
"""Capsule tessellation passed to :func:`trimesh.creation.capsule` (same for every figure, so all
primitive bodies share one topology)."""


@dataclass(frozen=True)
class PrimitiveSubject:
    """One capsule figure: ``proportions`` in body units (see :func:`sample_subjects`)."""

    subject_id: str
    proportions: dict[str, float]
    pose_seed: int

    def __hash__(self) -> int:
        return hash(self.subject_id)


_RANGES = {
    "torso_length": (0.45, 0.60), "torso_radius": (0.10, 0.15), "head_radius": (0.08, 0.11),
    "neck_length": (0.03, 0.07), "upper_arm": (0.25, 0.32), "lower_arm": (0.24, 0.30),
    "arm_radius": (0.035, 0.055), "thigh": (0.38, 0.48), "shin": (0.36, 0.45), "leg_radius": (0.05, 0.075),
}


def _split_code(split: str) -> int:
    return int.from_bytes(hashlib.sha256(f"cerberus-primitives-{split}".encode()).digest()[:4], "little")


def sample_subjects(n: int, seed: int = 0, split: str = "train") -> list[PrimitiveSubject]:
    """``n`` figures of one split; subject ``i`` comes from ``default_rng([split_code, seed, i])``, so
    different splits never share a subject and fewer subjects are a prefix of more."""
    if n < 0 or seed < 0:
        raise BodyError(f"sample_subjects needs n >= 0 and seed >= 0, got n={n}, seed={seed}")
    out = []
    for i in range(n):
        rng = np.random.default_rng([_split_code(split), seed, i])
        props = {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in _RANGES.items()}
        out.append(PrimitiveSubject(f"{split}-p{seed}-{i}", props, int(rng.integers(0, 2**31 - 1))))
    return out


def canonical_pose() -> np.ndarray:
    """``(D,)`` degrees: standing straight, arms 20 degrees away from the body."""
    pose = np.zeros(len(_DOFS))
    pose[DOF_NAMES.index("shoulder_abd.L")] = pose[DOF_NAMES.index("shoulder_abd.R")] = 20.0
    return pose


def sample_poses(rng: np.random.Generator, n: int) -> np.ndarray:
    """``(n, D)`` joint angles in degrees, uniform within :data:`DOF_LIMITS`."""
    return DOF_LIMITS[:, 0] + rng.random((n, len(_DOFS))) * (DOF_LIMITS[:, 1] - DOF_LIMITS[:, 0])


def _rot(axis: str, deg: np.ndarray) -> np.ndarray:
    """``(n,)`` degrees → ``(n, 3, 3)`` rotations about a world axis."""
    a = np.deg2rad(deg)
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    m = {"x": [o, z, z, z, c, -s, z, s, c], "y": [c, z, s, z, o, z, -s, z, c], "z": [c, -s, z, s, c, z, z, z, o]}[axis]
    return np.stack(m, -1).reshape(-1, 3, 3)


@lru_cache(maxsize=1)
def _unit_capsule() -> tuple[np.ndarray, np.ndarray]:
    """A capsule with a cylinder of length 1 and radius 1 along +Z, centred: ``(vertices, faces)``; the
    cylinder is stretched to each segment's length in :meth:`PrimitiveBodySource._capsule`."""
    m = trimesh.creation.capsule(height=1.0, radius=1.0, count=list(CAPSULE_COUNT))
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


class PrimitiveBodySource:
    """Poses capsule figures into :class:`PosedBody` records.

    Attributes:
        part_names: :data:`PART_NAMES`.
        faces: ``(F, 3)`` int64, shared by all figures and poses.
        vertex_parts: ``(V,)`` int16 part of each vertex.
    """

    def __init__(self) -> None:
        self.part_names = list(PART_NAMES)
        cv, cf = _unit_capsule()
        n = len(cv)
        self.faces = np.concatenate([cf + k * n for k in range(len(PART_NAMES))])
        self.vertex_parts = np.repeat(np.arange(len(PART_NAMES), dtype=np.int16), n)
        self._scale: dict[str, float] = {}

    def pose_params(self, subject: PrimitiveSubject, pose_ids: Sequence[int]) -> np.ndarray:
        """``(len(pose_ids), D)`` degrees; id 0 is canonical, id ``k`` from ``default_rng([pose_seed, k])``."""
        rows = []
        for pid in pose_ids:
            if pid < 0:
                raise BodyError(f"pose ids must be >= 0, got {pid}")
            rng = np.random.default_rng([subject.pose_seed, int(pid)])
            rows.append(canonical_pose() if pid == 0 else sample_poses(rng, 1)[0])
        return np.stack(rows) if rows else np.zeros((0, len(_DOFS)))

    @staticmethod
    def _capsule(start: np.ndarray, rot: np.ndarray, length: float, radius: float, down: bool) -> np.ndarray:
        """``(n, Vc, 3)`` capsule vertices of a segment starting at ``start`` ``(n, 3)`` whose frame is
        ``rot`` ``(n, 3, 3)``; the rest direction is -Y (``down``) or +Y."""
        cv, _ = _unit_capsule()
        sign = np.sign(cv[:, 2])
        local = cv * radius
        local[:, 2] = (cv[:, 2] - 0.5 * sign) * radius + 0.5 * sign * length  # stretch the cylinder only
        local[:, 2] += 0.5 * length  # starts at the joint, runs along +Z
        flip = -1.0 if down else 1.0
        to_rest = np.array([[1.0, 0, 0], [0, 0, flip], [0, -flip, 0]])
        rest = local @ to_rest.T  # +Z -> -Y (down) or +Y (up)
        return np.einsum("nij,vj->nvi", rot, rest) + start[:, None]

    def raw_vertices(self, subject: PrimitiveSubject, poses: np.ndarray) -> np.ndarray:
        """``(n, V, 3)`` posed vertices in body units (pelvis at the origin), before normalisation."""
        p = subject.proportions
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, len(_DOFS))
        n = len(poses)
        a = {name: poses[:, i] for i, name in enumerate(DOF_NAMES)}
        zero = np.zeros((n, 3))
        spine = _rot("y", a["spine_twist"]) @ _rot("z", -a["spine_side"]) @ _rot("x", a["spine_flex"])
        chest = spine @ np.array([0.0, p["torso_length"], 0.0])
        neck = spine @ _rot("y", a["neck_twist"]) @ _rot("x", a["neck_flex"])
        parts = [
            self._capsule(chest, neck, p["neck_length"] + p["head_radius"], p["head_radius"], down=False),
            self._capsule(zero, spine, p["torso_length"], p["torso_radius"], down=False),
        ]
        for side, sgn in (("L", 1.0), ("R", -1.0)):
            shoulder = spine @ np.array([sgn * (p["torso_radius"] + p["arm_radius"]), 0.92 * p["torso_length"], 0.0])
            upper = spine @ _rot("x", -a[f"shoulder_flex.{side}"]) @ _rot("z", sgn * a[f"shoulder_abd.{side}"])
            elbow = shoulder + upper @ np.array([0.0, -p["upper_arm"], 0.0])
            lower = upper @ _rot("x", -a[f"elbow_flex.{side}"])
            parts += [self._capsule(shoulder, upper, p["upper_arm"], p["arm_radius"], down=True),
                      self._capsule(elbow, lower, p["lower_arm"], 0.9 * p["arm_radius"], down=True)]
        for side, sgn in (("L", 1.0), ("R", -1.0)):
            hip = np.array([sgn * 0.55 * p["torso_radius"], 0.0, 0.0]) + zero
            thigh = _rot("x", -a[f"hip_flex.{side}"]) @ _rot("z", sgn * a[f"hip_abd.{side}"])
            knee = hip + thigh @ np.array([0.0, -p["thigh"], 0.0])
            shin = thigh @ _rot("x", a[f"knee_flex.{side}"])
            parts += [self._capsule(hip, thigh, p["thigh"], p["leg_radius"], down=True),
                      self._capsule(knee, shin, p["shin"], 0.85 * p["leg_radius"], down=True)]
        return np.concatenate(parts, axis=1)

    def subject_scale(self, subject: PrimitiveSubject) -> float:
        """Normalised units per body unit, shared by all poses of the subject (see module docstring)."""
        if subject.subject_id not in self._scale:
            sampled = sample_poses(np.random.default_rng(REFERENCE_SEED), REFERENCE_POSES)
            ref = np.concatenate([canonical_pose()[None], sampled])
            scale, _ = normalise_subject(list(self.raw_vertices(subject, ref)), fill=FILL)
            self._scale[subject.subject_id] = scale
        return self._scale[subject.subject_id]

    def posed_bodies(self, subject: PrimitiveSubject, pose_ids: Sequence[int]) -> list[PosedBody]:
        """Normalised bodies of one subject in the poses ``pose_ids``.

        Raises:
            ValueError: if a pose leaves ``[-0.5, 0.5]^3`` after the subject's scale.
        """
        params = self.pose_params(subject, pose_ids)
        scale = self.subject_scale(subject)
        out = []
        for pid, v, q in zip(pose_ids, self.raw_vertices(subject, params), params, strict=True):
            vn = (v - 0.5 * (v.max(0) + v.min(0))) * scale
            if np.abs(vn).max() > 0.5:
                raise BodyError(f"{subject.subject_id} pose {pid} leaves the unit cube after scaling")
            out.append(PosedBody(vn.astype(np.float32), self.faces, self.vertex_parts, self.part_names,
                                 subject.subject_id, int(pid), meta={"pose_params": q}))
        return out
