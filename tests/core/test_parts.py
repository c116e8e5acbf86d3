"""PartSet and the posing math behind Hard Human and "new pose" (cerberus_core.parts)."""
from __future__ import annotations

import pytest
import torch

from cerberus_core.errors import ShapeError
from cerberus_core.parts import PartSet, transfer_pose
from tests.support.oracle import body_parts, random_partset, random_rotations


def test_posed_is_rotation_then_translation():
    r = random_partset(2, 3, 0)
    expected = torch.einsum("bpij,bpvj->bpvi", r.rotations, r.local_vertices) + r.translations[:, :, None]
    torch.testing.assert_close(r.posed(), expected)


def test_identity_pose_leaves_canonical_shape_unchanged():
    canon = random_partset(1, 4, 1)
    identity = PartSet(canon.local_vertices, canon.faces, torch.eye(3).expand(1, 4, 3, 3).clone(),
                                  torch.zeros(1, 4, 3))
    torch.testing.assert_close(transfer_pose(canon, identity).posed(), canon.local_vertices)


def test_transfer_reproduces_other_image_when_shapes_agree(primitive_bodies):
    # Real capsule-figure parts; image B has the same part shapes as A but other transforms.
    a = body_parts(primitive_bodies[0], seed=5)
    b = PartSet(a.local_vertices.clone(), a.faces, random_rotations(a.num_parts, 9).float()[None],
                           a.translations + torch.tensor([0.1, -0.05, 0.02]))
    torch.testing.assert_close(transfer_pose(a, b).posed(), b.posed())
    torch.testing.assert_close(transfer_pose(b, a).posed(), a.posed())
    poses = PartSet.cat([a, b])  # one canonical shape broadcasts over a batch of poses
    torch.testing.assert_close(transfer_pose(a, poses).posed(), poses.posed())
    # Shapes from another pose (capsules at other angles in the same local frames) do not reproduce B.
    other = body_parts(primitive_bodies[1], seed=5)
    assert not torch.allclose(transfer_pose(other, b).posed(), b.posed(), atol=1e-3)


def test_transfer_pose_rejects_mismatched_parts():
    with pytest.raises(ValueError, match="parts"):
        transfer_pose(random_partset(1, 3, 0), random_partset(2, 4, 1))
    with pytest.raises(ValueError, match="batch"):
        transfer_pose(random_partset(2, 3, 0), random_partset(3, 3, 1))


def test_validation_messages():
    r = random_partset(1, 2, 0)
    with pytest.raises(ValueError, match="rotations must be"):
        PartSet(r.local_vertices, r.faces, r.rotations[:, :1], r.translations)
    with pytest.raises(ValueError, match="faces index"):
        PartSet(r.local_vertices, r.faces + 1000, r.rotations, r.translations)


def test_from_posed_index_cat_and_part_meshes():
    r = random_partset(3, 2, 2)
    wrapped = PartSet.from_posed(r.posed(), r.faces)
    torch.testing.assert_close(wrapped.posed(), r.posed())
    single = PartSet.from_posed(r.posed()[:, 0], r.faces)
    assert single.num_parts == 1
    assert PartSet.cat([r.index(2), r.index(0)]).batch_size == 2
    meshes = r.part_meshes(1)
    assert len(meshes) == 2 and meshes[0][0].shape == (r.num_vertices, 3)
    torch.testing.assert_close(torch.as_tensor(meshes[1][0]).float(), r.posed()[1, 1])


def test_pose_donors_skip_images_to_avoid_where_another_can_lend():
    """Issue 34: the new pose borrowed the next image's pose whether or not that image was out of the training
    domain; now the next one not to avoid, else the next one."""
    from cerberus_core.parts import pose_donors

    assert pose_donors(3) == [1, 2, 0]
    assert pose_donors(3, [False, True, False]) == [2, 2, 0]
    assert pose_donors(2, [True, False]) == [1, 0]  # the in-domain image has only the flagged one to borrow from
    assert pose_donors(3, [True, True, True]) == [1, 2, 0]
    assert pose_donors(1, [True]) == [None] and pose_donors(0) == []
    with pytest.raises(ShapeError, match="2 flags for 3 images"):
        pose_donors(3, [False, False])
