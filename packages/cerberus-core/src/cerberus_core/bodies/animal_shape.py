"""Procedural quadruped species: shape parameters, archetypes and the deterministic species sampler.

A species is a dictionary of shape parameters (:data:`SHAPE_PARAMS`). Lengths are in *body units*
(the torso is about one unit long; the absolute size is irrelevant because every species is later
normalised to the unit cube), angles in radians, the rest are dimensionless ratios. Species are
drawn around hand-made archetypes that span the range the paper's SMAL set covers, from deer (small
head, long thin legs) to hippopotamuses (large head, short thick legs).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cerberus_core.errors import BodyError

SHAPE_PARAMS: dict[str, str] = {
    "torso_length": "torso length, rump to chest (body units)",
    "torso_height": "vertical semi-axis of the belly (body units)",
    "torso_width": "lateral semi-axis of the belly (body units)",
    "chest_scale": "chest girth relative to the belly (ratio)",
    "leg_length": "ground clearance under the belly in the rest pose (body units)",
    "leg_radius": "upper-leg radius (body units)",
    "leg_taper": "lower-leg radius / upper-leg radius (ratio)",
    "paw_size": "foot (paw or hoof) radius / lower-leg radius (ratio)",
    "hind_angle": "zig-zag of the hind leg: thigh forward, shank backward (rad, scaled)",
    "neck_length": "neck length from its base inside the chest (body units)",
    "neck_radius": "neck radius at its base (body units)",
    "neck_angle": "rest elevation of the neck above the horizontal (rad)",
    "head_size": "cranium radius (body units)",
    "snout_length": "snout length / head_size (ratio)",
    "snout_width": "snout radius / head_size (ratio)",
    "ear_length": "ear length / head_size (ratio)",
    "ear_width": "ear width / ear length (ratio)",
    "ear_droop": "0 = upright ears, 1 = hanging ears",
    "horn_length": "horn length / head_size (ratio, 0 = no horns)",
    "tail_length": "tail length (body units)",
    "tail_radius": "tail radius at its base (body units)",
    "tail_droop": "rest angle of the tail below the horizontal (rad)",
    "tail_bush": "bulge of the tail's middle (0 = thin tapering tail, 1 = bushy)",
}
"""Shape parameter names with their meaning and unit."""

_ANGLE_PARAMS = {"neck_angle", "tail_droop", "hind_angle"}
_UNIT_PARAMS = {"ear_droop", "tail_bush"}  # kept in [0, 1]

# Archetype parameter centres, in SHAPE_PARAMS order. Ordered so that the first few species already
# span the range (deer, hippo, dog, cat, horse, ...).
_P = list(SHAPE_PARAMS)
# fmt: off
_ARCHETYPE_ROWS: dict[str, tuple[str, list[float]]] = {
    # line 1: torso_length torso_height torso_width chest_scale leg_length leg_radius leg_taper paw_size hind_angle
    # line 2: neck_length neck_radius neck_angle head_size snout_length snout_width ear_length ear_width ear_droop
    #         horn_length tail_length tail_radius tail_droop tail_bush
    "deer": ("deer-like: thin long legs, long neck, small head", [
        1.000, 0.170, 0.140, 1.000, 0.820, 0.042, 0.500, 1.000, 0.900,
        0.500, 0.075, 0.950, 0.085, 1.700, 0.450, 1.500, 0.500, 0.100, 0.000, 0.120, 0.035, 0.300, 0.500]),
    "hippo": ("hippo-like: barrel body, short thick legs, huge head", [
        1.200, 0.340, 0.340, 1.050, 0.150, 0.120, 0.850, 1.100, 0.300,
        0.120, 0.260, 0.100, 0.220, 1.400, 0.850, 0.250, 0.800, 0.000, 0.000, 0.180, 0.035, 1.200, 0.000]),
    "dog": ("dog-like: medium legs, pointed ears, medium tail", [
        0.900, 0.170, 0.130, 1.100, 0.470, 0.050, 0.550, 1.300, 1.000,
        0.320, 0.080, 0.700, 0.100, 1.200, 0.400, 0.900, 0.600, 0.000, 0.000, 0.500, 0.045, 0.800, 0.600]),
    "cat": ("cat-like: short face, long thin tail, big paws", [
        0.800, 0.140, 0.120, 1.000, 0.350, 0.040, 0.600, 1.400, 1.100,
        0.200, 0.070, 0.500, 0.090, 0.450, 0.450, 0.800, 0.800, 0.000, 0.000, 0.850, 0.025, 0.900, 0.000]),
    "horse": ("horse-like: long legs, long head, flowing tail", [
        1.100, 0.220, 0.180, 1.000, 0.780, 0.060, 0.550, 1.100, 1.000,
        0.600, 0.110, 0.850, 0.110, 2.200, 0.500, 0.800, 0.500, 0.000, 0.000, 0.600, 0.060, 1.100, 0.600]),
    "cow": ("cow-like: heavy body, medium legs, horns", [
        1.150, 0.300, 0.250, 1.000, 0.480, 0.080, 0.600, 1.100, 0.800,
        0.350, 0.170, 0.400, 0.130, 1.500, 0.650, 0.800, 0.550, 0.600, 0.800, 0.700, 0.030, 1.400, 0.000]),
    "weasel": ("dachshund/weasel-like: long low body, very short legs", [
        1.100, 0.120, 0.110, 1.000, 0.160, 0.040, 0.700, 1.300, 0.600,
        0.250, 0.065, 0.400, 0.080, 1.000, 0.400, 0.600, 0.700, 0.600, 0.000, 0.450, 0.030, 0.600, 0.200]),
    "gazelle": ("gazelle-like: very slender legs, thin horns", [
        0.950, 0.150, 0.120, 1.000, 0.890, 0.035, 0.500, 1.000, 0.900,
        0.450, 0.060, 0.900, 0.075, 1.600, 0.400, 1.600, 0.400, 0.100, 2.000, 0.120, 0.030, 0.400, 0.300]),
    "pig": ("pig-like: round body, short legs, snout", [
        1.000, 0.260, 0.240, 1.000, 0.210, 0.070, 0.700, 1.000, 0.500,
        0.150, 0.200, 0.200, 0.140, 1.300, 0.550, 0.800, 0.800, 0.500, 0.000, 0.180, 0.020, 0.800, 0.000]),
    "lion": ("big-cat-like: powerful forequarters, long tail", [
        1.000, 0.190, 0.160, 1.100, 0.410, 0.065, 0.650, 1.400, 1.000,
        0.250, 0.110, 0.450, 0.130, 0.600, 0.550, 0.450, 1.000, 0.000, 0.000, 0.850, 0.035, 1.000, 0.100]),
    "rhino": ("rhino-like: massive body, thick legs, long head", [
        1.200, 0.320, 0.300, 1.050, 0.240, 0.110, 0.800, 1.100, 0.400,
        0.200, 0.220, 0.150, 0.180, 1.600, 0.700, 0.500, 0.600, 0.000, 0.600, 0.200, 0.030, 1.300, 0.000]),
    "llama": ("llama-like: very long upright neck", [
        1.000, 0.180, 0.150, 1.000, 0.810, 0.050, 0.550, 1.100, 0.900,
        0.750, 0.075, 1.250, 0.080, 1.400, 0.450, 1.300, 0.450, 0.000, 0.000, 0.150, 0.040, 0.700, 0.500]),
    "bear": ("bear-like: bulky, thick legs, small ears, stub tail", [
        1.000, 0.260, 0.240, 1.100, 0.320, 0.100, 0.750, 1.300, 0.300,
        0.250, 0.160, 0.350, 0.130, 0.900, 0.500, 0.400, 1.000, 0.000, 0.000, 0.060, 0.040, 0.800, 0.000]),
    "fox": ("fox-like: short legs, pointed snout, bushy tail", [
        0.850, 0.140, 0.110, 1.050, 0.350, 0.038, 0.600, 1.300, 1.000,
        0.250, 0.065, 0.550, 0.085, 1.300, 0.350, 1.200, 0.650, 0.000, 0.000, 0.600, 0.055, 0.600, 1.000]),
    "goat": ("goat-like: compact, medium legs, swept horns", [
        0.900, 0.200, 0.160, 1.000, 0.550, 0.050, 0.550, 1.000, 0.800,
        0.350, 0.090, 0.800, 0.090, 1.500, 0.450, 1.000, 0.500, 0.400, 1.500, 0.120, 0.030, 0.100, 0.300]),
    "hound": ("hound-like: long legs, hanging ears", [
        0.950, 0.170, 0.130, 1.100, 0.570, 0.048, 0.550, 1.200, 1.000,
        0.350, 0.080, 0.650, 0.100, 1.400, 0.400, 1.100, 0.600, 0.950, 0.000, 0.500, 0.035, 0.900, 0.100]),
}
# fmt: on
ARCHETYPES: dict[str, dict[str, float]] = {
    k: dict(zip(_P, row, strict=True)) for k, (_, row) in _ARCHETYPE_ROWS.items()
}
"""Archetype name -> parameter centre."""

SPECIES_JITTER: float = 0.08
"""Log-normal sigma of the per-parameter species jitter (angles: additive, in rad)."""
MAX_MIX: float = 0.3
"""Largest weight with which a species leans towards a second, random archetype."""


@dataclass(frozen=True)
class AnimalSpecies:
    """One procedural quadruped species.

    Attributes:
        name: identifier, e.g. ``"species_07_cow"`` (used as the ``PosedBody.subject``).
        params: shape parameters, keys :data:`SHAPE_PARAMS` (do not mutate).
        archetype: the archetype the species was drawn around (a key of :data:`ARCHETYPES`).
    """

    name: str
    params: dict[str, float]
    archetype: str = field(default="")

    def __post_init__(self) -> None:
        missing = set(SHAPE_PARAMS) - set(self.params)
        if missing:
            raise BodyError(f"AnimalSpecies {self.name}: missing shape parameters {sorted(missing)}")
        bad = {k: v for k, v in self.params.items() if not np.isfinite(v)}
        if bad:
            raise BodyError(f"AnimalSpecies {self.name}: non-finite parameters {bad}")


def archetype_species(archetype: str, name: str | None = None) -> AnimalSpecies:
    """The species sitting exactly at an archetype's parameter centre."""
    if archetype not in ARCHETYPES:
        raise BodyError(f"unknown archetype {archetype!r}; known: {sorted(ARCHETYPES)}")
    return AnimalSpecies(name=name or archetype, params=dict(ARCHETYPES[archetype]), archetype=archetype)


def sample_species(n: int = 41, seed: int = 0) -> list[AnimalSpecies]:
    """Draw ``n`` species deterministically.

    Species ``i`` uses archetype ``i mod 16`` (in :data:`ARCHETYPES` order, so any prefix spans deer
    to hippo), leans towards a second random archetype with weight ``U(0, MAX_MIX)`` and then jitters
    every parameter (log-normal, sigma :data:`SPECIES_JITTER`; angles additive). Species ``i`` depends
    only on ``(seed, i)``, so ``sample_species(5)`` is a prefix of ``sample_species(41)``.

    Args:
        n: number of species (>= 1).
        seed: integer seed.

    Returns:
        ``n`` species named ``species_{i:02d}_{archetype}``.
    """
    if n < 1:
        raise BodyError(f"sample_species: n must be >= 1, got {n}")
    names = list(ARCHETYPES)
    out = []
    for i in range(n):
        rng = np.random.default_rng([int(seed), i])
        arch = names[i % len(names)]
        other = names[int(rng.integers(len(names)))]
        w = float(rng.uniform(0.0, MAX_MIX))
        noise = rng.normal(0.0, SPECIES_JITTER, size=len(_P))
        params = {}
        for key, eps in zip(_P, noise, strict=True):
            v = (1 - w) * ARCHETYPES[arch][key] + w * ARCHETYPES[other][key]
            if key in _ANGLE_PARAMS:
                v = v + eps
            elif key in _UNIT_PARAMS:
                v = float(np.clip(v + eps, 0.0, 1.0))
            else:
                v = v * float(np.exp(eps))
            params[key] = float(v)
        if ARCHETYPES[arch]["horn_length"] == 0.0:  # hornless archetypes stay hornless
            params["horn_length"] = 0.0
        out.append(AnimalSpecies(name=f"species_{i:02d}_{arch}", params=params, archetype=arch))
    return out
