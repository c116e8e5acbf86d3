"""Oracle reconstructions for the evaluation tests: real capsule-figure bodies, rendered with the torch backend.

``body_parts`` turns a ground-truth body of the ``primitives`` source (10 capsules sharing one
topology) into a :class:`PartSet` that reproduces it exactly (an oracle "model"), with
non-trivial local frames so that rotations are exercised. :class:`TinyViewDataset` is a test set of
such bodies (2 subjects x 3 poses x 2 views, pose 0 canonical) that follows the dataset contract of
:mod:`cerberus_core.eval.runner`, with images really rendered.
"""
from __future__ import annotations

import torch

from cerberus_core.bodies.primitives import PrimitiveBodySource, sample_subjects
from cerberus_core.parts import PartSet
from cerberus_core.render.api import render
from cerberus_core.render.camera import Camera
from cerberus_core.render.light import Light
from cerberus_core.render.templates import icosphere

IMAGE_SIZE = 32
ELEVATION, DISTANCE, FOV = 15.0, 2.6, 30.0


def random_rotations(n: int, seed: int) -> torch.Tensor:
    """``(n, 3, 3)`` proper rotations from QR of Gaussian matrices."""
    g = torch.Generator().manual_seed(seed)
    q, r = torch.linalg.qr(torch.randn(n, 3, 3, generator=g, dtype=torch.float64))
    q = q * torch.sign(torch.diagonal(r, dim1=-2, dim2=-1)).unsqueeze(-2)
    q[torch.det(q) < 0, :, 0] *= -1
    return q


def random_partset(b: int, p: int, seed: int) -> PartSet:
    """A batch-``b`` reconstruction of ``p`` small icosphere parts, randomly turned and placed."""
    g = torch.Generator().manual_seed(seed)
    t = icosphere(1)
    local = t.vertices * (0.05 + 0.05 * torch.rand(b, p, 1, 3, generator=g))
    rot = random_rotations(b * p, seed).float().reshape(b, p, 3, 3)
    return PartSet(local, t.faces, rot, 0.2 * torch.randn(b, p, 3, generator=g))


def body_parts(body, seed: int = 0) -> PartSet:
    """A batch-1 reconstruction whose posed parts are exactly the body's capsules."""
    nparts = len(body.part_names)
    verts = torch.as_tensor(body.vertices, dtype=torch.float64).reshape(nparts, -1, 3)
    faces = torch.as_tensor(body.faces[: len(body.faces) // nparts])
    centre = verts.mean(1)  # (P, 3)
    rot = random_rotations(nparts, seed)
    local = (verts - centre[:, None]) @ rot  # row-vector form of R^T (x - c)
    return PartSet(local[None].float(), faces, rot[None].float(), centre[None].float())


class TinyViewDataset:
    """2 subjects x 3 poses (pose 0 canonical) x 2 views of capsule figures, images rendered."""

    def __init__(self, renderer, azimuths=(30.0, 120.0)) -> None:
        source = PrimitiveBodySource()
        self.bodies = {}
        self.items = []
        for subject in sample_subjects(2, seed=3, split="test"):
            for body in source.posed_bodies(subject, [0, 1, 2]):
                self.bodies[(body.subject, body.pose_id)] = body
                for view, az in enumerate(azimuths):
                    self.items.append(dict(subject=body.subject, pose=body.pose_id, view=view,
                                           is_canonical=body.pose_id == 0, azimuth=az, elevation=ELEVATION,
                                           distance=DISTANCE, fov_y=FOV))
        self.images = []
        for it in self.items:
            body = self.bodies[(it["subject"], it["pose"])]
            cam = Camera.look_at(it["azimuth"], ELEVATION, DISTANCE, fov_y_deg=FOV, image_size=IMAGE_SIZE)
            out = render(renderer, torch.as_tensor(body.vertices)[None], torch.as_tensor(body.faces), cam,
                         Light.following(cam), background=(1.0, 1.0, 1.0))
            self.images.append(out.image[0])
        self.gt_calls = 0

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int) -> dict:
        return dict(self.items[i], images=self.images[i])

    def cameras(self, batch: dict) -> Camera:
        return Camera.look_at(batch["azimuth"], batch["elevation"], batch["distance"], fov_y_deg=batch["fov_y"],
                              image_size=IMAGE_SIZE)

    def metadata(self, i: int) -> dict:
        return dict(self.items[i])

    def gt_mesh(self, i: int):
        self.gt_calls += 1
        it = self.items[i]
        return self.bodies[(it["subject"], it["pose"])]


class OracleModel:
    """Recognises each rendered test image and returns the reconstruction that reproduces its body.

    Part ``k`` has the same local frame in every image, so the canonical shapes posed with the
    transforms of another view of the canonical pose reproduce it exactly; in other poses the
    capsules are only moved, not turned, so the Hard Human IoU drops."""

    def __init__(self, dataset: TinyViewDataset) -> None:
        self.table = {}
        for i, img in enumerate(dataset.images):
            body = dataset.gt_mesh(i)
            self.table[img.numpy().tobytes()] = body_parts(body, seed=0)  # one local frame per part index
        dataset.gt_calls = 0
        self.calls = 0

    def __call__(self, images: torch.Tensor, camera: Camera) -> PartSet:
        assert camera.batch_size == images.shape[0]
        self.calls += images.shape[0]
        return PartSet.cat([self.table[img.numpy().tobytes()] for img in images])
