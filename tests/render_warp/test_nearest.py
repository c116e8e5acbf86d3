"""The Warp kernel of the pulls' nearest-neighbour search against core's torch search and the
per-image ``cdist`` loop before it: the same chosen distances (near-ties may pick another index), so
the pulls' values and gradients are the same; threads and the CUDA thread layout change nothing."""
import pytest
import torch

from cerberus_core.losses import hidden_part_pull, mask_pixel_centres, silhouette_chamfer
from cerberus_core.render.nearest import nearest_indices as torch_search
from cerberus_render_warp.nearest import nearest_indices as warp_search
from tests.support.reference_ops import chosen_distances, loop_search, pull_scene, pulls_with_each_search


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_warp_search_finds_the_distances_of_the_loop(seed, dtype):
    points, fg = pull_scene(seed)
    targets, valid = mask_pixel_centres(fg)
    points, targets, counts = points.to(dtype), targets.to(dtype), valid.sum(1)
    found = warp_search(points, targets, counts)
    for new, ref in zip(chosen_distances(points, targets, counts, found),
                        chosen_distances(points, targets, counts, loop_search(points, targets, counts)), strict=True):
        torch.testing.assert_close(new, ref, atol=1e-5, rtol=0)
    assert (found[1][~valid] == 0).all() and (found[0][counts == 0] == 0).all()
    one_way = warp_search(points, targets, counts, both=False)
    assert one_way[1] is None and torch.equal(one_way[0], found[0])


def test_warp_search_breaks_exact_ties_by_the_smallest_index():
    points = torch.tensor([[[1.0, 1.0], [3.0, 1.0]]])  # both one unit from the middle target
    targets = torch.tensor([[[2.0, 1.0], [2.0, 1.0], [9.0, 9.0]]])
    to_target, to_point = warp_search(points, targets, torch.tensor([3]))
    assert to_target.tolist() == [[0, 0]] and to_point.tolist() == [[0, 0, 1]]


def test_the_pulls_with_the_warp_search_equal_the_torch_search(warp_renderer):
    points, fg = pull_scene(3)
    visible = torch.rand(6, 5, generator=torch.Generator().manual_seed(4)) > 0.5
    for pull in (lambda s, p: silhouette_chamfer(p, fg, max_points=64, search=s),
                 lambda s, p: hidden_part_pull(p.view(6, 5, 30, 2), visible, fg, search=s)):
        out = pulls_with_each_search(pull, (warp_renderer.nearest_indices, torch_search), points)
        torch.testing.assert_close(out[0][0], out[1][0], atol=1e-6, rtol=0)
        torch.testing.assert_close(out[0][1], out[1][1], atol=1e-6, rtol=0)


def test_thread_split_and_cuda_layout_give_identical_indices(monkeypatch):
    import cerberus_render_warp._runtime as runtime

    points, fg = pull_scene(5, n=8)
    targets, valid = mask_pixel_centres(fg)
    counts = valid.sum(1)
    threads = torch.get_num_threads()
    try:
        results = []
        for n in (1, 3):
            torch.set_num_threads(n)
            results.append(warp_search(points, targets, counts))
    finally:
        torch.set_num_threads(threads)
    monkeypatch.setattr(runtime, "ONE_ITEM_PER_THREAD", True)
    results.append(warp_search(points, targets, counts))
    for other in results[1:]:
        assert all(torch.equal(a, b) for a, b in zip(results[0], other, strict=True))
