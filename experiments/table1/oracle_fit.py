"""The oracle row of Table 1: how well N deformed icospheres can fit a body with no network at all.

    python experiments/table1/oracle_fit.py [DATA] [--parts 9] [--steps 300] [--limit K] [--out DIR]

Shapes: a body is ``(V, 3)`` vertices and ``(F, 3)`` faces in normalised mesh units (world frame, the
``kato`` grid spans [-0.5, 0.5]^3; a human is about 0.75 tall); a fit is ``(N, 162, 3)`` part vertices
sharing the template's ``(320, 3)`` faces.

For every distinct test body of DATA (the 4 views of a pose share one body: it is fitted once and its
IoU given to each of its images), N parts are fitted directly in 3D, in the world frame, to the
ground-truth mesh (``Dataset.open(DATA).views("test").gt_mesh(i)``). Each part is the paper's representation:
an icosphere of level 2 (162 vertices, 320 faces) whose vertices move freely (template + per-vertex
offsets, what the shape head can express; rotation, scale and translation are redundant with free
vertices).

* **Initialisation**: ``--samples`` points sampled on the body's surface (area-weighted, fixed
  seed) are clustered by k-means (k-means++ seeding from a fixed seed, 20 Lloyd iterations in torch).
  ``--init ellipsoid`` (default): part k starts as the unit sphere mapped onto the principal axes of
  cluster k (half-axes sqrt(3) standard deviations, the half-length of a uniform segment);
  ``--init sphere``: a sphere at the centroid whose radius is the RMS distance of its points to it.
* **Fit**: Adam (``--lr``, cosine decay to a tenth) for ``--steps`` steps on the parts' free vertices,
  written as a per-part affine map of the template plus per-vertex offsets (the affine map is
  redundant with free offsets; it lets Adam stretch a whole part at once). The loss, in mesh units^2:
  a symmetric chamfer distance between ``--part-samples`` points sampled on the parts' faces (fresh
  barycentric samples every step, differentiable in the vertices) and the body's surface samples;
  plus ``--smooth`` times the paper's smoothness loss (:func:`cerberus_core.losses.smoothness_loss`
  with the template's dihedral quadruples, summed over parts) so each part stays a proper closed
  mesh; plus ``--inside`` times the mean squared depth by which part points (vertices and samples)
  leave the body, read from a 64^3 signed distance to the body (:class:`BodyDistance`). Without that
  term (``--inside 0``) a part whose cluster spans two limbs can stay a sheet between them, on the
  surface of neither.
* **Score**: voxel IoU of the union of the parts against the ground truth with exactly what
  ``cerberus eval`` uses (:class:`cerberus_core.eval.standard.VoxelScorer`: the ``cerberus.metrics``
  entry point ``voxel_iou_scorer``, ``kato`` protocol, 32^3).

Writes ``OUT/oracle_N{parts}.json`` (mean IoU over test images, per subject, per body, per-part
statistics: parts used, volumes, mesh checks) and ``OUT/oracle_N{parts}.png`` (ground truth beside the
fitted parts, in part colours, from two viewpoints) and prints a one-paragraph summary. Single thread.

Measured on ``cerberus data generate --dataset human --size small`` (52 test bodies, 208 images),
defaults (300 steps): **N = 9: 0.875** (subjects 0.870 / 0.880, bodies 0.78-0.91), 9 of 9 parts
holding voxels of their own in every body, parts' volumes 1.13x the body's, 1 of 468 parts with a
folded edge; about 4 CPU seconds per body (221 s wall on a lightly shared core). **N = 1** with
``--smooth 1e-4``: **0.584** (0.584 / 0.583), limbs reached by spikes of the one sphere. With the
default ``--smooth 1e-5`` the single sphere crumples (folded edges and a negative volume in every
body; 0.655 on the first 8 bodies); such a mesh is not a proper part, hence the larger weight. The
k-means start is a local minimum: a part whose cluster spans torso and arm can stay a flap over both
(visible in the picture); ``--inside 0`` scores the same on the first 8 bodies (0.864 against 0.865).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import distance_transform_edt

from cerberus_core import Camera, make_renderer, render_parts
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.eval.standard import VoxelScorer
from cerberus_core.losses import dihedral_cosines, smoothness_loss
from cerberus_core.render import render
from cerberus_core.render.templates import MeshTemplate, icosphere
from cerberus_core.viz import atomic_save_png, image_grid, part_colors
from cerberus_metrics.api import voxelize

Tensor = torch.Tensor

VOXEL = 1.0 / 32
"""Edge of one voxel of the ``kato`` 32^3 grid, in mesh units (the grid spans [-0.5, 0.5])."""


# ------------------------------------------------------------------ sampling and clustering
def sample_surface(vertices: Tensor, faces: Tensor, n: int, generator: torch.Generator | None = None) -> Tensor:
    """Area-weighted uniform samples on a triangle mesh, differentiable in ``vertices``.

    Args:
        vertices: ``(..., V, 3)`` (a leading batch, e.g. parts, shares ``faces``).
        faces: ``(F, 3)`` int64.
        n: samples per mesh.
        generator: torch generator (fixed seed → fixed samples).
    Returns:
        ``(..., n, 3)`` points. Face choice follows the (detached) areas; barycentric coordinates are
        uniform on each triangle.
    """
    tri = vertices[..., faces, :]  # (..., F, 3, 3)
    area = torch.linalg.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :], dim=-1).norm(dim=-1)
    flat = area.detach().reshape(-1, area.shape[-1]).clamp_min(1e-12)
    idx = torch.multinomial(flat, n, replacement=True, generator=generator).reshape(*area.shape[:-1], n)
    u = torch.rand(*idx.shape, 2, generator=generator, dtype=vertices.dtype)
    flip = u.sum(-1, keepdim=True) > 1
    u = torch.where(flip, 1 - u, u)
    chosen = torch.gather(tri, -3, idx[..., None, None].expand(*idx.shape, 3, 3))  # (..., n, 3, 3)
    return (chosen[..., 0, :] * (1 - u[..., :1] - u[..., 1:]) + chosen[..., 1, :] * u[..., :1]
            + chosen[..., 2, :] * u[..., 1:])


def kmeans(points: Tensor, k: int, iters: int = 20, generator: torch.Generator | None = None) -> tuple[Tensor, Tensor]:
    """k-means with k-means++ seeding and Lloyd iterations.

    Args:
        points: ``(S, 3)``.
        k: clusters.
    Returns:
        ``centres`` ``(k, 3)`` and ``labels`` ``(S,)`` int64. An emptied cluster keeps its centre.
    """
    first = int(torch.randint(points.shape[0], (1,), generator=generator))
    centres = [points[first]]
    for _ in range(1, k):
        d2 = torch.cdist(points, torch.stack(centres)).square().min(dim=1).values
        centres.append(points[int(torch.multinomial(d2.clamp_min(0) + 1e-12, 1, generator=generator))])
    c = torch.stack(centres)
    for _ in range(iters):
        labels = torch.cdist(points, c).argmin(dim=1)
        sums = torch.zeros_like(c).index_add_(0, labels, points)
        counts = torch.bincount(labels, minlength=k).to(points.dtype)
        c = torch.where(counts[:, None] > 0, sums / counts.clamp_min(1)[:, None], c)
    return c, torch.cdist(points, c).argmin(dim=1)


# ------------------------------------------------------------------ inside/outside of the body
class BodyDistance:
    """Signed distance to the body on a fine grid, trilinearly interpolated (differentiable in the query).

    Built from the body's solid occupancy at ``resolution``^3 over [-0.5, 0.5]^3 (the metric's own
    voxelization, ``kato`` rule) and two Euclidean distance transforms. Positive outside the body.

    Args:
        vertices, faces: the body mesh (numpy).
        resolution: grid cells per side.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, resolution: int = 64) -> None:
        occ = voxelize((vertices, faces), "kato", resolution, check_self_intersections=False).occupancy
        pitch = 1.0 / (resolution - 1)  # kato maps v to R * (v * (R-1)/R + 0.5): centres span [-0.5, 0.5]
        sdf = (distance_transform_edt(~occ) - distance_transform_edt(occ)) * pitch  # [x, y, z]
        # grid_sample wants (N, C, D, H, W) indexed [z, y, x] with coordinates (x, y, z) in [-1, 1]
        self.grid = torch.from_numpy(sdf.transpose(2, 1, 0).copy()).float()[None, None]

    def __call__(self, points: Tensor) -> Tensor:
        """``(..., 3)`` → ``(...)`` signed distance (mesh units; beyond the grid: the border value)."""
        q = (2 * points).reshape(1, -1, 1, 1, 3)
        d = torch.nn.functional.grid_sample(self.grid, q, align_corners=True, padding_mode="border")
        return d.reshape(points.shape[:-1])


# ------------------------------------------------------------------ the fit
def chamfer(a: Tensor, b: Tensor) -> Tensor:
    """Symmetric chamfer distance: mean squared nearest distance ``a -> b`` plus ``b -> a``.

    Args:
        a: ``(A, 3)``; b: ``(B, 3)`` (mesh units).
    Returns:
        scalar, mesh units^2. The nearest neighbours are found without autograd and the loss is taken
        on the matched pairs: the same value and gradient as ``cdist().min()``, without a backward pass
        through the ``(A, B)`` distance matrix (5x faster on one core).
    """
    with torch.no_grad():
        d = torch.cdist(a, b)
        nb, na = d.argmin(dim=1), d.argmin(dim=0)
    return (a - b[nb]).square().sum(-1).mean() + (b - a[na]).square().sum(-1).mean()


def fit_body(vertices: np.ndarray, faces: np.ndarray, template: MeshTemplate, parts: int, steps: int,
             *, samples: int = 2000, part_samples: int = 2000, lr: float = 3e-3, smooth: float = 1e-5,
             inside: float = 30.0, init: str = "ellipsoid", seed: int = 0) -> tuple[Tensor, dict]:
    """Fit ``parts`` deformed icospheres to one body.

    Args:
        vertices: ``(V, 3)`` body vertices (mesh units, world frame); faces ``(F, 3)``.
        template: the part template (unit sphere).
        steps: Adam steps; lr: Adam learning rate (mesh units per step, roughly).
        samples: body surface samples; part_samples: points sampled on all parts' faces per step.
        smooth: weight of the smoothness loss; inside: weight of the squared outside depth.
        init: ``"sphere"`` (radius: RMS distance of the cluster's points to its centroid) or
            ``"ellipsoid"`` (the cluster's principal axes, half-axes sqrt(3) standard deviations).
    Returns:
        ``(P, 162, 3)`` fitted part vertices and a dict of loss values (start and end).
    """
    gen = torch.Generator().manual_seed(seed)
    bv = torch.as_tensor(vertices, dtype=torch.float32)
    bf = torch.as_tensor(faces, dtype=torch.int64)
    target = sample_surface(bv, bf, samples, gen)
    centres, labels = kmeans(target, parts, generator=gen)
    tv, tf, dih = template.vertices, template.faces, template.dihedral
    shapes = []  # (P, 3, 3): x_rest = shape @ template_vertex + centre
    for k in range(parts):
        pts = target[labels == k] - centres[k]
        if pts.shape[0] < 4:
            shapes.append(torch.eye(3) * VOXEL)
            continue
        if init == "sphere":
            shapes.append(torch.eye(3) * pts.square().sum(-1).mean().sqrt())
        else:  # principal axes; sqrt(3) std is the half-length of a uniform segment
            evals, evecs = torch.linalg.eigh(pts.T @ pts / pts.shape[0])
            evecs = evecs * torch.linalg.det(evecs).sign()  # a rotation: faces keep facing outwards
            shapes.append(evecs * (3 * evals.clamp_min(VOXEL ** 2 / 3)).sqrt())
    shape = torch.stack(shapes)
    # free vertices = affine(template) + offsets: the affine part is redundant but lets Adam stretch a
    # whole part at once, where per-vertex offsets alone pull one vertex at a time
    affine = shape.clone().requires_grad_(True)
    shift = centres.clone().requires_grad_(True)
    offsets = torch.zeros(parts, tv.shape[0], 3, requires_grad=True)

    def current() -> Tensor:
        return tv @ affine.transpose(-1, -2) + shift[:, None] + offsets

    opt = torch.optim.Adam([affine, shift, offsets], lr=lr)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda t: 0.1 + 0.45 * (1 + math.cos(math.pi * t / max(1, steps))))
    sdf = BodyDistance(vertices, faces) if inside > 0 else None
    per_part = max(1, part_samples // parts)
    log = {}
    for step in range(steps + 1):
        verts = current()
        pts = sample_surface(verts, tf, per_part, gen).reshape(-1, 3)
        fit = chamfer(pts, target)
        sm = smoothness_loss(verts, dih)
        loss = fit + smooth * sm
        if sdf is not None:
            out = sdf(torch.cat([pts, verts.reshape(-1, 3)])).clamp_min(0).square().mean()
            loss = loss + inside * out
        if step == 0:
            log["chamfer_start"] = float(fit.detach())
        if step == steps:
            log.update(chamfer_end=float(fit.detach()), smoothness_end=float(sm.detach()) / parts)
            break
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
    return current().detach(), log


# ------------------------------------------------------------------ checks and statistics
def part_checks(verts: Tensor, faces: Tensor, dihedral: Tensor) -> dict:
    """Volume and mesh checks of each part.

    Args:
        verts: ``(P, V, 3)``; faces ``(F, 3)`` (the closed template: every edge has two faces);
            dihedral: the template's ``(E, 4)`` dihedral quadruples.
    Returns:
        ``volume`` ``(P,)`` signed volumes (mesh units^3; > 0 for outward faces), ``min_area`` ``(P,)``
        smallest face area, ``flipped`` ``(P,)`` fraction of faces whose normal points towards the
        part's centroid, ``folded`` ``(P,)`` edges whose two faces meet at less than 90 degrees (a crease
        or a fold; a level-2 icosphere has none, its flattest-to-sharpest edges meet at 159-164 degrees),
        ``extent`` ``(P,)`` longest side of the bounding box.
    """
    tri = verts[:, faces]  # (P, F, 3, 3)
    cross = torch.linalg.cross(tri[:, :, 1] - tri[:, :, 0], tri[:, :, 2] - tri[:, :, 0], dim=-1)
    volume = (tri[:, :, 0] * torch.linalg.cross(tri[:, :, 1], tri[:, :, 2], dim=-1)).sum(-1).sum(-1) / 6
    centroid = verts.mean(1, keepdim=True)
    flipped = ((cross * (tri.mean(2) - centroid)).sum(-1) < 0).float().mean(1)
    extent = (verts.max(1).values - verts.min(1).values).max(-1).values
    folded = (dihedral_cosines(verts, dihedral) > 0).sum(-1)
    return {"volume": volume, "min_area": cross.norm(dim=-1).min(1).values / 2, "flipped": flipped,
            "folded": folded, "extent": extent}


def part_voxels(parts: list[tuple[np.ndarray, np.ndarray]], scorer: VoxelScorer) -> list[np.ndarray]:
    """Each part's solid voxels on the evaluation grid (``kato``, 32^3), as boolean arrays; the voxels of
    a part leaving the grid are dropped (``outside="clamp"``), as ``cerberus eval`` does."""
    return [voxelize(p, scorer.protocol, scorer.resolution, check_self_intersections=False,
                     open_mesh="close", outside="clamp").occupancy for p in parts]


# ------------------------------------------------------------------ picture
def picture(bodies: list[tuple[np.ndarray, np.ndarray, Tensor, float, str]], faces: Tensor, path: Path,
            size: int = 128) -> Path:
    """Ground truth beside the fitted parts, front and side, one row per body.

    Args:
        bodies: ``(gt_vertices, gt_faces, part_vertices (P, V, 3), iou, label)``.
    """
    renderer = make_renderer("torch")
    rows, titles = [], []
    for gv, gf, pv, iou, label in bodies:
        cam = Camera.look_at(torch.tensor([30.0, 120.0]), 15.0, 1.968, fov_y_deg=30.0, image_size=size)
        gt = render(renderer, torch.as_tensor(gv, dtype=torch.float32)[None].expand(2, -1, -1),
                    torch.as_tensor(gf), cam).image
        col = part_colors(pv.shape[0])
        fit = render_parts(renderer, pv[None].expand(2, -1, -1, -1), faces, cam, albedo=col).image
        rows.append(torch.cat([gt[:1], fit[:1], gt[1:], fit[1:]]))
        titles.append(f"{label} {iou:.2f}")
    return atomic_save_png(image_grid(rows, row_titles=titles), path)


# ------------------------------------------------------------------ main
def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(
        description="Oracle row of Table 1: fit N deformed icospheres (162 vertices each) directly to each test "
                    "body's ground-truth mesh and score their union with the evaluation's voxel IoU (32^3, kato).",
        epilog=__doc__.split("\n\n", 2)[2], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("data", nargs="?", default="data/human", help="dataset folder, its test split is fitted "
                   "(default data/human, where experiments/table1/run.sh generates it)")
    p.add_argument("--parts", type=int, default=9, help="parts N (9: Cerberus; 1: the single-mesh oracle, NMRr's)")
    p.add_argument("--steps", type=int, default=300, help="Adam steps per body")
    p.add_argument("--lr", type=float, default=3e-3, help="Adam learning rate (mesh units; bodies are ~0.75 tall)")
    p.add_argument("--smooth", type=float, default=1e-5, help="weight of the smoothness loss (sum over all parts' "
                   "edges of (cos theta + 1)^2) against the chamfer distance (mesh units^2); 0 lets parts crumple")
    p.add_argument("--inside", type=float, default=30.0, help="weight of the mean squared depth (mesh units^2) by "
                   "which part points leave the body; 0: the plain symmetric chamfer fit, where a part whose k-means "
                   "cluster spans two limbs can stay a sheet between them")
    p.add_argument("--init", choices=("ellipsoid", "sphere"), default="ellipsoid", help="starting shape of a part: "
                   "a sphere (radius: RMS distance of its k-means cluster to the centroid) or an ellipsoid on the "
                   "cluster's principal axes")
    p.add_argument("--samples", type=int, default=2000, help="body surface samples (k-means and chamfer)")
    p.add_argument("--part-samples", type=int, default=2000, help="points sampled on the parts' faces per step")
    p.add_argument("--limit", type=int, default=None, help="fit only the first K distinct bodies")
    p.add_argument("--seed", type=int, default=0, help="seed of surface sampling and k-means")
    p.add_argument("--picture", type=int, default=4, help="bodies in the PNG (0: none)")
    p.add_argument("--out", type=Path, default=Path("runs/oracle"), help="output folder: oracle_N{parts}.json "
                   "and oracle_N{parts}.png")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    t0, c0 = time.perf_counter(), time.process_time()

    ds = Dataset.open(args.data).views("test")
    rec = ds.records
    bodies: dict[tuple[int, int], list[int]] = {}
    for i, r in enumerate(rec):
        bodies.setdefault((int(r["subject"]), int(r["pose"])), []).append(i)
    keys = list(bodies)[: args.limit] if args.limit else list(bodies)
    template = icosphere(2)
    scorer = VoxelScorer("kato", 32)
    names = ds.subject_names
    results, shown = [], []
    pick = set(np.linspace(0, len(keys) - 1, min(args.picture, len(keys))).round().astype(int).tolist()) \
        if args.picture else set()
    for b, key in enumerate(keys):
        body = ds.gt_mesh(bodies[key][0])
        tb = time.perf_counter()
        verts, log = fit_body(body.vertices, body.faces, template, args.parts, args.steps, samples=args.samples,
                              part_samples=args.part_samples, lr=args.lr, smooth=args.smooth, inside=args.inside,
                              init=args.init, seed=args.seed)
        fit_s = time.perf_counter() - tb
        meshes = [(v.numpy().astype(np.float64), template.faces.numpy()) for v in verts]
        score = scorer(meshes, (body.vertices, body.faces))
        checks = part_checks(verts, template.faces, template.dihedral)
        vox = part_voxels(meshes, scorer)
        union = np.logical_or.reduce(vox)
        others = [np.logical_or.reduce([w for j, w in enumerate(vox) if j != k]) if len(vox) > 1
                  else np.zeros_like(union) for k in range(len(vox))]
        own = [int((v & ~o).sum()) for v, o in zip(vox, others, strict=True)]
        results.append({
            "subject": names[key[0]], "pose": key[1], "images": bodies[key], "iou": score.iou,
            "clipped": score.clipped, "error": score.error, "fit_seconds": fit_s,
            "gt_volume": float(abs(np.einsum("ij,ij->i", body.vertices[body.faces[:, 0]],
                                             np.cross(body.vertices[body.faces[:, 1]],
                                                      body.vertices[body.faces[:, 2]])).sum() / 6)),
            "part_volume": checks["volume"].tolist(), "part_min_area": checks["min_area"].tolist(),
            "part_flipped": checks["flipped"].tolist(), "part_folded_edges": checks["folded"].tolist(),
            "part_extent": checks["extent"].tolist(),
            "part_voxels": [int(v.sum()) for v in vox], "part_own_voxels": own,
            "union_voxels": int(union.sum()), **log,
        })
        print(f"[{b + 1}/{len(keys)}] {names[key[0]]} pose {key[1]}: IoU {score.iou:.3f}  chamfer "
              f"{log['chamfer_start']:.2e} -> {log['chamfer_end']:.2e}  {fit_s:.1f}s", flush=True)
        if b in pick:
            shown.append((body.vertices, body.faces, verts, score.iou, f"{key[0]}/{key[1]}"))
    args.out.mkdir(parents=True, exist_ok=True)
    png = picture(shown, template.faces, args.out / f"oracle_N{args.parts}.png") if shown else None
    wall = time.perf_counter() - t0  # everything: reading, fitting, scoring, the picture
    cpu = time.process_time() - c0  # the same in CPU seconds (wall is longer on a shared machine)

    # per image: each body's IoU given to each of its views
    img_iou = np.array([r["iou"] for r in results for _ in r["images"]])
    img_subj = np.array([r["subject"] for r in results for _ in r["images"]])
    per_subject = {s: float(img_iou[img_subj == s].mean()) for s in sorted(set(img_subj.tolist()))}
    vol = np.array([r["part_volume"] for r in results])  # (bodies, P)
    folded = np.array([r["part_folded_edges"] for r in results])
    own = np.array([r["part_own_voxels"] for r in results])
    used = (own > 0).sum(1)
    summary = {
        "data": str(args.data), "parts": args.parts, "steps": args.steps, "lr": args.lr, "smooth": args.smooth,
        "inside": args.inside, "init": args.init, "samples": args.samples, "part_samples": args.part_samples, "seed": args.seed,
        "protocol": scorer.protocol, "resolution": scorer.resolution,
        "bodies": len(results), "images": int(img_iou.size), "mean_iou": float(img_iou.mean()),
        "per_subject": per_subject, "body_iou_min": float(img_iou.min()), "body_iou_max": float(img_iou.max()),
        "parts_used_mean": float(used.mean()), "parts_used_min": int(used.min()),
        "part_volume_mean": float(vol.mean()), "part_volume_min": float(vol.min()),
        "part_volume_sum_over_gt": float((vol.sum(1) / np.array([r["gt_volume"] for r in results])).mean()),
        "parts_degenerate": int((vol <= 0).sum() + (np.array([r["part_min_area"] for r in results]) <= 0).sum()),
        "part_flipped_mean": float(np.mean([r["part_flipped"] for r in results])),
        "part_volume_sorted_mean": np.sort(vol, axis=1)[:, ::-1].mean(0).tolist(),
        "part_own_voxels_sorted_mean": np.sort(own, axis=1)[:, ::-1].mean(0).tolist(),
        "folded_edges_per_part_mean": float(folded.mean()), "parts_with_folded_edges": int((folded > 0).sum()),
        "part_smoothness_mean": float(np.mean([r["smoothness_end"] for r in results])),
        "clipped": int(sum(r["clipped"] for r in results)), "failed": int(sum(r["error"] is not None for r in results)),
        "wall_seconds": wall, "cpu_seconds": cpu, "fit_seconds_mean": float(np.mean([r["fit_seconds"] for r in results])),
        "threads": torch.get_num_threads(), "per_body": results,
    }
    json_path = args.out / f"oracle_N{args.parts}.json"
    json_path.write_text(json.dumps(summary, indent=1))
    subj = ", ".join(f"{s} {v:.3f}" for s, v in per_subject.items())
    print(f"\nOracle fit of {args.parts} deformed icosphere(s) (162 vertices each) to {len(results)} test bodies "
          f"({img_iou.size} images) of {args.data}, {args.steps} Adam steps each on a symmetric chamfer distance "
          f"plus smoothness {args.smooth:g}{f' and inside {args.inside:g}' if args.inside else ''}: voxel IoU "
          f"(32^3, kato, as `cerberus eval`) {img_iou.mean():.3f} over the test images (per subject: {subj}; "
          f"bodies from {img_iou.min():.3f} to {img_iou.max():.3f}); {used.mean():.1f} of {args.parts} parts used "
          f"on average (a part is used when it holds voxels no other part holds, at least {used.min()} in every "
          f"body), mean part volume {vol.mean():.2e} (min {vol.min():.2e}) mesh units^3, parts' volumes summing to "
          f"{summary['part_volume_sum_over_gt']:.2f}x the body's; {summary['parts_degenerate']} degenerate parts (volume or a face area <= 0), "
          f"{summary['parts_with_folded_edges']} of {vol.size} with a folded edge (< 90 degrees), "
          f"{summary['clipped']} clipped, {summary['failed']} failed. Wall time {wall:.0f} s ({cpu:.0f} CPU s) on "
          f"{torch.get_num_threads()} thread ({summary['fit_seconds_mean']:.1f} s per fit). JSON: {json_path}"
          + (f"; picture: {png}" if png else "") + ".")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
