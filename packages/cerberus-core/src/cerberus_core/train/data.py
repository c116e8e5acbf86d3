"""What the trainer needs from a dataset, and the deterministic order it reads it in.

The data contract (kept small on purpose): a map-style dataset of quadruplets whose items are dicts
with

* ``images``: ``(4, 3, H, W)`` float32 in [0, 1], ordered ``(a0, a1, b0, b1)``;
* ``azimuth``, ``elevation``, ``distance``, ``fov_y``: ``(4,)`` float32, degrees / world units;

and which has the attributes ``image_size`` (int) and ``scene`` (a
:class:`cerberus_core.datasets.scene.SceneSetup`: camera distance and clipping planes, light, albedo,
background; it turns the items' view fields into cameras). Anything else in the items (subject, pose and view ids)
is carried along and ignored. :class:`cerberus_core.datasets.readers.QuadrupletDataset` is the reader
of the toolkit's on-disk format.

Data order is a pure function of ``(seed, step)``: the sample stream is the concatenation of one
random permutation of the dataset per epoch (permutation ``e`` seeded by ``(seed, e)``), and step
``s`` reads stream positions ``[s * B, (s + 1) * B)``; data-parallel rank ``r`` of ``W`` takes the
``r``-th of ``W`` equal slices. A resumed run therefore reads exactly the batches an uninterrupted
one would.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch.utils.data import Sampler

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.looks import input_look
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.errors import ConfigError, TrainingDatasetError
from cerberus_core.render.camera import Camera
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor


def check_dataset(dataset: Any) -> None:
    """Raise :class:`TrainingDatasetError` with the missing pieces if ``dataset`` does not follow the contract."""
    missing = [a for a in ("image_size", "scene", "__len__", "__getitem__") if not hasattr(dataset, a)]
    if missing:
        raise TrainingDatasetError(f"training dataset {type(dataset).__name__} lacks {missing}; it must be a "
                                   "map-style dataset of quadruplet dicts with .image_size and .scene "
                                   "(see cerberus_core.train.data)")
    if not isinstance(dataset.scene, SceneSetup):
        raise TrainingDatasetError(f"training dataset {type(dataset).__name__}: .scene must be a SceneSetup, got "
                                   f"{type(dataset.scene).__name__} (datasets.scene.read_scene reads a manifest's "
                                   "scene dict)")
    if len(dataset) == 0:
        raise TrainingDatasetError("the training dataset is empty; generate its split or point `data.root` and "
                                   "`data.split` at one that holds quadruplets")


def build_dataset(root: str, split: str) -> Any:
    """The quadruplet dataset of ``root`` (:class:`cerberus_core.datasets.readers.QuadrupletDataset`)."""
    return Dataset.open(root).quadruplets(split)


# ------------------------------------------------------------------ deterministic order
def epoch_permutation(n: int, seed: int, epoch: int) -> Tensor:
    """The ``epoch``-th random permutation of ``range(n)`` for ``seed`` (same on every platform)."""
    state = np.random.SeedSequence([int(seed), int(epoch)]).generate_state(2, dtype=np.uint32)
    g = torch.Generator().manual_seed(int(state[0]) << 32 | int(state[1]))
    return torch.randperm(n, generator=g)


def step_indices(n: int, seed: int, step: int, batch_size: int) -> list[int]:
    """Dataset indices of the global batch of ``step`` (see the module docstring)."""
    start = step * batch_size
    out: list[int] = []
    epoch, offset = divmod(start, n)
    while len(out) < batch_size:
        perm = epoch_permutation(n, seed, epoch)
        take = perm[offset: offset + batch_size - len(out)]
        out.extend(int(i) for i in take)
        epoch, offset = epoch + 1, 0
    return out


class StepBatchSampler(Sampler[list[int]]):
    """Yields, for steps ``start .. end - 1``, this rank's slice of each global batch.

    Args:
        n: dataset length.
        seed: data-order seed.
        batch_size: global batch size (quadruplets per step over all ranks).
        start, end: step range.
        rank, world_size: data-parallel position; ``batch_size`` must be divisible by ``world_size``.
    """

    def __init__(self, n: int, seed: int, batch_size: int, start: int, end: int, rank: int = 0,
                 world_size: int = 1) -> None:
        if batch_size % world_size:
            raise ConfigError.about("train.batch_size", batch_size, "must be divisible by the number of processes "
                                    f"({world_size}) so each draws an equal slice",
                                    f"`train.batch_size=VALUE`, VALUE a multiple of {world_size}")
        self.n, self.seed, self.batch_size = n, seed, batch_size
        self.start, self.end = start, end
        self.per_rank = batch_size // world_size
        self.rank = rank

    def __len__(self) -> int:
        return max(0, self.end - self.start)

    def __iter__(self) -> Iterator[list[int]]:
        lo = self.rank * self.per_rank
        for step in range(self.start, self.end):
            yield step_indices(self.n, self.seed, step, self.batch_size)[lo: lo + self.per_rank]


# ------------------------------------------------------------------ batches
@dataclass
class QuadrupletBatch:
    """A collated batch on the training device.

    Attributes:
        images: ``(B, 4, 3, H, W)`` at the training resolution, as the dataset stores them: what the
            losses compare against.
        camera: ``4 B`` cameras in the flattened order ``(b, k) → 4 b + k``.
        inputs: ``(B, 4, 3, H, W)``: what the network sees, the images in another input look
            (:func:`with_input_look`); ``None``: the images themselves.
    """

    images: Tensor
    camera: Camera
    inputs: Tensor | None = None

    @property
    def network_inputs(self) -> Tensor:
        """``(B, 4, 3, H, W)``: what the network sees (:attr:`inputs`, else :attr:`images`)."""
        return self.images if self.inputs is None else self.inputs

    @property
    def num_quadruplets(self) -> int:
        return self.images.shape[0]


def quadruplet_batch(batch: dict[str, Any], device: torch.device, scene: SceneSetup,
                     image_size: int | None = None) -> QuadrupletBatch:
    """Collated dataset items → images at ``image_size`` and their cameras
    (:meth:`SceneSetup.view_cameras`), on ``device``."""
    images = torch.as_tensor(batch["images"]).to(device=device, dtype=torch.float32)
    check_shapes("quadruplet_batch", images=(images, "B 4 3 H W"))
    bsz, _, _, h, w = images.shape
    if image_size is not None and (h, w) != (image_size, image_size):
        flat = torch.nn.functional.interpolate(images.flatten(0, 1), size=(image_size, image_size),
                                               mode="bilinear", antialias=True, align_corners=False)
        images = flat.clamp(0, 1).view(bsz, 4, 3, image_size, image_size)
        h = w = image_size

    return QuadrupletBatch(images, scene.view_cameras(batch, (h, w), device=device))


def with_input_look(batch: QuadrupletBatch, look: str, scene: SceneSetup,
                    generator: torch.Generator | None = None) -> QuadrupletBatch:
    """``batch`` with :attr:`~QuadrupletBatch.inputs` its images shown in ``look``
    (:func:`cerberus_core.datasets.looks.input_look`; ``data.input_look``); the images, which the losses
    compare against, stay as stored. ``shaded`` returns ``batch`` unchanged.

    Args:
        generator: the random source of the ``random`` look (a CPU generator, e.g.
            :func:`~cerberus_core.datasets.looks.look_generator` of the seed, step and rank).
    """
    if look == "shaded":
        return batch
    flat = batch.images.flatten(0, 1)
    batch.inputs = input_look(flat, look, scene, generator).view_as(batch.images)
    return batch

