"""Does one 64 px image carry where the body stands along the view? A probe trained on the ground truth.

    python experiments/depth/depth_probe.py DATA [--run RUN] [--poses P] [--epochs E] [--json OUT]

Every model's largest error on the humans is one depth shift per image (docs/results.md, "One shift per image"),
and a linear read-out of the encoder's global latents holds none of it (``depth_oracle.py --readout``). This asks
the question before it: is it in the image at all? The data puts every pose's bounding box on the world origin,
so where the body's mass stands along a view is not fixed: a body that reaches towards the camera has its mass
behind the origin. Per view, from the ground truth:

* **the target**, the depth of the body's surface centroid (area-weighted, world units) less the depth of the
  world origin, and as a **control** that the probe can read what an image does show, the centroid's image
  position less the origin's (px);
* **the probe**, a small convolutional network trained from scratch on the input images of the views of the
  first ``P`` training poses to predict the three, scored on the test views by R² (1 - residual / variance;
  0 is the training mean's score).

With ``--run``, the same questions of a trained model, and what they are worth in IoU (``cerberus eval``'s
scoring, 32³ ``kato``, the union of parts), each prediction shifted along its own rays (the input view stays as
predicted) so that its surface centroid's depth offset is:

* the model's own, unshifted (its centroid's depth offset against the target: R² after a straight-line fit on the
  training views, and the mean |error|);
* the ground truth's (the most a correct body depth gives: compare ``depth_oracle.py --best-shift``);
* the model's own after a straight line fitted on the training views (a calibration of its scale and bias);
* that plus the probe's *residual*: the probe also learns the ground truth less the calibrated model's own, so
  this asks whether the image holds what the model misses;
* the probe's own (what a single image's depth, read by a network that was told the answer in training, gives);
* and as one more probe target, the model's triangulated whole-body shift (``depth_oracle.py``'s, from the
  pose's views), to compare with ``--readout``'s linear read-out of the latents.

The probe is told the 3D answer in training, which the method is not: it bounds what an image holds, it is not
a method. One thread; a few minutes for 4,000 training poses.
"""
from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections.abc import Callable

import numpy as np
import torch
from torch import nn

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.eval.runner import iterate_batches
from cerberus_core.eval.standard import VoxelScorer
from cerberus_core.plumbing.atomic import atomic_write_text
from cerberus_core.render.camera import Camera
from cerberus_core.run import Run

TARGETS = ("depth", "u", "v")
"""The ground-truth targets per view: the surface centroid's depth offset from the origin (world units) and its
image offset from the origin's projection (px)."""


def surface_centroid(vertices: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Area-weighted centroid ``(..., 3)`` of triangle meshes ``vertices`` ``(..., V, 3)`` sharing ``faces`` ``(F, 3)``.

    >>> square = torch.tensor([[0., 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]])
    >>> surface_centroid(square, torch.tensor([[0, 1, 2], [0, 2, 3]])).tolist()
    [1.0, 1.0, 0.0]
    """
    tri = vertices[..., faces, :]  # (..., F, 3, 3)
    area = torch.linalg.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :]).norm(dim=-1)
    centre = tri.mean(-2)  # (..., F, 3)
    return (area.unsqueeze(-1) * centre).sum(-2) / area.sum(-1, keepdim=True)


def offsets(camera: Camera, points: torch.Tensor) -> torch.Tensor:
    """``(B, 3)``: each point's depth less the world origin's (world units), then its pixel position less the
    origin's, seen by ``camera`` (batch ``B``), ``points`` ``(B, 3)`` world."""
    uv, depth = camera.project(torch.stack([points, torch.zeros_like(points)], 1))  # (B, 2, 2), (B, 2)
    return torch.cat([(depth[:, 0] - depth[:, 1]).unsqueeze(-1), uv[:, 0] - uv[:, 1]], -1)


def views(dataset, indices: list[int]) -> tuple[torch.Tensor, np.ndarray]:
    """The views ``indices`` of a split, read once: their input images ``(M, 3, H, W)`` and the ground truth's
    :data:`TARGETS` ``(M, 3)``."""
    pictures, out = [], []
    for idx, batch, camera in iterate_batches(dataset, indices, 64):
        centres = []
        for i in idx:
            body = dataset.gt_mesh(i)
            centres.append(surface_centroid(torch.as_tensor(np.asarray(body.vertices), dtype=torch.float32),
                                            torch.as_tensor(np.asarray(body.faces), dtype=torch.long)))
        pictures.append(batch["images"])
        out.append(offsets(camera, torch.stack(centres)))
    return torch.cat(pictures), torch.cat(out).numpy()


def probe_net(channels: int, outputs: int, size: int) -> nn.Sequential:
    """Four stride-2 convolutions (32 to 128 channels) and two linear layers: ``(B, channels, size, size)`` to
    ``(B, outputs)``."""
    layers, width = [], channels
    for out in (32, 64, 128, 128):
        layers += [nn.Conv2d(width, out, 3, stride=2, padding=1), nn.BatchNorm2d(out), nn.ReLU()]
        width = out
    return nn.Sequential(*layers, nn.Flatten(), nn.Linear(128 * (size // 16) ** 2, 256), nn.ReLU(),
                         nn.Linear(256, outputs))


def r2(guess: np.ndarray, truth: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """Per column, 1 - mean squared residual / mean squared deviation from ``mean`` (the training mean)."""
    return 1 - ((guess - truth) ** 2).mean(0) / ((truth - mean) ** 2).mean(0)


def fit_probe(x: torch.Tensor, y: np.ndarray, test_x: torch.Tensor, epochs: int, seed: int = 0,
              log: Callable[[str], None] | None = None) -> tuple:
    """Train :func:`probe_net` on images ``x`` ``(M, C, H, W)`` to standardised targets ``y`` ``(M, K)`` (Adam,
    batch 64, the learning rate cosine-decayed from 1e-3); the last tenth held out picks the epoch. Returns the
    predictions for ``x`` and ``test_x`` ``(M', K)`` in the targets' units, and the held-out R² per epoch (also
    passed to ``log`` as each epoch ends)."""
    torch.manual_seed(seed)
    mu, sd = y.mean(0), y.std(0) + 1e-9
    target = torch.as_tensor((y - mu) / sd, dtype=torch.float32)
    cut = int(len(y) * 0.9)
    net = probe_net(x.shape[1], y.shape[1], x.shape[-1])
    opt = torch.optim.Adam(net.parameters(), lr=1e-3, weight_decay=1e-4)
    steps = epochs * ((cut + 63) // 64)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, steps)

    def run(a: torch.Tensor) -> torch.Tensor:
        net.eval()
        with torch.no_grad():
            return torch.cat([net(a[s:s + 512]) for s in range(0, len(a), 512)])

    best, best_state, curve = -np.inf, None, []
    for _ in range(epochs):
        net.train()
        for s in torch.randperm(cut).split(64):
            loss = ((net(x[s]) - target[s]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
        held = float(r2(run(x[cut:]).numpy(), target[cut:].numpy(), np.zeros(y.shape[1])).mean())
        curve.append(held)
        if log:
            log(f"probe epoch {len(curve)}/{epochs}: held-out R² {held:.3f} (mean over the targets)")
        if held > best:
            best, best_state = held, {k: v.clone() for k, v in net.state_dict().items()}
    net.load_state_dict(best_state)
    return run(x).numpy() * sd + mu, run(test_x).numpy() * sd + mu, curve


def model_offsets(model, dataset, indices: list[int], keep: bool = False) -> tuple[np.ndarray, dict]:
    """A trained model's own :data:`TARGETS` ``(M, 3)`` for the views ``indices`` (its parts' surface centroid), and
    with ``keep``, per view index ``(parts, camera, keypoint depths)`` for shifting it (else an empty dict)."""
    out, kept = [], {}
    with torch.no_grad():
        for idx, batch, camera in iterate_batches(dataset, indices, 64):
            pred = model(batch["images"])
            parts = model.pose(pred, camera)
            posed = parts.posed()  # (B, N, V, 3)
            n, v = posed.shape[1:3]
            faces = torch.cat([parts.faces + k * v for k in range(n)])  # the parts as one mesh
            centre = surface_centroid(posed.flatten(1, 2), faces)  # (B, 3)
            out.append(offsets(camera, centre))
            for b, i in enumerate(idx if keep else ()):
                kept[i] = (parts.index(b), camera.index([b]), pred.maps.depth[b])
    return torch.cat(out).numpy(), kept


def line_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares ``y ≈ a x + b``: ``(a, b)``."""
    a, b = np.polyfit(x, y, 1)
    return float(a), float(b)


def shifted_ious(dataset, kept: dict, indices: list[int], shifts: np.ndarray) -> np.ndarray:
    """Voxel IoU of each view's prediction moved along its own rays by ``shifts`` ``(M,)`` (world units, depth)."""
    from depth_oracle import along_rays  # this folder's oracle: one way to move parts along their rays

    scorer, out = VoxelScorer(), []
    for i, g in zip(indices, shifts, strict=True):
        parts, camera, depth = kept[i]
        body = dataset.gt_mesh(i)
        moved = along_rays(parts, camera.center[0], depth, depth + float(g))
        out.append(scorer(moved.part_meshes(0), (body.vertices, body.faces)).iou)
    return np.array(out)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 2)[2],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("data", help="dataset folder with train and test splits (several views per pose)")
    p.add_argument("--run", default=None, help="also score this trained model (run folder, weights or shipped name)")
    p.add_argument("--poses", type=int, default=4000, help="training poses whose views train the probe (default 4000)")
    p.add_argument("--epochs", type=int, default=6, help="probe training epochs (default 6)")
    p.add_argument("--limit", type=int, default=None, help="first N test poses only (default all)")
    p.add_argument("--json", default=None, help="also write the figures as JSON here")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    warnings.simplefilter("ignore")  # mesh-quality warnings on predicted parts, as in cerberus eval
    from depth_oracle import body_shifts, paired_gain, predict, views_by_pose

    data = Dataset.open(args.data)
    train, test = data.views("train"), data.views("test")
    train_poses, test_poses = views_by_pose(train, args.poses), views_by_pose(test, args.limit)
    tr = [i for v in train_poses for i in v]
    te = [i for v in test_poses for i in v]
    (x_tr, y_tr), (x_te, y_te) = views(train, tr), views(test, te)
    columns = list(TARGETS)
    if args.run:
        model = Run.load(args.run).model.eval()
        own_tr, _ = model_offsets(model, train, tr)
        own_te, kept = model_offsets(model, test, te, keep=True)
        a, b = line_fit(own_tr[:, 0], y_tr[:, 0])  # the model's centroid depth, calibrated on the training views
        fit_tr, fit_te = a * own_tr[:, 0] + b, a * own_te[:, 0] + b
        uv, depth, _, cams, _ = predict(model, train, train_poses)
        shift_tr = body_shifts(train_poses, uv, depth, cams)
        uv, depth, _, cams, _ = predict(model, test, test_poses)
        shift_te = body_shifts(test_poses, uv, depth, cams)
        y_tr = np.column_stack([y_tr, y_tr[:, 0] - fit_tr, [shift_tr[i] for i in tr]])
        y_te = np.column_stack([y_te, y_te[:, 0] - fit_te, [shift_te[i] for i in te]])
        columns += ["residual", "body_shift"]
    guess_tr, guess_te, curve = fit_probe(x_tr, y_tr, x_te, args.epochs, log=lambda m: print(m, flush=True))
    mean = y_tr.mean(0)
    figures = {"data": args.data, "train_views": len(tr), "test_views": len(te), "epochs": args.epochs,
               "held_out_r2_by_epoch": curve,
               "targets": {c: {"std": float(y_te[:, k].std()), "mean_abs": float(np.abs(y_te[:, k] - mean[k]).mean()),
                               "probe_train_r2": float(r2(guess_tr[:, k], y_tr[:, k], mean[k])),
                               "probe_test_r2": float(r2(guess_te[:, k], y_te[:, k], mean[k])),
                               "probe_test_correlation": float(np.corrcoef(guess_te[:, k], y_te[:, k])[0, 1])}
                           for k, c in enumerate(columns)}}
    print(f"{len(tr)} training views ({len(train_poses)} poses), {len(te)} test views; probe: {args.epochs} epochs")
    for c, f in figures["targets"].items():
        print(f"  {c}: test std {f['std']:.4f}; probe R² {f['probe_train_r2']:.3f} train, {f['probe_test_r2']:.3f} "
              f"test (correlation {f['probe_test_correlation']:+.2f})")
    if args.run:
        base = shifted_ious(test, kept, te, np.zeros(len(te)))
        moves = {"ground_truth": y_te[:, 0], "line_fit": fit_te, "line_fit_and_probe": fit_te + guess_te[:, 3],
                 "probe": guess_te[:, 0]}
        figures["model"] = {"run": args.run, "own_depth_r2": float(r2(fit_te, y_te[:, 0], mean[0])),
                            "own_depth_mean_abs_error": float(np.abs(own_te[:, 0] - y_te[:, 0]).mean()),
                            "line_fit": [a, b], "iou": float(base.mean()),
                            **{k: paired_gain(shifted_ious(test, kept, te, m - own_te[:, 0]), base)
                               for k, m in moves.items()}}
        f = figures["model"]
        print(f"  the model's own centroid depth: R² {f['own_depth_r2']:.3f} after a line fit on the training views "
              f"(slope {a:.2f}), mean |error| {f['own_depth_mean_abs_error']:.4f}")
        for key, what in (("ground_truth", "the ground truth's"), ("line_fit", "the model's after the line fit"),
                          ("line_fit_and_probe", "the line fit's plus the probe's residual"), ("probe", "the probe's")):
            g = f[key]
            print(f"  voxel IoU {f['iou']:.4f} -> {g['iou']:.4f} with the centroid at {what} depth "
                  f"({g['gain']:+.4f} ± {g['gain_se']:.4f}, better on {g['improved']} / {len(te)})")
    if args.json:
        atomic_write_text(args.json, json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
