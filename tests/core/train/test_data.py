"""Data order is a pure function of (seed, step); ranks draw disjoint slices of each global batch."""
import torch

from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.train.data import StepBatchSampler, epoch_permutation, quadruplet_batch, step_indices


def test_step_indices_walk_through_epoch_permutations():
    n, b = 10, 4
    stream = [i for step in range(5) for i in step_indices(n, 7, step, b)]
    assert sorted(stream[:10]) == list(range(10))  # epoch 0 is a permutation
    assert sorted(stream[10:20]) == list(range(10))  # and so is epoch 1
    assert stream[:10] == epoch_permutation(n, 7, 0).tolist()
    assert stream[:10] != epoch_permutation(n, 8, 0).tolist()
    assert step_indices(n, 7, 3, b) == step_indices(n, 7, 3, b)


def test_sampler_resumes_with_the_same_batches_and_slices_by_rank():
    full = list(StepBatchSampler(13, 0, 6, 0, 8))
    resumed = list(StepBatchSampler(13, 0, 6, 5, 8))
    assert resumed == full[5:]
    ranks = [list(StepBatchSampler(13, 0, 6, 0, 8, rank=r, world_size=3)) for r in range(3)]
    for step in range(8):
        assert [i for r in ranks for i in r[step]] == full[step]


def test_sampler_needs_a_divisible_batch():
    import pytest
    with pytest.raises(ValueError, match="divisible"):
        StepBatchSampler(10, 0, 5, 0, 1, rank=0, world_size=2)


def test_quadruplet_batch_resizes_and_builds_flattened_cameras():
    scene = SceneSetup(distance=2.5)
    raw = {"images": torch.rand(2, 4, 3, 64, 64), "azimuth": torch.arange(8.0).view(2, 4) * 30,
           "elevation": torch.full((2, 4), 15.0), "distance": torch.full((2, 4), 2.5),
           "fov_y": torch.full((2, 4), 30.0)}
    batch = quadruplet_batch(raw, torch.device("cpu"), scene, image_size=32)
    assert batch.images.shape == (2, 4, 3, 32, 32)
    assert (batch.camera.height, batch.camera.width, batch.camera.batch_size) == (32, 32, 8)
    ref = scene.cameras(torch.tensor([210.0]), 32)  # item (1, 3) is camera 4 * 1 + 3
    torch.testing.assert_close(batch.camera.rotation[7], ref.rotation[0])
