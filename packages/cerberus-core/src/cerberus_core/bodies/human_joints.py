"""The joint angles of the anny humans: the pose vector's degrees of freedom, their bones, axes and
limits (degrees).

A pose of :mod:`cerberus_core.bodies.human` is a vector of ``len(DOF_NAMES)`` angles in this order;
:mod:`cerberus_core.bodies.human` samples and applies them, :mod:`cerberus_core.bodies.human_motion`
animates them. Both build on this table (and neither on the other's internals).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Dof:
    """One joint angle: rotates ``bones`` (label, fraction of the angle) about ``axis``.

    ``axis`` is a unit vector in anny's rest frame, ``"bone:<a>><b>"`` for the rest direction of the
    limb segment from bone head ``a`` to bone head ``b`` (a twist), or ``"flex:<a>><b>><c>"`` for a
    hinge at head ``b`` folding segment ``b>c`` away from segment ``a>b``: the axis is
    ``(b - a) x (c - b)`` and the angle is measured from the *straight* limb (anny's rest pose bends
    it slightly; that rest bend, taken from the default body, is subtracted).
    """

    name: str
    bones: tuple[tuple[str, float], ...]
    axis: tuple[float, float, float] | str
    low: float  # degrees
    high: float  # degrees
    straight_prob: float = 0.0  # probability of drawing a near-straight joint in [low, low + 10]


_X, _Y, _Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
_NEG_X, _NEG_Y = (-1.0, 0.0, 0.0), (0.0, -1.0, 0.0)

_CENTRAL_DOFS: tuple[Dof, ...] = (
    # Spine bend spread over the three upper spine bones.
    Dof("spine_flex", (("spine03", 1 / 3), ("spine02", 1 / 3), ("spine01", 1 / 3)), _X, -15.0, 45.0),
    Dof("spine_side", (("spine03", 1 / 3), ("spine02", 1 / 3), ("spine01", 1 / 3)), _Y, -20.0, 20.0),
    Dof("spine_twist", (("spine03", 1 / 3), ("spine02", 1 / 3), ("spine01", 1 / 3)), _Z, -35.0, 35.0),
    Dof("neck_flex", (("neck01", 0.5), ("head", 0.5)), _X, -30.0, 40.0),
    Dof("neck_side", (("neck01", 0.5), ("head", 0.5)), _Y, -25.0, 25.0),
    Dof("neck_twist", (("neck01", 0.5), ("head", 0.5)), _Z, -50.0, 50.0),
)

# Left-side limbs; the right side mirrors them. Angles of one bone compose in list order
# (R = R_first @ R_second @ ...: the last one acts first, in the rest frame).
_LEFT_DOFS: tuple[Dof, ...] = (
    Dof("hip_flex", (("upperleg01", 1.0),), _NEG_X, -20.0, 100.0),
    Dof("hip_abd", (("upperleg01", 1.0),), _NEG_Y, -5.0, 40.0),
    Dof("hip_twist", (("upperleg01", 1.0),), "bone:upperleg01>lowerleg01", -30.0, 30.0),
    Dof("knee_flex", (("lowerleg01", 1.0),), _X, 0.0, 115.0, straight_prob=0.4),
    Dof("ankle_flex", (("foot", 1.0),), _NEG_X, -30.0, 20.0),
    Dof("shoulder_flex", (("upperarm01", 1.0),), _NEG_X, -30.0, 90.0),
    Dof("shoulder_abd", (("upperarm01", 1.0),), _NEG_Y, -20.0, 80.0),
    Dof("shoulder_twist", (("upperarm01", 1.0),), "bone:upperarm01>lowerarm01", -45.0, 45.0),
    Dof("elbow_flex", (("lowerarm01", 1.0),), "flex:upperarm01>lowerarm01>wrist", 0.0, 140.0, straight_prob=0.4),
    Dof("forearm_twist", (("lowerarm02", 1.0),), "bone:lowerarm01>wrist", -40.0, 40.0),
)


def _side(dof: Dof, side: str) -> Dof:
    bones = tuple((f"{bone}.{side}", w) for bone, w in dof.bones)
    axis = dof.axis
    if isinstance(axis, str):
        kind, segment = axis.split(":")
        axis = f"{kind}:" + ">".join(f"{b}.{side}" for b in segment.split(">"))
    return Dof(f"{dof.name}.{side}", bones, axis, dof.low, dof.high, dof.straight_prob)


DOFS: tuple[Dof, ...] = (
    _CENTRAL_DOFS + tuple(_side(d, "L") for d in _LEFT_DOFS) + tuple(_side(d, "R") for d in _LEFT_DOFS)
)
DOF_NAMES: list[str] = [d.name for d in DOFS]
"""Names of the pose vector's entries (degrees), in order."""
DOF_LIMITS: np.ndarray = np.array([[d.low, d.high] for d in DOFS], dtype=np.float64)
"""``(D, 2)`` lower/upper joint limits in degrees; the canonical pose (zeros) lies inside."""
DOF_INDEX: dict[str, int] = {name: j for j, name in enumerate(DOF_NAMES)}
"""``{dof name: its entry in the pose vector}``."""


def random_side(rng: np.random.Generator) -> tuple[str, str]:
    """``(moving side, other side)``: ``("L", "R")`` or ``("R", "L")``, each with probability 1/2 (one uniform
    drawn), for a pose whose one side moves (a motion primitive, a held-out family)."""
    return ("L", "R") if rng.random() < 0.5 else ("R", "L")
