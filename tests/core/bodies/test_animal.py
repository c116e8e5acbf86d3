"""Tests for the procedural quadruped body source (cerberus_core.bodies.animal*)."""

from __future__ import annotations

import numpy as np
import pytest

from cerberus_core.bodies.animal import (
    ANIMAL_PART_NAMES,
    N_SPECIES,
    N_TEST_POSES,
    N_TRAIN_POSES,
    AnimalPose,
    animal_pose_splits,
    build_animal,
    rest_pose,
    sample_animal_poses,
    sample_species,
    species_extent,
    species_scale,
)
from cerberus_core.bodies.animal_sdf import primitives_bounds
from cerberus_core.bodies.animal_shape import ARCHETYPES, SHAPE_PARAMS, archetype_species
from cerberus_core.bodies.animal_skeleton import animal_primitives
from cerberus_core.bodies.body import FILL, PosedBody
from tests.support.meshes import assert_closed


@pytest.fixture(scope="module")
def species() -> list:
    return sample_species()


@pytest.fixture(scope="module")
def deer_body(species) -> PosedBody:
    return build_animal(species[0], rest_pose(), 0)


# --- species ---------------------------------------------------------------------------------------


def test_species_defaults_and_determinism(species) -> None:
    assert len(species) == N_SPECIES == 41
    assert (N_TRAIN_POSES, N_TEST_POSES) == (47, 3)
    again = sample_species()
    assert [s.name for s in species] == [s.name for s in again]
    assert all(s.params == t.params for s, t in zip(species, again, strict=True))
    assert len({s.name for s in species}) == 41
    assert species[7].name.startswith("species_07_")
    assert set(species[0].params) == set(SHAPE_PARAMS)
    assert [s.params for s in sample_species(5)] == [s.params for s in species[:5]]  # prefix-stable
    assert sample_species(3, seed=1)[0].params != species[0].params
    assert {s.archetype for s in species} == set(ARCHETYPES)


def test_species_span_deer_to_hippo(species) -> None:
    leg_ratio = np.array([s.params["leg_length"] / s.params["torso_length"] for s in species])
    assert leg_ratio.max() / leg_ratio.min() > 4  # leg length varies a lot
    thickness = np.array([s.params["leg_radius"] / s.params["torso_length"] for s in species])
    assert thickness.max() / thickness.min() > 2.5
    head = np.array([s.params["head_size"] / s.params["torso_length"] for s in species])
    assert head.max() / head.min() > 2
    deer, hippo = archetype_species("deer").params, archetype_species("hippo").params
    assert deer["leg_length"] > 3 * hippo["leg_length"] and hippo["leg_radius"] > 2 * deer["leg_radius"]
    assert hippo["head_size"] > 2 * deer["head_size"]


def test_bad_inputs(species) -> None:
    with pytest.raises(ValueError, match="archetype"):
        archetype_species("unicorn")
    with pytest.raises(ValueError, match="n must be"):
        sample_species(0)
    with pytest.raises(ValueError, match="resolution"):
        build_animal(species[0], rest_pose(), 0, resolution=4)


# --- poses -----------------------------------------------------------------------------------------


def test_poses_deterministic_and_varied(species) -> None:
    a = sample_animal_poses(species[2], np.random.default_rng(3), 20)
    b = sample_animal_poses(species[2], np.random.default_rng(3), 20)
    assert a == b
    assert len(set(a)) == 20 or len({repr(p) for p in a}) == 20
    assert len({p.kind for p in a}) >= 3
    train, test = animal_pose_splits(species[2])
    assert (len(train), len(test)) == (47, 3)
    train5, test5 = animal_pose_splits(species[2], n_train=5)
    assert train5 == train[:5] and test5 == test  # prefix-stable, test poses independent
    assert animal_pose_splits(species[3])[0][0] != train[0]  # per-species streams


def _group_centre(params: dict, pose: AnimalPose, group: str) -> np.ndarray:
    prims = [q for q in animal_primitives(params, pose) if q.group == ANIMAL_PART_NAMES.index(group)]
    lo, hi = primitives_bounds(prims)
    return 0.5 * (lo + hi)


def test_pose_sign_conventions() -> None:
    params = archetype_species("dog").params
    rest = rest_pose()
    head0, tail0 = _group_centre(params, rest, "head"), _group_centre(params, rest, "tail")
    assert _group_centre(params, AnimalPose(neck_yaw=0.4, head_yaw=0.4), "head")[0] > head0[0] + 0.05  # left = +X
    assert _group_centre(params, AnimalPose(tail_yaw=0.6), "tail")[0] > tail0[0] + 0.02
    assert _group_centre(params, AnimalPose(neck_raise=0.4), "head")[1] > head0[1] + 0.02
    assert _group_centre(params, AnimalPose(tail_lift=0.6), "tail")[1] > tail0[1] + 0.02
    pitched = AnimalPose(body_pitch=0.4)
    assert _group_centre(params, pitched, "head")[1] > head0[1] and _group_centre(params, pitched, "tail")[1] < tail0[1]
    swing = AnimalPose(legs=((0.5, 0.0, 0.0),) + ((0.0, 0.0, 0.0),) * 3)
    fl0 = _group_centre(params, rest, "front_left_leg")
    assert _group_centre(params, swing, "front_left_leg")[2] > fl0[2] + 0.02  # swing > 0: foot forward
    np.testing.assert_allclose(
        _group_centre(params, swing, "front_right_leg"), _group_centre(params, rest, "front_right_leg")
    )


def test_envelope_covers_sampled_poses(species) -> None:
    """The species scale comes from the envelope poses; sampled poses must stay inside it."""
    for sp in species[::4]:
        ext = species_extent(sp)
        train, test = animal_pose_splits(sp)
        for pose in train[:25] + test:
            lo, hi = primitives_bounds(animal_primitives(sp.params, pose))
            assert (hi - lo).max() <= ext * 1.0 + 1e-9, (sp.name, pose.kind)


# --- posed bodies ----------------------------------------------------------------------------------


def test_body_record(deer_body, species) -> None:
    b = deer_body
    assert isinstance(b, PosedBody)
    assert b.vertices.dtype == np.float32 and b.faces.dtype == np.int64 and b.vertex_parts.dtype == np.int16
    assert b.part_names == ANIMAL_PART_NAMES and len(ANIMAL_PART_NAMES) == 8
    assert b.subject == species[0].name and b.pose_id == 0
    assert 5_000 <= len(b.faces) <= 15_000
    assert b.meta["scale"] == pytest.approx(species_scale(species[0]))


def test_deterministic(species, deer_body) -> None:
    again = build_animal(species[0], rest_pose(), 0)
    np.testing.assert_array_equal(again.vertices, deer_body.vertices)
    np.testing.assert_array_equal(again.faces, deer_body.faces)
    np.testing.assert_array_equal(again.vertex_parts, deer_body.vertex_parts)


@pytest.mark.parametrize("index", [1, 3, 6, 11])
def test_watertight_in_cube_posed(species, index) -> None:
    sp = species[index]
    pose = animal_pose_splits(sp)[0][index % 5]
    b = build_animal(sp, pose, 1)
    assert_closed(b)
    assert np.abs(b.vertices).max() <= 0.5
    ext = b.vertices.max(0) - b.vertices.min(0)
    assert np.allclose(b.vertices.max(0) + b.vertices.min(0), 0, atol=1e-5)  # centred on its box
    assert ext.max() <= FILL + 1e-4


def test_rest_pose_labels(deer_body) -> None:
    b = deer_body
    assert_closed(b)
    assert set(np.unique(b.vertex_parts)) == set(range(8))
    cen = {n: b.vertices[b.vertex_parts == i].mean(0) for i, n in enumerate(ANIMAL_PART_NAMES)}
    assert cen["head"][2] == max(c[2] for c in cen.values())  # head at the +Z end
    assert cen["head"][2] > 0.25
    assert cen["tail"][2] < cen["torso"][2]
    for leg in ANIMAL_PART_NAMES[4:]:
        assert cen[leg][1] < cen["torso"][1] - 0.1  # legs below the torso
    assert cen["front_left_leg"][0] > 0 > cen["front_right_leg"][0]  # animal's left is +X
    assert cen["back_left_leg"][0] > 0 > cen["back_right_leg"][0]
    assert cen["front_left_leg"][2] > cen["back_left_leg"][2]
    assert b.vertices[:, 1].min() == pytest.approx(b.vertices[b.vertex_parts >= 4, 1].min())  # feet lowest


def test_species_and_poses_differ(species, deer_body) -> None:
    hippo = build_animal(species[1], rest_pose(), 0)
    ext_d = deer_body.vertices.max(0) - deer_body.vertices.min(0)
    ext_h = hippo.vertices.max(0) - hippo.vertices.min(0)
    assert ext_d[1] / ext_d[2] > 1.5 * ext_h[1] / ext_h[2]  # the deer is tall, the hippo long and low
    assert ext_h[0] > 1.8 * ext_d[0]  # ... and wide
    pose = animal_pose_splits(species[0])[0][0]
    posed = build_animal(species[0], pose, 1)
    assert posed.meta["scale"] == deer_body.meta["scale"]  # one scale per species
    assert not np.allclose(posed.vertices.max(0), deer_body.vertices.max(0), atol=1e-3)


@pytest.mark.slow
def test_many_species_and_poses(species) -> None:
    for sp in species:
        train, test = animal_pose_splits(sp)
        for i, pose in enumerate(train[:2] + test[:1]):
            b = build_animal(sp, pose, i)
            assert_closed(b)
            assert np.abs(b.vertices).max() <= 0.5
            assert len(np.unique(b.vertex_parts)) == 8
