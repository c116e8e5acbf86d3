"""Input looks: the same rendered body shown to the network in another appearance.

A dataset stores one look, the *shaded* render (uniform grey albedo, a white light along the viewing
direction plus ambient light, docs/data_format.md). A photo has none of that shading: a cut-out
person is a silhouette with clothes, skin and the room's light. An input look re-draws a stored image
so that the network sees the body another way while the training losses keep comparing against the
shaded render (``data.input_look``; ``cerberus eval --input-look`` scores a model on the looks).
One function per look, each on a batch of images ``(..., 3, H, W)`` float in [0, 1]:

* :func:`shaded_look`: the image as stored (the default; nothing is computed).
* :func:`flat_look`: the body's mask filled with one grey level, the mean grey of the body; the
  background as it is. What a model reading only the silhouette gets.
* :func:`random_look`: an appearance drawn at random per image: an albedo colour, a texture over the
  body (stripes or blotches), and the light's balance of ambient and directional intensity and its
  falloff. The dataset stores no normals or depth, only the shaded image, so the light's *direction*
  cannot be changed honestly: the directional light stays along the viewing direction, and what is
  varied is what the stored shading determines, the cosine ``n · l`` recovered from each pixel's grey
  (:func:`shading_cosine`).

What is the body: :func:`body_mask` (every pixel off the background colour, :data:`TOLERANCE`) and
:func:`body_coverage` (its anti-aliased coverage estimated from its neighbours), so the
recoloured body keeps the anti-aliased edge of the render.

>>> import torch
>>> from cerberus_core.datasets.looks import flat_look
>>> image = torch.zeros(1, 3, 4, 4)
>>> image[0, :, 1:3, 1:3] = torch.tensor([0.4, 0.6, 0.4, 0.6]).view(2, 2)  # a 2x2 grey body on black
>>> flat_look(image, background=(0.0, 0.0, 0.0))[0, 0]
tensor([[0.0000, 0.0000, 0.0000, 0.0000],
        [0.0000, 0.5000, 0.5000, 0.0000],
        [0.0000, 0.5000, 0.5000, 0.0000],
        [0.0000, 0.0000, 0.0000, 0.0000]])
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal, get_args

import numpy as np
import torch
import torch.nn.functional as F

from cerberus_core.errors import ConfigError
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

InputLook = Literal["shaded", "flat", "random"]
"""The input looks by name (``data.input_look``, ``EvalSettings.input_look``)."""

INPUT_LOOKS: tuple[str, ...] = get_args(InputLook)

TOLERANCE = 0.5 / 255
"""A pixel within this of the background colour in every channel is background: the stored background is
exact (uint8), so every other pixel, the faintest anti-aliased edge included, is the body's
(:func:`cerberus_core.losses.background_mask`'s default). The flat test depends on it: the shipped ``human``
model scores 0.2596 voxel IoU on flat silhouettes with this mask, 0.2621 when pixels within 0.02 count as
background, 0.2883 within 0.05 (docs/evaluation.md)."""


def _background(images: Tensor, background: Sequence[float] | Tensor) -> Tensor:
    return torch.as_tensor(background, dtype=images.dtype, device=images.device).view(3, 1, 1)


def body_mask(images: Tensor, background: Sequence[float] | Tensor, tol: float = TOLERANCE) -> Tensor:
    """The body's pixels: those more than ``tol`` from the background colour in some channel.

    Args:
        images: ``(..., 3, H, W)`` in [0, 1].
        background: the dataset's RGB background colour (``scene.background``), in [0, 1].
    Returns:
        ``(..., 1, H, W)`` bool, true on the body.
    """
    check_shapes("body_mask", images=(images, "... 3 H W"))
    return ((images - _background(images, background)).abs() > tol).any(dim=-3, keepdim=True)


def body_coverage(images: Tensor, background: Sequence[float] | Tensor, tol: float = TOLERANCE) -> Tensor:
    """How much of each pixel the body covers, estimated from the image alone.

    A stored pixel is ``alpha · c + (1 - alpha) · background`` (the render's anti-aliasing), ``c`` the
    body's shaded colour. A body pixel whose 8 neighbours are all body is taken as fully covered; a
    pixel on the body's edge gets ``alpha`` = its distance from the background over the largest such
    distance in its 3x3 neighbourhood (the nearest fully covered colour), at most 1.

    Args:
        images: ``(..., 3, H, W)`` in [0, 1].
        background: the RGB background colour, in [0, 1].
        tol: see :func:`body_mask`.
    Returns:
        ``(..., 1, H, W)`` float in [0, 1]; 0 off the body.
    """
    mask = body_mask(images, background, tol)
    lead, (h, w) = images.shape[:-3], images.shape[-2:]
    m = mask.reshape(-1, 1, h, w).float()
    dist = (images - _background(images, background)).abs().amax(dim=-3, keepdim=True).reshape(-1, 1, h, w) * m
    interior = -F.max_pool2d(-m, 3, stride=1, padding=1)  # eroded: every neighbour on the body
    near = F.max_pool2d(dist, 3, stride=1, padding=1)
    alpha = torch.where(interior > 0, torch.ones_like(dist), dist / near.clamp(min=1e-6)).clamp(0, 1) * m
    return alpha.reshape(*lead, 1, h, w)


def shading_cosine(images: Tensor, coverage: Tensor, background: Sequence[float] | Tensor,
                   albedo: Sequence[float], ambient: float, diffuse: float) -> Tensor:
    """The cosine ``n · l`` between each body pixel's normal and the light, read back from the stored grey.

    The datasets shade ``albedo · (ambient + diffuse · max(0, n · l))`` with the light along the viewing
    direction (:class:`~cerberus_core.datasets.scene.SceneSetup`), so the cosine is the one quantity of
    the light the image holds.

    Args:
        images: ``(..., 3, H, W)`` shaded renders in [0, 1].
        coverage: ``(..., 1, H, W)`` from :func:`body_coverage`.
        background: RGB background, albedo: RGB albedo, ambient, diffuse: the scene's light.
    Returns:
        ``(..., 1, H, W)`` in [0, 1]; 0 off the body.
    """
    bg = _background(images, background)
    alb = torch.as_tensor(albedo, dtype=images.dtype, device=images.device).view(3, 1, 1)
    colour = (images - (1 - coverage) * bg) / coverage.clamp(min=1e-3)  # the covered colour, un-blended
    cosine = ((colour / alb.clamp(min=1e-3)).mean(dim=-3, keepdim=True) - ambient) / max(diffuse, 1e-6)
    return cosine.clamp(0, 1) * (coverage > 0)


def shaded_look(images: Tensor) -> Tensor:
    """The image as the dataset stores it (the default input look)."""
    return images


MEAN_COSINE = 0.44
"""The mean cosine ``n · l`` over a rendered body's pixels, its anti-aliased edge included: a training body's mean
grey is ``mean(albedo) · (ambient + diffuse · MEAN_COSINE)`` (:func:`flat_grey`). Measured on the human test renders:
body mean grey 0.532 ± 0.014 (every 4th of the 208 test images of ``--size large``, min 0.495, max 0.569) with
albedo 0.8, ambient 0.4, diffuse 0.6: ``(0.532 / 0.8 - 0.4) / 0.6 = 0.44``; held by a test on freshly generated
renders."""


def flat_grey(scene) -> float:
    """The grey a photo's silhouette is filled with for a model trained in the flat look: a training body's mean grey
    under ``scene``'s light (:data:`MEAN_COSINE`), since a photo's own colours (dark clothes, a lit wall) say nothing
    of the grey the model learned. 0.532 for the datasets' default light."""
    return float(sum(scene.albedo) / 3 * (scene.ambient + scene.diffuse * MEAN_COSINE))


def flat_look(images: Tensor, background: Sequence[float] | Tensor, tol: float = TOLERANCE, *,
              grey: float | None = None) -> Tensor:
    """Each body's mask filled with one grey level, the mean grey of that body; the background as it is.

    Args:
        images: ``(..., 3, H, W)`` in [0, 1].
        background: the RGB background colour, in [0, 1].
        tol: a pixel within this of the background in every channel is background (:func:`body_mask`).
        grey: fill every body with this grey instead of its own mean (a photo: :func:`flat_grey`).
    Returns:
        ``(..., 3, H, W)``: the mean over the body's pixels and channels (or ``grey``) on every body pixel, the
        input elsewhere (an image without a body pixel is returned as it is).
    """
    mask = body_mask(images, background, tol)
    if grey is not None:
        return torch.where(mask, images.new_tensor(float(grey)), images)
    weight = mask.to(images.dtype)
    mean = (images * weight).sum(dim=(-3, -2, -1), keepdim=True) / (3 * weight.sum(dim=(-3, -2, -1), keepdim=True)
                                                                   ).clamp(min=1)
    return torch.where(mask, mean.expand_as(images), images)


def _hsv_to_rgb(h: Tensor, s: Tensor, v: Tensor) -> Tensor:
    """``(B,)`` hue in [0, 1), saturation, value → ``(B, 3)`` RGB."""
    k = torch.stack([(5 + h * 6) % 6, (3 + h * 6) % 6, (1 + h * 6) % 6], -1)
    return v[:, None] - v[:, None] * s[:, None] * (torch.minimum(k, 4 - k).clamp(0, 1))


def random_look(images: Tensor, background: Sequence[float] | Tensor, albedo: Sequence[float], ambient: float,
                diffuse: float, generator: torch.Generator | None = None, tol: float = TOLERANCE) -> Tensor:
    """Each image's body re-drawn in an appearance drawn at random: albedo colour, texture and light.

    Per image: an albedo colour (hue uniform, saturation 0-0.8, value 0.35-1); a texture multiplied
    over the body in image space (none, stripes at a random angle, 2-8 periods over the image, or
    smooth blotches from a 4x4 to 8x8 random grid), contrast 0.2-0.6; the light's ambient share
    0.15-0.7 (directional 1 minus it) and a falloff exponent 0.5-2 on the cosine
    (:func:`shading_cosine`). The light stays along the viewing direction (no normals are stored).
    The anti-aliased edge is kept (:func:`body_coverage`); the background is left as it is.

    Args:
        images: ``(B, 3, H, W)`` shaded renders in [0, 1] (a dataset's look: ``albedo``, ``ambient``,
            ``diffuse`` and ``background`` its scene's, :class:`~cerberus_core.datasets.scene.SceneSetup`).
        generator: the random source (a CPU generator; the draws do not depend on the images' device).
    Returns:
        ``(B, 3, H, W)`` in [0, 1].
    """
    check_shapes("random_look", images=(images, "B 3 H W"))
    b, _, h, w = images.shape
    g = generator

    def uniform(lo: float, hi: float, *shape: int) -> Tensor:
        return lo + (hi - lo) * torch.rand(*shape, generator=g)

    colour = _hsv_to_rgb(uniform(0, 1, b), uniform(0, 0.8, b), uniform(0.35, 1.0, b))  # (B, 3)
    amb, gamma = uniform(0.15, 0.7, b), torch.exp(uniform(math.log(0.5), math.log(2.0), b))
    kind = torch.randint(0, 3, (b,), generator=g)  # 0 none, 1 stripes, 2 blotches
    contrast = uniform(0.2, 0.6, b) * (kind > 0)
    angle, periods, phase = uniform(0, math.pi, b), uniform(2, 8, b), uniform(0, 2 * math.pi, b)
    cells = int(torch.randint(4, 9, (1,), generator=g))
    blotch = torch.rand(b, 1, cells, cells, generator=g)

    dev, dt = images.device, images.dtype
    ys, xs = torch.meshgrid(torch.linspace(0, 1, h, device=dev, dtype=dt), torch.linspace(0, 1, w, device=dev, dtype=dt),
                            indexing="ij")
    k = lambda t: t.to(device=dev, dtype=dt).view(b, 1, 1, 1)  # noqa: E731 - per-image scalar as a map
    stripes = 0.5 + 0.5 * torch.sin(2 * math.pi * k(periods) * (xs * torch.cos(k(angle)) + ys * torch.sin(k(angle)))
                                     + k(phase))
    blotches = F.interpolate(blotch.to(device=dev, dtype=dt), size=(h, w), mode="bicubic", align_corners=False)
    pattern = torch.where(k(kind) == 1, stripes, blotches.clamp(0, 1))
    texture = 1 - k(contrast) * pattern  # (B, 1, H, W) in [0.4, 1]

    coverage = body_coverage(images, background, tol)
    cosine = shading_cosine(images, coverage, background, albedo, ambient, diffuse)
    light = k(amb) + (1 - k(amb)) * cosine.clamp(min=0) ** k(gamma)
    body = (colour.to(device=dev, dtype=dt).view(b, 3, 1, 1) * texture * light).clamp(0, 1)
    bg = _background(images, background)
    return torch.where(coverage > 0, coverage * body + (1 - coverage) * bg, images)


def check_look(look: str, key: str = "data.input_look") -> str:
    """``look`` if it names an input look, else a :class:`ConfigError` naming ``key`` and the looks."""
    if look not in INPUT_LOOKS:
        raise ConfigError.about(key, look, "must be one of " + ", ".join(repr(n) for n in INPUT_LOOKS))
    return look


def input_look(images: Tensor, look: str, scene, generator: torch.Generator | None = None) -> Tensor:
    """``images`` shown in ``look`` (one of :data:`INPUT_LOOKS`), for a dataset whose scene set-up is ``scene``.

    Args:
        images: ``(B, 3, H, W)`` shaded renders in [0, 1].
        look: ``shaded`` (returned as they are), ``flat`` or ``random``.
        scene: the dataset's :class:`~cerberus_core.datasets.scene.SceneSetup` (background, albedo, light).
        generator: the random source of ``random``.
    Returns:
        ``(B, 3, H, W)`` in [0, 1].
    """
    check_look(look)
    if look == "shaded":
        return shaded_look(images)
    if look == "flat":
        return flat_look(images, scene.background)
    return random_look(images, scene.background, scene.albedo, scene.ambient, scene.diffuse, generator)


def look_generator(seed: int, *key: int) -> torch.Generator:
    """The CPU generator of the random look for ``(seed, *key)`` (a training step and rank, a test image's
    index): the same draws on every machine and device."""
    state = np.random.SeedSequence([int(seed), 0x100C, *(int(k) for k in key)]).generate_state(2, dtype=np.uint32)
    return torch.Generator().manual_seed(int(state[0]) << 32 | int(state[1]))


class LookedViews:
    """A view dataset (:class:`~cerberus_core.datasets.readers.ViewDataset`) whose items' ``images`` are
    shown in an input look; everything else (records, cameras, ground truth, ``len``) is the dataset's.

    Image ``i`` in the ``random`` look is drawn with :func:`look_generator` ``(seed, i)``: the same
    appearance in every evaluation, whatever the batching.
    """

    def __init__(self, views, look: str, seed: int = 0) -> None:
        self._views, self.look, self.seed = views, check_look(look, "input_look"), int(seed)

    def __len__(self) -> int:
        return len(self._views)

    def __getitem__(self, i: int) -> dict:
        item = dict(self._views[i])
        images = torch.as_tensor(item["images"])
        images = images.float() / 255.0 if images.dtype == torch.uint8 else images.float()
        gen = look_generator(self.seed, int(i)) if self.look == "random" else None
        item["images"] = input_look(images[None], self.look, self._views.scene, gen)[0]
        return item

    def __getattr__(self, name: str):
        if name.startswith("__") or name == "_views":
            raise AttributeError(name)
        return getattr(self._views, name)
