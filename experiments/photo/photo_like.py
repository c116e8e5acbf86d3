"""The photo-like test (issue 41, item 3): the test split rendered as photos, cut out by a mask, scored in 3D.

    python experiments/photo/photo_like.py RUN DATA OUT [--images N] [--size 256] [--masks exact,auto] [--fit STEPS]

Each test image's ground-truth body is rendered again from its own camera, as a photo would show it, with
appearances no training image has: clothes by body part (a shirt over the torso and upper arms, sleeves to
the wrist on half of the bodies, trousers over pelvis and legs, skin on head, neck and hands), a solid 3D
texture on the shirt (stripes, checks or none), a light from a random direction (not along the view), and a
cluttered background (a wall and floor gradient, smooth colour blobs, noise). It is rendered at ``--size``
pixels (2x2 supersampled). Each photo is then cut out as ``cerberus reconstruct`` cuts it out
(:func:`cerberus_core.reconstruct.input_domain.prepare_input`: composited onto the training background, framed to
the training camera, resized to the model's size) by

* ``exact``: the render's own coverage (alpha), the best mask there is;
* ``auto``: the photo extra's person mask (``cerberus reconstruct --mask auto``; needs ``cerberus-core[photo]``),

and the model's reconstruction is scored like ``cerberus eval`` scores it (voxel IoU against the ground
truth, the image's own camera). Also measured: the automatic mask's IoU against the exact one, and the
reconstruction's rendered silhouette against the mask it was given. With ``--fit STEPS`` each reconstruction is
also fitted to the silhouette it was given (:func:`cerberus_core.reconstruct.fit.fit_silhouette`, what ``cerberus
reconstruct --fit`` does) and scored again, under ``<mask>_fit``: whether the fit moves the body in 3D toward the
truth or only its outline toward the mask. Writes OUT/results.json, OUT/photos/
(each photo, exact mask and automatic mask as PNG) and OUT/sheet.png (photo, mask, input, parts for a few).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image
from tqdm import tqdm

from cerberus_core import Run
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.eval.compare import paired_difference
from cerberus_core.eval.figures import render_reconstruction
from cerberus_core.eval.runner import evaluate_dataset
from cerberus_core.photo_mask import AUTO, person_mask, rendered_silhouette, segmenter_available, silhouette_iou
from cerberus_core.reconstruct.fit import FitSettings, fit_silhouette
from cerberus_core.reconstruct.input_domain import prepare_input
from cerberus_core.render.api import render
from cerberus_core.render.backends import make_renderer
from cerberus_core.render.light import Light
from cerberus_core.viz import image_grid

SKIN = np.array([[0.96, 0.80, 0.69], [0.88, 0.67, 0.53], [0.76, 0.55, 0.40], [0.55, 0.38, 0.26],
                 [0.36, 0.24, 0.16]])
SKIN_PARTS = ("head", "neck")
SHIRT_PARTS = ("torso", "upper_arm.L", "upper_arm.R")
SLEEVE_PARTS = ("lower_arm.L", "lower_arm.R")  # skin (the hand and forearm) on half of the bodies
TROUSER_PARTS = ("pelvis", "thigh.L", "thigh.R", "shin.L", "shin.R")


def hsv(h: float, s: float, v: float) -> np.ndarray:
    k = (np.array([5.0, 3.0, 1.0]) + h * 6) % 6
    return v - v * s * np.clip(np.minimum(k, 4 - k), 0, 1)


def clothes(vertices: np.ndarray, parts: np.ndarray, names: list[str], rng: np.random.Generator) -> np.ndarray:
    """``(V, 3)`` per-vertex albedo: skin, a shirt with a solid texture, trousers."""
    skin = SKIN[rng.integers(len(SKIN))] * rng.uniform(0.9, 1.05)
    shirt = hsv(rng.uniform(), rng.uniform(0.2, 0.9), rng.uniform(0.3, 0.95))
    second = hsv(rng.uniform(), rng.uniform(0.0, 0.6), rng.uniform(0.6, 1.0))
    trousers = hsv(rng.uniform(0.55, 0.7), rng.uniform(0.3, 0.7), rng.uniform(0.15, 0.5)) if rng.uniform() < 0.6 \
        else hsv(rng.uniform(), rng.uniform(0.0, 0.5), rng.uniform(0.1, 0.6))
    x, y, z = vertices.T
    kind, period = rng.integers(3), rng.uniform(0.04, 0.1)
    pattern = {0: np.zeros_like(y), 1: (np.floor(y / period) % 2),
               2: ((np.floor(x / period) + np.floor(y / period) + np.floor(z / period)) % 2)}[int(kind)]
    top = shirt[None] * (1 - pattern[:, None]) + second[None] * pattern[:, None]
    sleeves = rng.uniform() < 0.5
    part = np.asarray(names)[parts]
    out = np.empty((len(vertices), 3))
    out[:] = skin
    shirted = np.isin(part, SHIRT_PARTS + (SLEEVE_PARTS if sleeves else ()))
    out[shirted] = top[shirted]
    out[np.isin(part, TROUSER_PARTS)] = trousers
    return np.clip(out, 0, 1)


def background(size: int, rng: np.random.Generator) -> np.ndarray:
    """``(S, S, 3)`` in [0, 1]: a wall over a floor, smooth colour blobs and noise."""
    wall, floor = hsv(rng.uniform(), rng.uniform(0, 0.5), rng.uniform(0.3, 0.95)), \
        hsv(rng.uniform(), rng.uniform(0, 0.6), rng.uniform(0.15, 0.7))
    horizon = rng.uniform(0.55, 0.85) * size
    rows = np.arange(size)[:, None, None]
    out = np.where(rows < horizon, wall * (0.8 + 0.2 * rows / size), floor * (0.7 + 0.3 * rows / size))
    out = np.broadcast_to(out, (size, size, 3)).copy()
    blobs = torch.rand(1, 3, 6, 6, generator=torch.Generator().manual_seed(int(rng.integers(2**31))))
    blobs = F.interpolate(blobs, size=(size, size), mode="bicubic", align_corners=False)[0].permute(1, 2, 0).numpy()
    out = (1 - 0.35) * out + 0.35 * blobs
    out += rng.normal(0, 0.03, out.shape)
    return np.clip(out, 0, 1)


def render_photo(renderer, body, scene, azimuth: float, size: int, rng: np.random.Generator):
    """The body as a photo: ``(S, S, 3)`` image and ``(S, S)`` exact coverage, both in [0, 1]."""
    camera = scene.cameras([azimuth], size * 2)
    v = torch.as_tensor(body.vertices, dtype=torch.float32)[None]
    albedo = torch.as_tensor(clothes(body.vertices, body.vertex_parts, body.part_names, rng), dtype=torch.float32)
    theta, lift = rng.uniform(-math.pi * 0.6, math.pi * 0.6), rng.uniform(0.1, 0.9)
    direction = [math.sin(theta) * math.cos(lift), math.sin(lift), math.cos(theta) * math.cos(lift)]  # towards light
    light = Light.camera_relative(camera, direction, ambient=float(rng.uniform(0.25, 0.45)),
                                  diffuse=float(rng.uniform(0.5, 0.8)))
    faces = torch.as_tensor(body.faces, dtype=torch.int64)
    with torch.no_grad():
        out = render(renderer, v, faces, camera, light, albedo=albedo[None], background=(0.0, 0.0, 0.0))
    image = F.avg_pool2d(out.image, 2)[0].permute(1, 2, 0).numpy()
    alpha = F.avg_pool2d(out.alpha.float(), 2)[0, 0].numpy()
    back = background(size, rng)
    photo = image + (1 - alpha[..., None]) * back  # the render is over black: premultiplied
    return np.clip(photo, 0, 1), alpha


class PhotoViews:
    """The test views with each image replaced by the model input prepared from its photo."""

    def __init__(self, views, images: dict[int, torch.Tensor]) -> None:
        self._views, self.images = views, images

    def __len__(self) -> int:
        return len(self._views)

    def __getitem__(self, i: int) -> dict:
        return dict(self._views[i]) | {"images": self.images[int(i)]}

    def __getattr__(self, name: str):
        if name.startswith("__") or name == "_views":
            raise AttributeError(name)
        return getattr(self._views, name)


def recording(run: Run, renderer, silhouettes: dict[str, np.ndarray], steps: int, made: dict[str, object]):
    """A reconstructor (``images, camera -> PartSet``): the model's prediction, fitted to each image's silhouette for
    ``steps`` (0: not fitted); images are found by their content (the runner batches them), and each image's
    reconstruction is kept in ``made`` under it, for the silhouette IoU."""
    def reconstruct(images: torch.Tensor, camera):
        with torch.no_grad():
            parts = run.model.reconstruct(images, camera)
        if steps:
            sil = torch.stack([torch.as_tensor(silhouettes[key(im)], dtype=torch.float32) for im in images])
            parts = fit_silhouette(renderer, parts, camera, sil, run.model.dihedral, FitSettings(steps=steps))
        for b, im in enumerate(images):
            made[key(im)] = parts.index([b])
        return parts
    return reconstruct


def key(image: torch.Tensor) -> str:
    return hashlib.sha1(image.detach().cpu().contiguous().numpy().tobytes()).hexdigest()


def u8(a: np.ndarray) -> np.ndarray:
    return (np.clip(a, 0, 1) * 255 + 0.5).astype(np.uint8)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run")
    ap.add_argument("data", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--images", type=int, default=0, help="N test images spread evenly over the split (0: all)")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--masks", default="exact,auto")
    ap.add_argument("--seed", type=int, default=41)
    ap.add_argument("--fit", type=int, default=0, metavar="STEPS",
                    help="also score each reconstruction fitted to its silhouette for STEPS steps (0: not)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    masks = args.masks.split(",")
    if AUTO in masks and not segmenter_available():
        raise SystemExit("--masks auto needs the photo extra: pip install 'cerberus-core[photo]'")
    run = Run.load(args.run)
    views = Dataset.open(args.data).views("test")
    scene = views.scene
    size = int(run.config.data.image_size or 64)
    n = len(views) if args.images <= 0 else min(args.images, len(views))
    indices = sorted({int(round(k)) for k in np.linspace(0, len(views) - 1, n)})  # spread over the split
    photos = args.out / "photos"
    photos.mkdir(parents=True, exist_ok=True)
    renderer = make_renderer("auto")
    inputs: dict[str, dict[int, torch.Tensor]] = {m: {} for m in masks}
    sil: dict[str, list[np.ndarray]] = {m: [] for m in masks}
    auto_ious, sheet = [], []
    for i in tqdm(indices, desc="photos", unit="img"):
        rng = np.random.default_rng([args.seed, i])
        item = views[i]
        photo, alpha = render_photo(renderer, views.gt_mesh(i), scene, float(item["azimuth"]), args.size, rng)
        Image.fromarray(u8(photo)).save(photos / f"{i:04d}.png")
        Image.fromarray(u8(alpha)).save(photos / f"{i:04d}_exact.png")
        if AUTO in masks:
            found = person_mask(photo)
            Image.fromarray(u8(found)).save(photos / f"{i:04d}_auto.png")
            auto_ious.append(silhouette_iou(found, alpha))
        for m in masks:
            loaded = prepare_input(photos / f"{i:04d}.png", size, scene,
                                   AUTO if m == AUTO else photos / f"{i:04d}_exact.png",
                                   look=run.config.data.input_look, warn=False)
            inputs[m][i] = loaded.image
            sil[m].append(loaded.silhouette)
            if len(sheet) < 6 and m == masks[-1]:
                sheet.append((photo, found if m == AUTO else alpha, loaded.image, i))
    results: dict = {"run": str(args.run), "data": str(args.data), "images": len(indices), "size": args.size,
                     "seed": args.seed}
    if auto_ious:  # NaN-aware: an empty pair (no person in the photo nor found) has no IoU
        results["auto_mask_iou"] = {"mean": float(np.nanmean(auto_ious)), "min": float(np.nanmin(auto_ious)),
                                    "below_0.5": int(np.sum(np.asarray(auto_ious) < 0.5))}
    fits = [(m, 0) for m in masks] + ([(m, args.fit) for m in masks] if args.fit > 0 else [])
    evaluations = {}
    for m, steps in fits:
        name = m if steps == 0 else f"{m}_fit"
        made: dict[str, object] = {}
        reconstruct = recording(run, renderer, {key(inputs[m][i]): sil[m][k] for k, i in enumerate(indices)}, steps,
                                made)
        evaluations[name] = evaluate_dataset(PhotoViews(views, inputs[m]), reconstruct, indices=indices,
                                             skip=("hard", "part_quality", "visibility", "depth", "segments",
                                                   "allocation"), progress=False)
        coverage = [silhouette_iou(rendered_silhouette(renderer, made[key(inputs[m][i])],
                                                       scene.cameras([float(views[i]["azimuth"])], size)), sil[m][k])
                    for k, i in enumerate(indices)]
        mean, covered = evaluations[name].standard.mean, float(np.nanmean(coverage))  # NaN-aware: empty pairs out
        results[name] = {"voxel_iou": mean, "silhouette_iou": covered,
                         "per_image": evaluations[name].image_ious()} | ({"fit_steps": steps} if steps else {})
        print(f"{name} mask: voxel IoU {mean:.4f}, silhouette IoU {covered:.3f}")
    for m in masks if args.fit > 0 else ():
        diff = paired_difference(evaluations[f"{m}_fit"].records, evaluations[m].records)
        if diff is not None:
            results[f"{m}_fit"]["paired_vs_unfitted"] = {"mean": diff.mean, "se": diff.sem, "better": diff.better,
                                                         "images": diff.n}
            print(f"{m}: fitted - unfitted voxel IoU {diff.mean:+.4f} +- {diff.sem:.4f} "
                  f"(better on {diff.better} of {diff.n})")
    if auto_ious:
        print(f"automatic mask against the exact one: IoU {results['auto_mask_iou']['mean']:.3f} (min "
              f"{results['auto_mask_iou']['min']:.3f}, {results['auto_mask_iou']['below_0.5']} below 0.5)")
    rows = []
    for photo, mask, model_input, i in sheet:
        cam = scene.cameras([float(views[i]["azimuth"])], size)
        with torch.no_grad():
            rec = run.model.reconstruct(model_input[None], cam)
        parts = render_reconstruction(renderer, rec, cam, parts=True, background=scene.background)[0]
        small = lambda a: torch.as_tensor(np.array(Image.fromarray(u8(a)).resize((size, size), Image.LANCZOS)),  # noqa: E731
                                          dtype=torch.float32).div(255)
        rows.append(torch.stack([small(photo).permute(2, 0, 1), small(mask)[None].expand(3, -1, -1), model_input,
                                 parts]))
    if rows:
        image_grid(rows, scale=2).save(args.out / "sheet.png")
    (args.out / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    print(f"results: {args.out / 'results.json'}; pictures: {args.out / 'sheet.png'}, {photos}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
