"""Procedural quadrupeds: the animal body source (our stand-in for the licence-gated SMAL set).

Pipeline for one (species, pose): forward kinematics turns the species' shape parameters and the
pose's joint angles into posed SDF primitives (:mod:`.animal_skeleton`); their smooth union is
sampled on a grid (:mod:`.animal_sdf`), meshed by a crack-free marching cubes and decimated to a
face budget with topology preserved (:mod:`.animal_mesh`); each vertex is labelled with the part
whose primitives are nearest. The result is a watertight :class:`~cerberus_core.bodies.body.PosedBody`.

Scale rule (``normalise_subject`` semantics with a scale that never depends on which poses are
generated): a species' scale is ``FILL / species_extent(species)``, where ``species_extent`` is the
largest axis-aligned extent, in body units, of the union of the species' primitives over its fixed
:func:`~cerberus_core.bodies.animal_pose.envelope_poses` (rest; neck vertical; sitting tall; neck and
tail horizontal with legs stretched; grazing; folded sit). Every pose is centred on its own
bounding-box centre and multiplied by that scale. Over 41 species x 250 sampled poses the largest
pose extent is 0.99 x the envelope (mean 0.84), i.e. at most ~0.89 normalised units and ~0.76 on
average; :func:`build_animal` still checks that each output lies in ``[-0.5, 0.5]^3`` and raises
otherwise.

Paper defaults: 41 species, 47 training + 3 test poses each, 4 views per training pose and 8 per
test pose (views are rendered elsewhere).
"""

from __future__ import annotations

from dataclasses import asdict
from functools import lru_cache

import numpy as np

from cerberus_core.bodies.animal_mesh import decimate, marching_cubes
from cerberus_core.bodies.animal_pose import (
    AnimalPose,
    animal_pose_splits,
    envelope_poses,
    rest_pose,
    sample_animal_poses,
)
from cerberus_core.bodies.animal_sdf import group_distances, primitives_bounds, sample_field
from cerberus_core.bodies.animal_shape import AnimalSpecies, sample_species
from cerberus_core.bodies.animal_skeleton import PART_GROUPS, animal_primitives
from cerberus_core.bodies.body import FILL, PosedBody
from cerberus_core.errors import BodyError, MissingPackageError

__all__ = [
    "ANIMAL_PART_NAMES",
    "AnimalPose",
    "AnimalSpecies",
    "DEFAULT_TARGET_FACES",
    "N_SPECIES",
    "N_TEST_POSES",
    "N_TRAIN_POSES",
    "animal_pose_splits",
    "build_animal",
    "rest_pose",
    "sample_animal_poses",
    "sample_species",
    "species_extent",
    "species_scale",
    "species_spacing",
]

ANIMAL_PART_NAMES: list[str] = list(PART_GROUPS)
"""Ground-truth semantic parts: head (with snout, ears, horns), neck, torso, tail and the four legs
(front/back x left/right, the animal's own left = +X; each leg includes its paw or hoof)."""

N_SPECIES: int = 41
N_TRAIN_POSES: int = 47
N_TEST_POSES: int = 3

DEFAULT_TARGET_FACES: int = 10_000
"""Face budget after decimation."""
RAW_FACES_PER_AREA: float = 3.0
"""Marching-cubes faces per squared grid step of surface area (measured on smooth shapes)."""
OVERSAMPLE: float = 1.6
"""Raw marching-cubes faces per budgeted face: the automatic grid aims at ``OVERSAMPLE * target``."""
LABEL_SMOOTHING_STEPS: int = 2
"""One-ring majority-vote passes applied to the nearest-primitive part labels (removes speckles
where two parts' primitives are almost equally near, e.g. thigh and rump)."""
MIN_RADIUS_STEPS: float = 0.6
"""Primitives thinner than this many grid steps (radius) are thickened so they survive sampling."""


@lru_cache(maxsize=256)
def _extent_cached(params_key: tuple[tuple[str, float], ...]) -> float:
    params = dict(params_key)
    extent = 0.0
    for pose in envelope_poses(AnimalSpecies("envelope", params)):
        lo, hi = primitives_bounds(animal_primitives(params, pose))
        extent = max(extent, float((hi - lo).max()))
    return extent


def species_extent(species: AnimalSpecies) -> float:
    """Largest bounding-box extent (body units) of the species over :func:`envelope_poses`.

    Computed analytically from the primitives (no meshing), so it is cheap and exact for the
    unblended union.
    """
    return _extent_cached(tuple(sorted(species.params.items())))


def species_scale(species: AnimalSpecies, fill: float = FILL) -> float:
    """Normalisation factor (normalised units per body unit) shared by all poses of ``species``."""
    return fill / species_extent(species)


@lru_cache(maxsize=256)
def _rest_area_cached(params_key: tuple[tuple[str, float], ...], extent: float) -> float:
    spacing = extent / 48
    prims = animal_primitives(dict(params_key), rest_pose(), min_radius=MIN_RADIUS_STEPS * spacing)
    verts, faces = marching_cubes(*sample_field(prims, spacing), spacing)
    tri = verts[faces]
    return float(0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum())


def species_spacing(species: AnimalSpecies, target_faces: int = DEFAULT_TARGET_FACES) -> float:
    """Automatic grid step (body units) for a species: one per species, shared by all its poses.

    Chosen from the rest-pose surface area ``A`` (a coarse marching-cubes pass) so that the raw mesh
    has about ``OVERSAMPLE * target_faces`` faces: ``sqrt(RAW_FACES_PER_AREA * A / (OVERSAMPLE *
    target_faces))``, clamped to ``[extent / 240, extent / 48]``. Bulky species thus get a coarser
    grid than thin-legged ones, which keeps decimation (the slow step) short.
    """
    extent = species_extent(species)
    area = _rest_area_cached(tuple(sorted(species.params.items())), extent)
    spacing = float(np.sqrt(RAW_FACES_PER_AREA * area / (OVERSAMPLE * max(int(target_faces), 100))))
    return float(np.clip(spacing, extent / 240, extent / 48))


def smooth_labels(
    labels: np.ndarray, faces: np.ndarray, n_parts: int, steps: int = LABEL_SMOOTHING_STEPS
) -> np.ndarray:
    """Majority vote of each vertex's one-ring (own label wins ties).

    Args:
        labels: ``(V,)`` int part index per vertex.
        faces: ``(F, 3)`` triangles.
        n_parts: number of parts.
        steps: number of passes.

    Returns:
        ``(V,)`` smoothed labels.
    """
    n = len(labels)
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    try:
        from scipy.sparse import coo_matrix
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingPackageError("the animal bodies need scipy: pip install 'cerberus-core[animal]'") from exc
    adj = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    adj = ((adj + adj.T) > 0).astype(np.float64)
    eye = np.eye(n_parts)
    for _ in range(steps):
        onehot = eye[labels]
        labels = np.asarray(adj @ onehot + 0.5 * onehot).argmax(1)
    return labels


def build_animal(
    species: AnimalSpecies,
    pose: AnimalPose,
    pose_id: int,
    resolution: int | None = None,
    target_faces: int | None = DEFAULT_TARGET_FACES,
) -> PosedBody:
    """Mesh one species in one pose.

    Args:
        species: the species.
        pose: joint angles.
        pose_id: identifier stored in the result (unique within the species).
        resolution: grid steps across the species' envelope extent (>= 16; the step is then
            ``FILL / resolution`` normalised units), or ``None`` for :func:`species_spacing`.
        target_faces: face budget for topology-preserving decimation, ``None`` to keep the raw
            marching-cubes mesh.

    Returns:
        a watertight :class:`PosedBody` in normalised units (inside ``[-0.5, 0.5]^3``, centred on its
        bounding box, scaled by :func:`species_scale`) with per-vertex labels into
        :data:`ANIMAL_PART_NAMES`. ``meta`` holds the archetype, scale, body-unit centre, pose kind,
        pose angles and grid step (normalised units).

    Raises:
        ValueError: on a bad resolution/budget, or if the pose leaves the unit cube.
    """
    if resolution is not None and resolution < 16:
        raise BodyError(f"build_animal: resolution must be >= 16 or None, got {resolution}")
    if target_faces is not None and target_faces < 100:
        raise BodyError(f"build_animal: target_faces must be >= 100 or None, got {target_faces}")
    extent = species_extent(species)
    if resolution is None:
        spacing = species_spacing(species, DEFAULT_TARGET_FACES if target_faces is None else target_faces)
    else:
        spacing = extent / resolution
    prims = animal_primitives(species.params, pose, min_radius=MIN_RADIUS_STEPS * spacing)
    field, origin = sample_field(prims, spacing)
    verts, faces = marching_cubes(field, origin, spacing)
    if len(faces) == 0:
        raise BodyError(f"build_animal: empty surface for {species.name} pose {pose_id}")
    if target_faces is not None:
        verts, faces = decimate(verts, faces, target_faces)
    labels = np.argmin(group_distances(prims, verts, len(PART_GROUPS)), axis=1)
    labels = smooth_labels(labels, faces, len(PART_GROUPS))
    scale = FILL / extent
    centre = 0.5 * (verts.max(0) + verts.min(0))
    normed = (verts - centre) * scale
    reach = float(np.abs(normed).max())
    if reach > 0.5:
        raise BodyError(
            f"build_animal: {species.name} pose {pose_id} ({pose.kind}) reaches {reach:.3f} > 0.5 after "
            f"normalisation; the pose exceeds the species' envelope (see species_extent)"
        )
    return PosedBody(
        vertices=normed.astype(np.float32),
        faces=faces,
        vertex_parts=labels.astype(np.int16),
        part_names=list(ANIMAL_PART_NAMES),
        subject=species.name,
        pose_id=int(pose_id),
        meta={
            "source": "procedural_animal",
            "archetype": species.archetype,
            "scale": scale,
            "centre": centre.tolist(),
            "pose_kind": pose.kind,
            "pose": asdict(pose),
            "grid_step": spacing * scale,
        },
    )
