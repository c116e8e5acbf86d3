"""The per-part depth oracle: what the voxel IoU would be if every part sat at the right depth.

    python experiments/depth/depth_oracle.py RUN DATA [--limit N] [--best-shift] [--flip] [--readout POSES]
        [--json OUT]

Every test pose is seen from several views. For each pose and each learned part, the part's rays
(from each view's camera centre through the keypoint that view predicts for it) are intersected in
the least-squares sense: the *triangulated* part position. Each image's parts are then moved along
their *own* camera rays to the depth of that point, so the input view stays exactly as predicted,
and the moved reconstruction is scored like ``cerberus eval`` (32^3, ``kato``, union of parts):

* **IoU** before and after, and the paired difference (mean ± s.e. over images, images improved);
* **the whole body's depth against the parts'**: the same with one shift per image, every part moved by the mean
  of its parts' depth corrections (*whole body*), and with each part's correction less that mean (*relative*): how
  much of the gain is where the whole body stands and how much is where the parts stand within it;
* with ``--best-shift``, the one shift per image that scores best against the ground truth (a grid of
  ±0.08 world units in steps of 0.01): the most the whole body's depth can give, and how well the
  triangulated shift finds it (correlation); 17 more scorings per image. Beside it, the shift on that grid
  that other signals pick, each scored the same way: the one that centres the parts' bounding box on the
  world origin (where the data puts every pose's box), and the ones that best match the pose's *other*
  views' ground-truth silhouettes, by silhouette IoU (what the cross view of eq. 4 and the silhouette term
  see in training) and by the silhouettes' centroids;
* with ``--readout POSES``, whether the network's global features hold the whole-body shift: a ridge read-out of
  it from the encoder's latents, fitted on the first ``POSES`` training poses (their triangulated shifts) and
  scored on the test images (R², correlation);
* with ``--flip``, whether the parts point the wrong way in depth: each part *mirrored in depth* about its own
  translation's depth, every vertex kept on its own camera ray (``d -> 2 d_T - d``, so the input view sees the
  part's silhouette as before: the two-way ambiguity a single view leaves a part), kept where the ground truth
  scores the image better, one part at a time in order (greedy); and the whole reconstruction mirrored about its
  mean depth at once; 1 + N + 1 more scorings per image;
* **the moves**: median distance a part moves, and the predicted against the triangulated depth
  (least-squares slope and correlation over every part of every image: slope 1 and correlation 1
  mean the depths are already consistent across views);
* **per part**: the mean absolute depth error (world units);
* **mass against translation**: the depth of each part's vertex mean (where its volume is) beside the depth of its
  translation (where its keypoint is), each against the triangulated depth; with the correlation of the mass's
  offset from the translation (along the view) with the translation's depth error. A strongly negative
  correlation and a mass closer to the triangulated depth than the translation say the vertices shift along the
  ray to make up for a translation at the wrong depth (the vertex offsets, not the depth head, hold the depth);
* **flatness**: the median ratio of each part's smallest to middle extent (principal axes of its
  vertices), for the predicted parts and for the ground-truth body parts: a part much flatter than the
  body's would be a thin sheet, whatever its depth; and the parts' size in their local frames (the
  largest local coordinate, against ``model.vertex_bound``, and the median largest extent).

A large gain says the parts sit right in their input view but not in 3D; a small one does not by itself say
depth is learned: read the whole-body and relative rows, which can cancel (the shipped ``human``: +0.045 and
−0.030; docs/results.md, "One shift per image") (``cerberus eval`` shows the same as the translation disagreement and the
turned-view silhouette IoU of its "Depth across views" section). Single thread; about a minute for
the 208 test images.
"""
from __future__ import annotations

import argparse
import functools
import json
import sys
import warnings
from collections import defaultdict

import numpy as np
import torch

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.eval.allocation import silhouette_centroids
from cerberus_core.eval.compare import paired_difference
from cerberus_core.eval.depth import coverage_masks
from cerberus_core.eval.masks import mask_iou
from cerberus_core.eval.runner import iterate_batches
from cerberus_core.eval.standard import VoxelScorer
from cerberus_core.parts import PartSet
from cerberus_core.plumbing.atomic import atomic_write_text
from cerberus_core.render.backends import make_renderer
from cerberus_core.render.camera import Camera, triangulate
from cerberus_core.render.interface import Renderer
from cerberus_core.run import Run


def flatness(points: np.ndarray) -> float:
    """Smallest over middle principal extent (standard deviation along the principal axes) of a point set."""
    centred = points - points.mean(0)
    s = np.sort(np.linalg.svd(centred, compute_uv=False))
    return float(s[0] / s[1]) if s[1] > 0 else 0.0


def along_rays(parts: PartSet, centre: torch.Tensor, depth: torch.Tensor, new_depth: torch.Tensor) -> PartSet:
    """One image's parts (batch 1) moved along their own camera rays from ``depth`` to ``new_depth`` ``(N,)``, so
    each keypoint stays where the input view sees it: ``c + (new / old) (T - c)``, ``centre`` ``(3,)`` the camera's."""
    moved = centre + (new_depth / depth).view(-1, 1) * (parts.translations[0] - centre)
    return PartSet(parts.local_vertices, parts.faces, parts.rotations, moved.unsqueeze(0))


def mirrored_in_depth(points: torch.Tensor, camera: Camera, about: torch.Tensor) -> torch.Tensor:
    """``(1, M, 3)`` world points mirrored in depth about ``about`` ``(1, M)`` (world units along the view, one
    value a point), each kept on its own camera ray: depth ``d -> 2 about - d`` at the same pixel. A part's
    surface mirrored so is the same in the input view and reversed in depth (its faces' winding reverses)."""
    uv, d = camera.project(points)
    return camera.unproject(uv, 2 * about - d)


def flip_search(scorer: VoxelScorer, one: PartSet, camera: Camera, gt: tuple) -> tuple[float, float, list[int]]:
    """One image's parts, each mirrored in depth about its translation's depth (:func:`mirrored_in_depth`) where
    that scores better against the ground truth, greedily in part order: the IoU of the greedy choice, the IoU of
    the whole reconstruction mirrored about its mean depth, and the parts the greedy choice mirrored."""
    posed = one.posed()  # (1, N, V, 3)
    n, v = posed.shape[1:3]
    _, t_depth = camera.project(one.translations)  # (1, N)
    flat = posed.reshape(1, n * v, 3)
    own = mirrored_in_depth(flat, camera, t_depth.repeat_interleave(v, 1)).view(n, v, 3)
    _, d = camera.project(flat)
    whole = mirrored_in_depth(flat, camera, d.mean().expand(1, n * v)).view(n, v, 3)
    meshes = one.part_meshes(0)
    reversed_faces = meshes[0][1][:, ::-1].copy()  # a mirrored surface's winding reverses
    flipped = [(p.double().numpy(), reversed_faces) for p in own]
    best, chosen = scorer(meshes, gt).iou, []
    for k in range(n):
        trial = [flipped[j] if j == k or j in chosen else meshes[j] for j in range(n)]
        iou = scorer(trial, gt).iou
        if iou > best:
            best, chosen = iou, [*chosen, k]
    mirror = scorer([(p.double().numpy(), reversed_faces) for p in whole], gt).iou
    return best, mirror, chosen


GRID = np.round(np.arange(-0.08, 0.0801, 0.01), 2)
"""The single depth shifts ``--best-shift`` tries (world units)."""


def views_by_pose(dataset, limit: int | None) -> list[list[int]]:
    """The first ``limit`` (``None``: all) poses of a split seen from at least two views: their views' indices."""
    rec = dataset.records
    by_pose: dict[tuple[int, int], list[int]] = defaultdict(list)
    for i in range(len(dataset)):
        by_pose[(int(rec["subject"][i]), int(rec["pose"][i]))].append(i)
    return [v for v in by_pose.values() if len(v) >= 2][:limit]


def predict(model, dataset, poses: list[list[int]]) -> tuple[dict, ...]:
    """Per view index: the keypoints ``uv`` ``(N, 2)``, their depths ``(N,)``, the reconstruction (a batch-1
    :class:`PartSet`), the camera and the encoder's latents (object and shape latent, concatenated)."""
    uv, depth, recon, cams, latents = {}, {}, {}, {}, {}
    with torch.no_grad():
        for batch_idx, batch, camera in iterate_batches(dataset, [i for v in poses for i in v], 16):
            pred = model(batch["images"])
            parts = model.pose(pred, camera)
            for b, i in enumerate(batch_idx):
                uv[i], depth[i] = pred.maps.uv[b], pred.maps.depth[b]
                recon[i], cams[i] = parts.index(b), camera.index([b])
                latents[i] = torch.cat([pred.object_latent[b], pred.shape_latent[b]]).float()
    return uv, depth, recon, cams, latents


def triangulated_depths(views: list[int], uv: dict, cams: dict) -> dict[int, torch.Tensor]:
    """Per view of one pose, the depth ``(N,)`` in that view of each part's triangulated position (its keypoint
    rays from all the pose's views, met in the least-squares sense)."""
    centres = torch.cat([cams[i].center for i in views])  # (K, 3)
    dirs = torch.stack([cams[i].rays(uv[i].unsqueeze(0))[0] for i in views])  # (K, N, 3)
    point = triangulate(centres, dirs)  # (N, 3) world
    return {i: cams[i].project(point.unsqueeze(0))[1][0] for i in views}


def body_shifts(poses: list[list[int]], uv: dict, depth: dict, cams: dict) -> dict[int, float]:
    """Per view, the whole body's triangulated shift: the mean over its parts of (triangulated - predicted depth)."""
    return {i: float((t - depth[i]).mean()) for v in poses for i, t in triangulated_depths(v, uv, cams).items()}


def ridge_readout(x: np.ndarray, y: np.ndarray, test_x: np.ndarray, test_y: np.ndarray) -> dict:
    """A ridge regression of ``y`` ``(M,)`` on standardised features ``x`` ``(M, D)``, its penalty (1 to 10⁴) picked
    on the last fifth of the rows held out, refitted on all of them and scored on ``(test_x, test_y)``: R² (1 -
    residual / variance) on both, the test correlation, and the test's mean |y| before and after subtracting the
    prediction."""
    mu, sd = x.mean(0), x.std(0) + 1e-6

    def fit(a: np.ndarray, b: np.ndarray, lam: float) -> np.ndarray:
        a = (a - mu) / sd
        return np.linalg.solve(a.T @ a + lam * np.eye(a.shape[1]), a.T @ (b - b.mean()))

    def r2(w: np.ndarray, a: np.ndarray, b: np.ndarray, offset: float) -> float:
        return float(1 - (((a - mu) / sd @ w + offset - b) ** 2).mean() / b.var())

    cut = int(len(y) * 0.8)
    lam = max((10.0 ** e for e in range(5)), key=lambda lam: r2(fit(x[:cut], y[:cut], lam), x[cut:], y[cut:],
                                                                 y[:cut].mean()))
    w = fit(x, y, lam)
    guess = (test_x - mu) / sd @ w + y.mean()
    return {"train_images": len(y), "features": x.shape[1], "ridge": lam, "train_r2": r2(w, x, y, y.mean()),
            "test_r2": r2(w, test_x, test_y, y.mean()), "test_correlation": float(np.corrcoef(guess, test_y)[0, 1]),
            "mean_abs_shift": float(np.abs(test_y).mean()), "mean_abs_residual": float(np.abs(test_y - guess).mean())}


def readout(model, data: str, train_poses: int, test_x: np.ndarray, test_y: np.ndarray) -> dict:
    """Can a linear read-out of the encoder's latents tell each image's whole-body shift? :func:`ridge_readout`
    fitted to the latents and triangulated shifts of the views of the first ``train_poses`` training poses, scored
    on the test images' latents ``test_x`` ``(M, D)`` and shifts ``test_y`` ``(M,)``."""
    train = Dataset.open(data).views("train")
    poses = views_by_pose(train, train_poses)
    uv, depth, _, cams, latents = predict(model, train, poses)
    shifts = body_shifts(poses, uv, depth, cams)
    x = np.stack([latents[i].numpy() for v in poses for i in v])
    y = np.array([shifts[i] for v in poses for i in v])
    return ridge_readout(x, y, test_x, test_y)


def paired_gain(x: list[float] | np.ndarray, base: np.ndarray) -> dict:
    """The mean IoU of a variant ``x`` ``(M,)`` and its paired difference to ``base`` ``(M,)`` (the prediction's,
    :func:`~cerberus_core.eval.compare.paired_difference`): ``iou``, ``gain`` ± ``gain_se`` (0 for one image), and
    the images ``improved``."""
    d = paired_difference([{"index": i, "iou": float(v)} for i, v in enumerate(x)],
                          [{"index": i, "iou": float(v)} for i, v in enumerate(base)])
    if d is None:  # one image: its difference, no spread
        gain = float(np.asarray(x)[0] - np.asarray(base)[0])
        return {"iou": float(np.mean(x)), "gain": gain, "gain_se": 0.0, "improved": int(gain > 0)}
    return {"iou": float(np.mean(x)), "gain": d.mean, "gain_se": d.sem, "improved": d.better}


def shift_search(scorer: VoxelScorer, renderer: Renderer, one: PartSet, camera: Camera, depth: torch.Tensor, gt: tuple,
                 others: list[Camera], truths: list[torch.Tensor]) -> tuple[list[float], dict[str, tuple[float, float]]]:
    """One image's reconstruction shifted along its rays by every ``GRID`` step and scored: the IoUs ``(G,)``, and
    per signal (``box_centre``, ``partner_silhouette``, ``partner_centroid``) the shift it picks and that shift's
    IoU. ``others``/``truths``: the pose's other cameras and the ground-truth silhouettes they see."""
    centre = camera.center[0]
    moved = [along_rays(one, centre, depth, depth + float(g)) for g in GRID]
    ious = [scorer(m.part_meshes(0), gt).iou for m in moved]
    shifted = torch.stack([m.posed()[0] for m in moved])  # (G, N, V, 3)
    sil_iou, cen_err = torch.zeros(len(GRID)), torch.zeros(len(GRID))
    for cam, mask in zip(others, truths, strict=True):
        seen = coverage_masks(renderer, shifted, one.faces, cam.index([0] * len(GRID)))  # (G, H, W)
        sil_iou += mask_iou(seen, mask.expand_as(seen)).nan_to_num(0.0)  # an empty pair (NaN): no evidence
        cen_err += (silhouette_centroids(seen) - silhouette_centroids(mask[None])).norm(dim=-1).nan_to_num(1e3)
    posed = one.posed()[0].flatten(0, 1)
    box = (posed.amax(0) + posed.amin(0)).view(1, 1, 3) / 2  # the data centres every pose's box on the origin
    g = float(camera.project(torch.zeros(1, 1, 3))[1][0, 0] - camera.project(box)[1][0, 0])
    picks = {"box_centre": (g, scorer(along_rays(one, centre, depth, depth + g).part_meshes(0), gt).iou)}
    for key, k in (("partner_silhouette", int(torch.argmax(sil_iou))), ("partner_centroid", int(torch.argmin(cen_err)))):
        picks[key] = (float(GRID[k]), ious[k])
    return ious, picks


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 2)[2],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run", help="run folder, weights file or shipped model name")
    p.add_argument("data", help="dataset folder with a test split (several views per pose)")
    p.add_argument("--limit", type=int, default=None, help="first N test poses only (default all)")
    p.add_argument("--best-shift", action="store_true",
                   help="also search the best single depth shift per image against the ground truth")
    p.add_argument("--flip", action="store_true",
                   help="also mirror each part in depth about its own depth (the input view unchanged) where the "
                        "ground truth scores it better, and the whole reconstruction about its mean depth")
    p.add_argument("--readout", type=int, default=None, metavar="POSES",
                   help="also fit a linear read-out of the whole-body shift from the encoder's latents on this many "
                        "training poses and score it on the test images")
    p.add_argument("--json", default=None, help="also write the figures as JSON here")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    warnings.simplefilter("ignore")  # mesh-quality warnings on predicted parts, as in cerberus eval
    run = Run.load(args.run)
    model = run.model.eval()
    dataset = Dataset.open(args.data).views("test")
    poses = views_by_pose(dataset, args.limit)
    uv, depth, recon, cams, latents = predict(model, dataset, poses)
    scorer = VoxelScorer()
    before, after, moves, d_pred, d_tri, d_mass = [], [], [], [], [], []
    errors = defaultdict(list)
    whole, relative, shifts, best, best_shift = [], [], [], [], []
    flip_best, flip_whole, flip_counts = [], [], defaultdict(int)
    shift_picks: list[dict[str, tuple[float, float]]] = []  # per image: (shift, IoU) each other signal picks
    renderer = make_renderer("torch")

    gt_mesh = functools.cache(dataset.gt_mesh)  # each view's body is read once, for its scoring and as a partner

    @functools.cache
    def truth(j: int) -> torch.Tensor:  # (H, W) the ground-truth body's silhouette in view j
        body = gt_mesh(j)
        verts = torch.as_tensor(np.asarray(body.vertices), dtype=torch.float32)[None, None]
        return coverage_masks(renderer, verts, torch.as_tensor(np.asarray(body.faces)), cams[j])[0]
    flat_pred, flat_gt, local_max, extents = [], [], [], []
    for views in poses:
        targets = triangulated_depths(views, uv, cams)
        for i in views:
            body = gt_mesh(i)
            gt = (body.vertices, body.faces)
            one = recon[i]
            posed = one.posed()[0]  # (N, V, 3) world
            flat_pred += [flatness(v.numpy()) for v in posed]
            d_mass.extend(cams[i].project(posed.mean(1).unsqueeze(0))[1][0].tolist())
            local = one.local_vertices[0]  # (N, V, 3)
            local_max.append(float(local.abs().max()))
            extents += (local.amax(1) - local.amin(1)).amax(-1).tolist()
            labels = np.asarray(body.vertex_parts)
            flat_gt += [flatness(np.asarray(body.vertices)[labels == k]) for k in np.unique(labels)
                        if (labels == k).sum() >= 4]
            target, centre, d = targets[i], cams[i].center[0], depth[i]
            shift = (target - d).mean()
            moved = along_rays(one, centre, d, target)
            before.append(scorer(one.part_meshes(0), gt).iou)
            after.append(scorer(moved.part_meshes(0), gt).iou)
            whole.append(scorer(along_rays(one, centre, d, d + shift).part_meshes(0), gt).iou)
            relative.append(scorer(along_rays(one, centre, d, target - shift).part_meshes(0), gt).iou)
            shifts.append(float(shift))
            if args.best_shift:
                truths = [truth(j) for j in views if j != i]
                ious, picks = shift_search(scorer, renderer, one, cams[i], d, gt, [cams[j] for j in views if j != i],
                                           truths)
                best.append(max(ious))
                best_shift.append(float(GRID[int(np.argmax(ious))]))
                shift_picks.append(picks)
            if args.flip:
                greedy, mirror, chosen = flip_search(scorer, one, cams[i], gt)
                flip_best.append(greedy)
                flip_whole.append(mirror)
                for k in chosen:
                    flip_counts[k] += 1
            moves.extend((moved.translations[0] - one.translations[0]).norm(dim=-1).tolist())
            d_pred.extend(depth[i].tolist())
            d_tri.extend(target.tolist())
            for n, e in enumerate((d - target).abs().tolist()):
                errors[n].append(e)
    b = np.array(before)
    paired = functools.partial(paired_gain, base=b)
    dp, dt = np.array(d_pred), np.array(d_tri)
    slope = float(np.polyfit(dt, dp, 1)[0])
    corr = float(np.corrcoef(dt, dp)[0, 1])
    dm = np.array(d_mass)
    oracle = paired(after)
    figures = {"run": str(args.run), "images": len(b), "poses": len(poses), "iou": float(b.mean()),
               "oracle_iou": oracle["iou"], "gain": oracle["gain"], "gain_se": oracle["gain_se"],
               "improved": oracle["improved"], "median_move": float(np.median(moves)),
               "depth_slope": slope, "depth_correlation": corr,
               "whole_body": {**paired(whole), "mean_abs_shift": float(np.abs(shifts).mean())},
               "relative": paired(relative),
               "per_part_depth_error": [float(np.mean(errors[n])) for n in sorted(errors)],
               "translation_depth_error": float(np.abs(dp - dt).mean()), "mass_depth_error": float(np.abs(dm - dt).mean()),
               "median_mass_offset": float(np.median(np.abs(dm - dp))),
               "mass_offset_vs_depth_error": float(np.corrcoef(dm - dp, dp - dt)[0, 1]),
               "median_flatness": float(np.median(flat_pred)), "median_flatness_gt_parts": float(np.median(flat_gt)),
               "largest_local_coordinate": max(local_max), "median_largest_extent": float(np.median(extents))}
    print(f"{figures['images']} images of {figures['poses']} poses: voxel IoU {figures['iou']:.4f} -> "
          f"{figures['oracle_iou']:.4f} with each part at its triangulated depth "
          f"({figures['gain']:+.4f} ± {figures['gain_se']:.4f}, better on {figures['improved']} / {figures['images']})")
    for key, what in (("whole_body", "one shift per image (the whole body)"),
                      ("relative", "each part's own correction less that shift")):
        f = figures[key]
        print(f"  {what}: {f['iou']:.4f} ({f['gain']:+.4f} ± {f['gain_se']:.4f}, better on {f['improved']})")
    print(f"  mean |whole-body shift| {figures['whole_body']['mean_abs_shift']:.4f} world units")
    if args.best_shift:
        bs = np.array(best_shift)
        figures["best_shift"] = {**paired(best), "mean_abs_shift": float(np.abs(bs).mean()),
                                 "correlation_with_triangulated": float(np.corrcoef(bs, shifts)[0, 1])}
        f = figures["best_shift"]
        print(f"  the best shift per image against the ground truth: {f['iou']:.4f} ({f['gain']:+.4f} ± "
              f"{f['gain_se']:.4f}), mean |shift| {f['mean_abs_shift']:.4f}, correlation with the triangulated "
              f"shift {f['correlation_with_triangulated']:.2f}")
        for key, what in (("box_centre", "that centres the parts' box on the world origin"),
                          ("partner_silhouette", "the pose's other views' silhouette IoU picks"),
                          ("partner_centroid", "their silhouettes' centroids pick")):
            ps = np.array([p[key][0] for p in shift_picks])
            figures[key] = {**paired([p[key][1] for p in shift_picks]), "mean_abs_shift": float(np.abs(ps).mean()),
                            "correlation_with_best": float(np.corrcoef(ps, bs)[0, 1])}
            f = figures[key]
            print(f"  the shift {what}: {f['iou']:.4f} ({f['gain']:+.4f} ± {f['gain_se']:.4f}), "
                  f"mean |shift| {f['mean_abs_shift']:.4f}, correlation with the best shift "
                  f"{f['correlation_with_best']:.2f}")
    if args.flip:
        figures["flip"] = {"per_part": paired(flip_best), "whole": paired(flip_whole),
                           "images_mirrored": [flip_counts[k] for k in range(recon[poses[0][0]].num_parts)]}
        f, w = figures["flip"]["per_part"], figures["flip"]["whole"]
        print(f"  each part mirrored in depth about its own depth where that is better (greedy): {f['iou']:.4f} "
              f"({f['gain']:+.4f} ± {f['gain_se']:.4f}, better on {f['improved']}); images where each part was "
              f"mirrored: {figures['flip']['images_mirrored']}")
        print(f"  the whole reconstruction mirrored about its mean depth: {w['iou']:.4f} ({w['gain']:+.4f} ± "
              f"{w['gain_se']:.4f}, better on {w['improved']})")
    print(f"median move {figures['median_move']:.3f} world units; predicted vs triangulated depth: "
          f"slope {slope:.2f}, correlation {corr:.2f}")
    print(f"mean |depth error| of the translations {figures['translation_depth_error']:.3f}, of the parts' vertex means "
          f"{figures['mass_depth_error']:.3f}; median |mass - translation| along the view "
          f"{figures['median_mass_offset']:.3f}, its correlation with the translation's error "
          f"{figures['mass_offset_vs_depth_error']:+.2f}")
    print("per-part mean |depth error|: " + ", ".join(f"{n}: {e:.3f}" for n, e in
                                                      enumerate(figures["per_part_depth_error"])))
    print(f"flatness (smallest / middle extent, median): predicted parts {figures['median_flatness']:.2f}, "
          f"ground-truth body parts {figures['median_flatness_gt_parts']:.2f}; local frames: largest |coordinate| "
          f"{figures['largest_local_coordinate']:.3f}, median largest part extent {figures['median_largest_extent']:.3f}")
    if args.readout:
        test_x = np.stack([latents[i].numpy() for v in poses for i in v])
        figures["readout"] = f = readout(model, args.data, args.readout, test_x, np.array(shifts))
        print(f"linear read-out of the whole-body shift from the latents ({f['features']} features, ridge "
              f"{f['ridge']:g}, {f['train_images']} training images): R² {f['train_r2']:.3f} on them, "
              f"{f['test_r2']:.3f} on the test images (correlation {f['test_correlation']:+.2f}); mean |shift| "
              f"{f['mean_abs_shift']:.4f} -> {f['mean_abs_residual']:.4f} with the read-out subtracted")
    if args.json:
        atomic_write_text(args.json, json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
