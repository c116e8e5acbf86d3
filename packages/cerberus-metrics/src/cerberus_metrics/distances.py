"""Surface sampling, nearest-neighbour distances (pymeshlab), Chamfer-L2 and F-score.

Protocol (Occupancy Networks / Tatarchenko et al. style, point cloud to point cloud):

* ``n_samples`` points are drawn uniformly by area on each surface (a multi-part shape
  samples the concatenation of its parts' surfaces, **including surface buried inside another
  part**: see :func:`sample_surface`). The prediction uses ``numpy.random.default_rng(seed)``,
  the ground truth ``default_rng(seed + 1)``.
* For every sampled point, the distance to the nearest sampled point of the other shape
  is computed exactly by pymeshlab (``get_hausdorff_distance`` on vertex-only meshes).
* Chamfer-L2 = mean(d(p -> G)^2) + mean(d(g -> P)^2), in mesh units squared.
* F-score at threshold t: precision = fraction of prediction points within t of the GT
  points, recall = fraction of GT points within t of the prediction points,
  F = 2PR / (P + R) (0 when P + R = 0). ``t`` is in mesh units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymeshlab

from .errors import MeasurementError
from .io import Mesh, MeshInputError

__all__ = ["MAX_SAMPLES", "check_samples", "sample_surface", "nearest_distances", "PointDistances", "point_distances"]

MAX_SAMPLES = 10_000_000
"""The most points sampled per surface: each point costs about 200 bytes through sampling and the
nearest-point search (both shapes), so this bound keeps a pair within about 2 GB."""


def check_samples(n: object) -> int:
    """``n`` as a sample count, or :class:`MeshInputError` when it is not an integer in [1, MAX_SAMPLES]."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_SAMPLES:
        raise MeshInputError(f"n_samples must be an integer in [1, {MAX_SAMPLES}], got {n!r}")
    return int(n)


def sample_surface(parts: list[Mesh], n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) float64 points uniform by area on all the parts' surfaces together (mesh units).

    Every part's whole surface is sampled, also where it lies inside another part (parts overlapping at a
    joint): such points are not on the outer surface of the union of the solids, which the voxel IoU scores.
    On a prediction they count against precision (and add to the prediction-to-ground-truth Chamfer term)
    where they lie farther than the threshold from the ground truth's surface; on a ground truth of parts,
    against recall. To score the union's outer surface alone, pass one mesh of the union (a boolean union of
    the parts). They are kept on purpose: telling a buried point apart needs an inside test of every sample
    against every other part (generalised winding numbers: 100,000 samples x 2,560 faces of 8 other 320-face
    parts is 2.6e8 solid angles, far more than the rest of a pair costs), and a point where two parts touch
    is neither inside nor outside.
    """
    check_samples(n)
    tri = np.concatenate([p.triangles for p in parts])  # (F, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    total = area.sum()
    if not total > 0:
        raise MeshInputError(f"{parts[0].name}: surface has zero area, so it cannot be sampled")
    face = rng.choice(tri.shape[0], size=int(n), p=area / total)
    r1, r2 = rng.random(int(n)), rng.random(int(n))
    s = np.sqrt(r1)
    t = tri[face]
    return (1 - s)[:, None] * t[:, 0] + (s * (1 - r2))[:, None] * t[:, 1] + (s * r2)[:, None] * t[:, 2]


def nearest_distances(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Distance from each point of src (N, 3) to its nearest point of dst (M, 3).

    Computed by pymeshlab's Hausdorff filter on vertex-only meshes (exact nearest point
    search on a uniform grid). Returns (N,) float64 in mesh units, in pymeshlab's sample
    order (use it for order-independent statistics only).
    """
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.ascontiguousarray(src, np.float64)))
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.ascontiguousarray(dst, np.float64)))
    both = np.concatenate([src, dst])
    diag = float(np.linalg.norm(both.max(axis=0) - both.min(axis=0)))
    res = ms.get_hausdorff_distance(
        sampledmesh=0,
        targetmesh=1,
        savesample=True,
        samplevert=True,
        sampleedge=False,
        sampleface=False,
        samplenum=int(src.shape[0]),
        maxdist=pymeshlab.PureValue(2.0 * diag + 1.0),
    )
    if int(res["n_samples"]) != src.shape[0]:
        raise MeasurementError(f"pymeshlab measured {res['n_samples']} of {src.shape[0]} points; please report this")
    a = ms.mesh(2).vertex_matrix()
    b = ms.mesh(3).vertex_matrix()
    return np.linalg.norm(a - b, axis=1)


#: Largest ratio between the diagonal of the box holding both point sets and the smaller set's
#: own diagonal that Chamfer/F-score accept (see :func:`_check_scales`).
MAX_SCALE_RATIO = 1e3


def _diag(p: np.ndarray) -> float:
    return float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))


def _check_scales(a: np.ndarray, b: np.ndarray, pred_name: str, gt_name: str) -> None:
    """Reject point sets (N, 3), (M, 3) whose sizes or positions differ by more than MAX_SCALE_RATIO.

    Then the distances measure only the scale or placement mismatch (different units, an
    unnormalised prediction), and pymeshlab's grid search, sized on the target set, slows down
    without bound (minutes at a ratio of 1e5, no answer at 1e6).
    """
    da, db = _diag(a), _diag(b)
    both = _diag(np.stack([a.min(axis=0), a.max(axis=0), b.min(axis=0), b.max(axis=0)]))
    small = min(da, db)
    if not np.isfinite(both) or not both <= MAX_SCALE_RATIO * small:
        ratio = "inf" if small == 0 or not np.isfinite(both) else f"{both / small:.3g}"
        raise MeshInputError(
            f"{pred_name} (size {da:.3g}) and {gt_name} (size {db:.3g}) are {ratio} times apart in scale or "
            f"position (together they span {both:.3g}; limit {MAX_SCALE_RATIO:g}x), so Chamfer/F-score would "
            "measure only that mismatch: check that both meshes use the same units and placement"
        )


@dataclass(frozen=True)
class PointDistances:
    """Nearest-neighbour distances between two sampled surfaces (mesh units).

    pred_to_gt: (N,) for each prediction point. gt_to_pred: (M,) for each GT point.
    """

    pred_to_gt: np.ndarray
    gt_to_pred: np.ndarray

    def chamfer_l2(self) -> float:
        """mean(d_pred^2) + mean(d_gt^2), mesh units squared."""
        return float(np.mean(self.pred_to_gt**2) + np.mean(self.gt_to_pred**2))

    def fscore(self, threshold: float) -> tuple[float, float, float]:
        """(F, precision, recall) at distance threshold (mesh units); a point counts when d < threshold."""
        if not threshold > 0:
            raise MeshInputError(f"threshold must be positive (mesh units), got {threshold!r}")
        precision = float(np.mean(self.pred_to_gt < threshold))
        recall = float(np.mean(self.gt_to_pred < threshold))
        f = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
        return f, precision, recall


def point_distances(pred: list[Mesh], gt: list[Mesh], n_samples: int, seed: int, normalize: bool) -> PointDistances:
    """Sample both surfaces and measure nearest distances both ways.

    normalize: first translate both shapes by the GT bounding-box centre and divide by the
    GT bounding box's longest side, so distances and thresholds are relative to the GT size.
    """
    a = sample_surface(pred, n_samples, np.random.default_rng(seed))
    b = sample_surface(gt, n_samples, np.random.default_rng(seed + 1))
    if normalize:
        v = np.concatenate([m.vertices for m in gt])
        lo, hi = v.min(axis=0), v.max(axis=0)
        size = float((hi - lo).max())
        if not size > 0:
            raise MeshInputError("normalize=True: the ground truth has a zero-size bounding box")
        centre = (lo + hi) / 2
        a, b = (a - centre) / size, (b - centre) / size
    _check_scales(a, b, pred[0].name, gt[0].name)
    return PointDistances(nearest_distances(a, b), nearest_distances(b, a))
