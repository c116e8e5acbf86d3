"""The pulls' nearest-neighbour search, core's batched torch reference (cerberus_core.render.nearest),
against the per-image ``cdist`` loop it replaced: the chosen pairs' distances are the same (near-ties
may pick another index; the distance is what the pulls use)."""
import pytest
import torch

from cerberus_core.losses import hidden_part_pull, mask_pixel_centres, silhouette_chamfer
from cerberus_core.render.nearest import nearest_indices
from tests.support.reference_ops import chosen_distances, loop_search, pull_scene, pulls_with_each_search


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    yield


@pytest.mark.parametrize("seed", [0, 1])
def test_batched_search_finds_the_distances_of_the_loop(seed):
    points, fg = pull_scene(seed)
    targets, valid = mask_pixel_centres(fg)
    counts = valid.sum(1)
    found = nearest_indices(points, targets, counts)
    for new, ref in zip(chosen_distances(points, targets, counts, found),
                        chosen_distances(points, targets, counts, loop_search(points, targets, counts)), strict=True):
        torch.testing.assert_close(new, ref, atol=1e-4, rtol=0)
    assert (found[1][~valid] == 0).all() and (found[0][counts == 0] == 0).all()  # padding and empty images: 0
    assert nearest_indices(points, targets, counts, both=False)[1] is None


def test_the_pulls_values_and_gradients_equal_the_loop_searchs():
    points, fg = pull_scene(2)
    for pull in (lambda s, p: silhouette_chamfer(p, fg, max_points=64, search=s),
                 lambda s, p: hidden_part_pull(p.view(6, 5, 30, 2), torch.rand(6, 5, generator=torch.Generator()
                                                                             .manual_seed(3)) > 0.5, fg, search=s)):
        out = pulls_with_each_search(pull, (nearest_indices, loop_search), points)
        torch.testing.assert_close(out[0][0], out[1][0], atol=1e-6, rtol=0)
        torch.testing.assert_close(out[0][1], out[1][1], atol=1e-6, rtol=0)
