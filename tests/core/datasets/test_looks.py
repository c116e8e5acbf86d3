"""Input looks (cerberus_core.datasets.looks): the flat silhouette, the random appearance, the coverage and
shading they read back from a stored render, and the view dataset shown in a look."""
import pytest
import torch
import torch.nn.functional as F

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.looks import (
    INPUT_LOOKS,
    LookedViews,
    body_coverage,
    body_mask,
    check_look,
    flat_look,
    input_look,
    look_generator,
    random_look,
    shading_cosine,
)
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.errors import ConfigError

SCENE = SceneSetup(background=(0.0, 0.0, 0.0))  # the human look's black background, albedo 0.8, light 0.4 + 0.6


def _disc(size=32, radius=10.0, supersample=8):
    """A disc rendered supersampled and box-filtered like the datasets (its exact coverage per pixel), shaded
    with a known cosine (1 at the centre, falling towards the rim): ``(image (1, 3, H, W), coverage, cosine)``."""
    n = size * supersample
    c = (torch.arange(n) + 0.5) / supersample
    y, x = torch.meshgrid(c, c, indexing="ij")
    r = ((x - size / 2) ** 2 + (y - size / 2) ** 2).sqrt()
    inside = (r <= radius).float()
    cosine_hi = (1 - (r / radius).clamp(max=1) ** 2).sqrt()
    alb, amb, dif = SCENE.albedo[0], SCENE.ambient, SCENE.diffuse
    grey_hi = inside * alb * (amb + dif * cosine_hi)
    pool = lambda t: F.avg_pool2d(t[None, None], supersample)[0, 0]  # noqa: E731
    coverage = pool(inside)
    image = pool(grey_hi).expand(3, -1, -1)[None].clone()
    cosine = pool(inside * cosine_hi) / coverage.clamp(min=1e-6)
    return image, coverage, cosine


def test_flat_look_fills_each_body_with_its_mean_grey_and_keeps_the_background():
    image, coverage, _ = _disc()
    other = image.clone() * 0.5  # a second, darker body: its own mean
    flat = flat_look(torch.cat([image, other]), SCENE.background)
    for k, src in enumerate((image, other)):
        mask = body_mask(src, SCENE.background)[0, 0]
        mean = src[0][:, mask].mean()
        assert torch.allclose(flat[k][:, mask], mean.expand(3, int(mask.sum())))
        assert torch.equal(flat[k][:, ~mask], src[0][:, ~mask])
    assert not torch.allclose(flat[0][:, mask], flat[1][:, mask])
    empty = torch.zeros(1, 3, 8, 8)
    assert torch.equal(flat_look(empty, SCENE.background), empty)  # no body: nothing to fill


def test_flat_look_on_a_white_background():
    image = torch.ones(1, 3, 6, 6)
    image[0, :, 2:4, 2:4] = torch.tensor([0.3, 0.5, 0.3, 0.5]).view(2, 2)
    flat = flat_look(image, (1.0, 1.0, 1.0))
    assert torch.allclose(flat[0, :, 2:4, 2:4], torch.full((3, 2, 2), 0.4))
    assert flat[0, :, 0].eq(1).all()


def test_body_coverage_reads_the_antialiased_edge_back():
    image, coverage, _ = _disc()
    est = body_coverage(image, SCENE.background)[0, 0]
    edge = (coverage > 0) & (coverage < 1)
    assert edge.sum() > 40
    # A sphere's rim is the hard case (its shading falls to the ambient there): the estimate's error on the edge
    # is a quarter of a hard mask's, and it never errs by more than the shading changes across a pixel.
    error, hard = (est - coverage).abs()[edge], ((coverage > 0).float() - coverage).abs()[edge]
    assert error.mean() < 0.25 * hard.mean() and error.max() < 0.25
    deep = -F.max_pool2d(-coverage[None, None], 3, stride=1, padding=1)[0, 0] == 1  # neighbours covered too
    assert est[coverage == 0].eq(0).all() and est[deep].eq(1).all()


def test_shading_cosine_recovers_the_cosine_the_render_was_shaded_with():
    image, coverage, cosine = _disc()
    est = shading_cosine(image, body_coverage(image, SCENE.background), SCENE.background, SCENE.albedo,
                         SCENE.ambient, SCENE.diffuse)[0, 0]
    deep = -F.max_pool2d(-coverage[None, None], 3, stride=1, padding=1)[0, 0] == 1  # its coverage is known: 1
    assert (est[deep] - cosine[deep]).abs().max() < 1e-5
    assert est[coverage == 0].eq(0).all()


def test_random_look_draws_a_coloured_textured_body_and_keeps_its_silhouette():
    image, coverage, _ = _disc()
    images = image.expand(16, -1, -1, -1).clone()
    out = random_look(images, SCENE.background, SCENE.albedo, SCENE.ambient, SCENE.diffuse,
                      torch.Generator().manual_seed(3))
    assert out.shape == images.shape and out.min() >= 0 and out.max() <= 1
    assert torch.equal(out[:, :, coverage == 0], images[:, :, coverage == 0])  # background as it was
    inside = coverage == 1
    spread = out[:, :, inside].amax(1) - out[:, :, inside].amin(1)  # (16, P): colour, not grey
    assert (spread.mean(1) > 0.05).sum() >= 8
    colours = out[:, :, inside].mean(-1)  # one mean colour per image: they differ
    assert torch.cdist(colours, colours).triu(1)[torch.ones(16, 16).triu(1).bool()].min() > 1e-3
    seen, true = body_mask(out, SCENE.background)[:, 0], body_mask(image, SCENE.background)[0, 0]
    iou = (seen & true).sum((1, 2)) / (seen | true).sum((1, 2))
    assert iou.min() > 0.9 and (seen & ~true).sum() == 0  # dark draws lose some of the faintest edge pixels


def test_random_look_is_a_function_of_its_generator():
    image, _, _ = _disc()
    images = image.expand(4, -1, -1, -1)
    draw = lambda seed: random_look(images, SCENE.background, SCENE.albedo, SCENE.ambient, SCENE.diffuse,  # noqa: E731
                                    look_generator(0, seed))
    assert torch.equal(draw(1), draw(1))
    assert not torch.allclose(draw(1), draw(2))


def test_input_look_dispatches_and_names_the_looks():
    image, _, _ = _disc()
    assert input_look(image, "shaded", SCENE) is image
    assert torch.equal(input_look(image, "flat", SCENE), flat_look(image, SCENE.background))
    assert INPUT_LOOKS == ("shaded", "flat", "random")
    with pytest.raises(ConfigError, match="data.input_look.*'shaded', 'flat', 'random'"):
        input_look(image, "silhouette", SCENE)
    with pytest.raises(ConfigError, match="input_look = 'grey'"):
        check_look("grey", "input_look")


def test_looked_views_show_the_test_images_in_a_look(pairs_dataset):
    views = Dataset.open(pairs_dataset).views("test")
    flat = LookedViews(views, "flat")
    assert len(flat) == len(views) and flat.records is views.records and flat.scene == views.scene
    item, mine = views[3], flat[3]
    assert torch.equal(mine["images"], flat_look(item["images"][None], views.scene.background)[0])
    assert {k: v for k, v in mine.items() if k != "images"}.keys() == {k for k in item if k != "images"}
    assert all(torch.equal(mine[k], item[k]) for k in item if k != "images")
    assert (flat.gt_mesh(3).vertices == views.gt_mesh(3).vertices).all()
    rand = LookedViews(views, "random")
    assert torch.equal(rand[2]["images"], rand[2]["images"])  # the same appearance every time
    assert not torch.equal(rand[2]["images"], views[2]["images"])
