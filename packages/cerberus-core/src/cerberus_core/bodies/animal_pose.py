"""Poses of the procedural quadrupeds and their deterministic generator.

A pose (:class:`~cerberus_core.bodies.animal_skeleton.AnimalPose`, joint angles in radians; sign
conventions in :mod:`cerberus_core.bodies.animal_skeleton`) is applied on top of a species' rest
skeleton.

The generator mixes gaits (stand, walk, trot, gallop) and behaviours (graze, alert, sit, lie) with
small per-joint noise; its ranges are deliberately smaller than for humans (as in the paper).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from cerberus_core.bodies.animal_sdf import primitives_bounds
from cerberus_core.bodies.animal_shape import AnimalSpecies
from cerberus_core.bodies.animal_skeleton import LEG_GROUPS, TORSO, AnimalPose, animal_primitives
from cerberus_core.errors import BodyError

POSE_KINDS: dict[str, float] = {
    "stand": 0.16,
    "walk": 0.24,
    "trot": 0.17,
    "gallop": 0.10,
    "graze": 0.12,
    "alert": 0.09,
    "sit": 0.07,
    "lie": 0.05,
}
"""Pose kinds and their sampling probabilities."""

LIMITS: dict[str, tuple[float, float]] = {
    "body_pitch": (-0.15, 1.0),
    "spine_yaw": (-0.35, 0.35),
    "spine_pitch": (-0.25, 0.2),
    "neck_raise": (-1.2, 0.6),
    "neck_yaw": (-0.6, 0.6),
    "head_pitch": (-0.7, 0.45),
    "head_yaw": (-0.8, 0.8),
    "tail_lift": (-0.8, 0.9),
    "tail_yaw": (-0.9, 0.9),
    "tail_curl": (-0.25, 0.3),
    "swing": (-1.1, 1.35),
    "bend": (0.0, 2.2),
    "abduct": (0.0, 0.2),
}
"""Joint limits (rad) every sampled pose is clipped to."""


def rest_pose() -> AnimalPose:
    """The rest pose: every joint at zero (standing square, neck at the species' rest angle)."""
    return AnimalPose()


@dataclass(frozen=True)
class SitConfiguration:
    """A species' sitting posture (radians): body pitch and the folded hind legs' swing and bend."""

    body_pitch: float
    hind_swing: float
    hind_bend: float
    rump_gap: float = 0.0
    """Height of the rump above the front feet, as a fraction of the front-leg height."""

    @property
    def feasible(self) -> bool:
        """Whether the species can sit (rump close to the ground); otherwise it lies down instead."""
        return self.rump_gap <= SIT_MAX_GAP


SIT_PITCH_RANGE: tuple[float, float] = (0.25, 0.9)
"""Body pitch searched for sitting (rad); long-legged species end at the top (front half raised)."""
SIT_MAX_GAP: float = 0.2
"""Largest rump gap (fraction of front-leg height) for which a species sits rather than lies."""


def sit_configuration(species: AnimalSpecies) -> SitConfiguration:
    """The species' sitting posture: thighs forward along the ground, shanks folded back, front
    legs vertical, and the body pitch (within :data:`SIT_PITCH_RANGE`) that brings the rump and
    folded hind legs level with the front feet (found by a 1-D search over the skeleton)."""
    return _sit_cached(tuple(sorted(species.params.items())))


@lru_cache(maxsize=256)
def _sit_cached(params_key: tuple[tuple[str, float], ...]) -> SitConfiguration:
    params = dict(params_key)
    hz = params["hind_angle"]
    bend = float(np.clip(2.8 - 1.05 * hz, 1.2, LIMITS["bend"][1] - 0.1))
    best, best_gap = SitConfiguration(SIT_PITCH_RANGE[1], 0.0, bend), np.inf
    for pitch in np.linspace(*SIT_PITCH_RANGE, 14):
        swing = float(np.clip(1.4 - pitch - 0.45 * hz, 0.3, LIMITS["swing"][1] - 0.1))
        cfg = SitConfiguration(float(pitch), swing, bend)
        pose = AnimalPose(kind="sit", legs=((-pitch, 0.0, 0.0),) * 2 + ((swing, bend, 0.05),) * 2, body_pitch=pitch)
        prims = animal_primitives(params, pose)
        front = primitives_bounds([q for q in prims if q.group in LEG_GROUPS[:2]])[0][1]
        hind = primitives_bounds([q for q in prims if q.group in LEG_GROUPS[2:] or q.group == TORSO])[0][1]
        gap = abs(hind - front)
        if gap < best_gap:
            best, best_gap = cfg, gap
    leg_height = params["leg_length"] + 0.9 * params["torso_height"]
    return SitConfiguration(best.body_pitch, best.hind_swing, best.hind_bend, float(best_gap / leg_height))


def _clip(name: str, v: float) -> float:
    lo, hi = LIMITS[name]
    return float(np.clip(v, lo, hi))


def _gait_legs(rng: np.random.Generator, kind: str, amp_scale: float) -> list[tuple[float, float, float]]:
    phase = rng.uniform()
    if kind == "walk":  # lateral sequence
        offsets, amp, flex = (0.25, 0.75, 0.0, 0.5), rng.uniform(0.18, 0.32), rng.uniform(0.4, 0.8)
    elif kind == "trot":  # diagonal pairs
        offsets, amp, flex = (0.0, 0.5, 0.5, 0.0), rng.uniform(0.28, 0.42), rng.uniform(0.6, 1.0)
    else:  # gallop / canter-like: fore pair and hind pair nearly together
        offsets, amp, flex = (0.1, 0.0, 0.6, 0.5), rng.uniform(0.4, 0.6), rng.uniform(0.7, 1.2)
    legs = []
    for off in offsets:
        t = 2 * np.pi * (phase + off)
        swing = amp_scale * amp * np.sin(t)
        bend = amp_scale * flex * max(0.0, np.cos(t)) + abs(rng.normal(0.0, 0.05))
        legs.append((swing + rng.normal(0.0, 0.04), bend, abs(rng.normal(0.0, 0.03))))
    return legs


def _standing_legs(rng: np.random.Generator) -> list[tuple[float, float, float]]:
    return [(rng.normal(0.0, 0.06), abs(rng.normal(0.0, 0.1)), abs(rng.normal(0.0, 0.04))) for _ in range(4)]


def sample_pose(species: AnimalSpecies, rng: np.random.Generator) -> AnimalPose:
    """Draw one pose for ``species`` (see :func:`sample_animal_poses`)."""
    p = species.params
    # long-legged animals swing their legs further than short-legged ones
    amp_scale = float(np.clip(0.55 + 0.5 * p["leg_length"] / p["torso_length"], 0.6, 1.05))
    kinds = list(POSE_KINDS)
    kind = kinds[int(rng.choice(len(kinds), p=np.array(list(POSE_KINDS.values())) / sum(POSE_KINDS.values())))]
    body_pitch = rng.normal(0.0, 0.03)
    spine_yaw, spine_pitch = rng.normal(0.0, 0.1), rng.normal(0.0, 0.05)
    neck_raise, neck_yaw = rng.normal(0.0, 0.15), rng.normal(0.0, 0.15)
    head_pitch, head_yaw = rng.normal(0.0, 0.12), rng.normal(0.0, 0.25)
    tail_lift, tail_yaw, tail_curl = rng.normal(0.0, 0.25), rng.normal(0.0, 0.35), rng.normal(0.0, 0.08)
    if kind == "sit" and not sit_configuration(species).feasible:
        kind = "lie"  # long-legged species cannot sit: they lie down (sternal, legs folded) instead
    if kind in ("walk", "trot", "gallop"):
        legs = _gait_legs(rng, kind, amp_scale)
        if kind == "gallop":
            spine_pitch += rng.uniform(-0.15, 0.1)
            neck_raise += rng.uniform(-0.3, 0.1)
            tail_lift += rng.uniform(0.0, 0.4)
    elif kind == "lie":
        hz = p["hind_angle"]  # hind thighs forward along the ground, shanks folded back
        legs = [(rng.uniform(0.1, 0.4), rng.uniform(1.9, 2.2), abs(rng.normal(0.0, 0.03))) for _ in range(2)]
        legs += [
            (1.4 - 0.45 * hz + rng.normal(0.0, 0.08), 2.8 - 1.05 * hz + rng.normal(0.0, 0.08), 0.08) for _ in range(2)
        ]
        neck_raise += rng.uniform(0.0, 0.3)
        tail_lift -= rng.uniform(0.2, 0.5)
    elif kind == "sit":
        sit = sit_configuration(species)
        body_pitch = sit.body_pitch + rng.normal(0.0, 0.04)
        legs = _standing_legs(rng)
        for i in (0, 1):  # front legs roughly vertical in the world
            legs[i] = (-body_pitch + rng.normal(0.0, 0.05), abs(rng.normal(0.0, 0.08)), legs[i][2])
        for i in (2, 3):  # hind legs folded under the body
            legs[i] = (
                sit.hind_swing + rng.normal(0.0, 0.08),
                sit.hind_bend + rng.normal(0.0, 0.08),
                0.05 + abs(rng.normal(0.0, 0.04)),
            )
        neck_raise -= 0.5 * body_pitch
        tail_lift -= rng.uniform(0.2, 0.6)
    else:
        legs = _standing_legs(rng)
        if kind == "graze":
            neck_raise = -rng.uniform(0.6, 1.1)
            head_pitch = -rng.uniform(0.2, 0.6)
        elif kind == "alert":
            neck_raise = rng.uniform(0.2, 0.5)
            head_pitch = rng.uniform(0.0, 0.3)
            head_yaw = rng.normal(0.0, 0.4)
    legs = [(_clip("swing", s), _clip("bend", b), _clip("abduct", a)) for s, b, a in legs]
    return AnimalPose(
        kind=kind,
        legs=tuple(legs),
        body_pitch=_clip("body_pitch", body_pitch),
        spine_yaw=_clip("spine_yaw", spine_yaw),
        spine_pitch=_clip("spine_pitch", spine_pitch),
        neck_raise=_clip("neck_raise", neck_raise),
        neck_yaw=_clip("neck_yaw", neck_yaw),
        head_pitch=_clip("head_pitch", head_pitch),
        head_yaw=_clip("head_yaw", head_yaw),
        tail_lift=_clip("tail_lift", tail_lift),
        tail_yaw=_clip("tail_yaw", tail_yaw),
        tail_curl=_clip("tail_curl", tail_curl),
    )


def sample_animal_poses(species: AnimalSpecies, rng: np.random.Generator, n: int) -> list[AnimalPose]:
    """Draw ``n`` poses for ``species`` from ``rng`` (deterministic given the generator state).

    Kinds are drawn with :data:`POSE_KINDS` probabilities; gait poses take a random phase of a
    walk/trot/gallop cycle; every angle gets small Gaussian noise and is clipped to :data:`LIMITS`.

    Args:
        species: the species (its leg length scales gait amplitudes).
        rng: numpy generator, advanced by the call.
        n: number of poses (>= 0).

    Returns:
        ``n`` poses.
    """
    if n < 0:
        raise BodyError(f"sample_animal_poses: n must be >= 0, got {n}")
    return [sample_pose(species, rng) for _ in range(n)]


def animal_pose_splits(
    species: AnimalSpecies, n_train: int = 47, n_test: int = 3, seed: int = 0
) -> tuple[list[AnimalPose], list[AnimalPose]]:
    """The species' fixed train and test poses (the paper uses 47 + 3).

    Train and test poses come from two independent generators seeded by ``(seed, crc32(name), split)``,
    so asking for fewer train poses gives a prefix of the full list and never changes the test poses.

    Returns:
        ``(train_poses, test_poses)``.
    """
    key = zlib.crc32(species.name.encode())
    train = sample_animal_poses(species, np.random.default_rng([int(seed), key, 0]), n_train)
    test = sample_animal_poses(species, np.random.default_rng([int(seed), key, 1]), n_test)
    return train, test


def envelope_poses(species: AnimalSpecies) -> list[AnimalPose]:
    """Extreme poses used to fix a species' normalisation scale (see ``animal.species_scale``).

    They push the body's reach to the generator's limits along each axis: rest; tallest standing
    (neck vertical, nose and tail up); longest (neck and tail horizontal, legs stretched fore and
    aft, back swayed either way); grazing; and, for species that sit, the tallest and the most
    folded sit (lying down is more compact than standing and needs no envelope pose).
    """
    p = species.params
    c = _clip
    vertical = np.pi / 2 - p["neck_angle"]
    stretched = ((0.65, 0.0, 0.0),) * 2 + ((-0.65, 0.0, 0.0),) * 2
    flat_neck = c("neck_raise", -p["neck_angle"])
    head_level = c("head_pitch", 0.35 - 0.4 * flat_neck)
    tail_level = c("tail_lift", p["tail_droop"])
    poses = [
        rest_pose(),
        AnimalPose(
            kind="envelope",
            neck_raise=c("neck_raise", vertical),
            head_pitch=LIMITS["head_pitch"][1],
            tail_lift=LIMITS["tail_lift"][1],
        ),
        *(AnimalPose(kind="envelope", legs=stretched, spine_pitch=LIMITS["spine_pitch"][end], neck_raise=flat_neck,
                     head_pitch=head_level, tail_lift=tail_level) for end in (1, 0)),  # the spine's two limits
        AnimalPose(kind="envelope", neck_raise=LIMITS["neck_raise"][0], head_pitch=LIMITS["head_pitch"][0]),
    ]
    cfg = sit_configuration(species)
    if cfg.feasible:
        sit = cfg.body_pitch + 0.1
        folded = ((-sit, 0.0, 0.0),) * 2 + ((cfg.hind_swing, cfg.hind_bend, 0.1),) * 2
        poses += [
            AnimalPose(
                kind="envelope",
                legs=folded,
                body_pitch=sit,
                neck_raise=c("neck_raise", vertical - sit),
                head_pitch=LIMITS["head_pitch"][1],
            ),
            AnimalPose(kind="envelope", legs=folded, body_pitch=sit, tail_lift=LIMITS["tail_lift"][0]),
        ]
    return poses
