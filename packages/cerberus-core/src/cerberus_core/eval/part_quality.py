"""Part quality: do the learned parts mean the same thing in every image? (Beyond the paper.)

Training never sees the ground-truth semantic parts (``PosedBody.vertex_parts``); here they judge
the parts Cerberus discovered.

1. **Assignment.** Every ground-truth vertex goes to the predicted part whose surface is nearest
   (:func:`assign_to_parts`). Surfaces are represented by a dense barycentric lattice of points on
   every predicted triangle (``density`` steps per edge), queried with a k-d tree: the chosen part
   is at most ``longest edge / (density * sqrt(3))`` farther than the nearest one (every point of a
   triangle lies within ``l / sqrt(3)`` of a corner of a sub-triangle with longest edge ``l``).
2. **Overlap.** Per image, a ``P x K`` matrix ``M[p, k]`` = surface area (or vertex count) of ground-
   truth part ``k`` assigned to predicted part ``p`` (:func:`overlap_matrix`). Vertices carry a third
   of the area of their incident faces by default, so the dense face of a body mesh does not outweigh
   its limbs.
3. **Consistency** over the test set (:class:`PartQuality`): each predicted part's label
   is its majority ground-truth part, ``argmax_k sum_images M[p, k]``. Its *agreement* is the fraction
   of images (among those where it covers anything) whose own majority ``argmax_k M_i[p, k]`` is that
   label; its *entropy* (bits) is that of the distribution of per-image majorities (0 = always the
   same part); its *purity* is the share of all the area it covers that belongs to its label. Beside them,
   how many of the ``K`` ground-truth parts are some learned part's label (``gt_parts_covered``): consistency
   and entropy only mean something with it, since a one-part model, its part labelled ``torso`` in every
   image, is perfectly consistent (1, 0 bits) and covers 1 of ``K``.
4. **Segmentation IoU.** Predicted parts are renamed to their labels (several may map to one ground-
   truth part; a ground-truth part nobody maps to scores 0), and per ground-truth part
   ``IoU_k = |pred = k and gt = k| / |pred = k or gt = k|`` is accumulated (by area) over the whole
   test set (:func:`segmentation_iou`); the mean over ground-truth parts is reported, leaving out a part
   with no area on either side (its IoU is NaN: nothing to score).

5. **Left and right merged.** Beside the per-side labels, everything above is scored again with the
   two sides of each ground-truth part as one (:func:`merge_sides`: ``shin.L`` and ``shin.R`` →
   ``shin``, ``front_left_leg`` and ``front_right_leg`` → ``front_leg``): a grey, untextured body seen
   from the front or the back looks the same, so nothing in an image says which leg is the body's left
   and per-side agreement is capped near 0.5 by the data, not by the model.

**No part labels.** Data without part labels (a mesh folder with no ``parts.npy``: one ground-truth
part, ``"body"``, covering every vertex) would make every score above a trivial 1.0: every learned
part's majority is the single ground-truth part. So when fewer than two ground-truth parts carry any
area over the test set, :meth:`PartQuality.summary` scores nothing: ``part_labels`` is
``False``, ``consistency``, ``mean_entropy_bits`` and ``mean_segmentation_iou`` are ``None``,
``parts`` and ``segmentation_iou`` are empty and ``note`` says so in one line. With labels,
``part_labels`` is ``True`` and ``note`` is ``None``.
"""
from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import trimesh

from cerberus_core.errors import ConfigError, MeshError, MissingPackageError
from cerberus_core.eval.markdown import fmt, markdown_table
from cerberus_core.eval.segments import one_vocabulary, vocabulary_set
from cerberus_core.eval.visibility import visibility_cells, visibility_header, visibility_sentence
from cerberus_core.shapes import check_shapes


def _np(x: Any, dtype=None) -> np.ndarray:
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype=dtype)


def barycentric_lattice(density: int) -> np.ndarray:
    """``(M, 3)`` barycentric weights ``(i, j, k) / density`` with ``i + j + k = density``;
    ``M = (density + 1)(density + 2) / 2``.

    Example:
        >>> barycentric_lattice(2)  # M = 6 points: the corners and the edge midpoints
        array([[0. , 0. , 1. ],
               [0. , 0.5, 0.5],
               [0. , 1. , 0. ],
               [0.5, 0. , 0.5],
               [0.5, 0.5, 0. ],
               [1. , 0. , 0. ]])
    """
    if density < 1:
        raise ConfigError.about("density", density, "must be >= 1", "`density=1` or more")
    return np.array([(i, j, density - i - j) for i in range(density + 1) for j in range(density + 1 - i)],
                    dtype=np.float64) / density


def surface_samples(part_vertices: np.ndarray, faces: np.ndarray, density: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Points covering every part's surface, with the part each belongs to.

    Args:
        part_vertices: ``(P, V, 3)``.
        faces: ``(F, 3)`` shared faces.
        density: lattice steps per triangle edge.
    Returns:
        ``points`` ``(P * F * M, 3)`` and ``part`` ``(P * F * M,)`` int64.

    Example: two parts of one triangle each (``F = 1``), the second one unit above the first:

        >>> tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        >>> points, part = surface_samples(np.stack([tri, tri + [0, 0, 1]]), np.array([[0, 1, 2]]), density=2)
        >>> points.shape, part.tolist()  # 2 parts x 1 face x 6 lattice points
        ((12, 3), [0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1])
        >>> points[7].tolist()  # part 1's second point: the midpoint of its edge (1, 2)
        [0.5, 0.5, 1.0]
    """
    pv = _np(part_vertices, np.float64)
    f = _np(faces, np.int64)
    tri = pv[:, f]  # (P, F, 3, 3)
    pts = np.einsum("mk,pfkd->pfmd", barycentric_lattice(density), tri)
    part = np.broadcast_to(np.arange(pv.shape[0])[:, None, None], pts.shape[:3])
    return pts.reshape(-1, 3), part.reshape(-1).astype(np.int64)


def assign_to_parts(points: np.ndarray, part_vertices: np.ndarray, faces: np.ndarray, density: int = 4) -> np.ndarray:
    """Index of the predicted part whose surface is nearest to each point.

    Args:
        points: ``(N, 3)`` e.g. ground-truth vertices (world coordinates).
        part_vertices: ``(P, V, 3)`` posed predicted parts (same frame).
        faces: ``(F, 3)``.
        density: see :func:`surface_samples`.
    Returns:
        ``(N,)`` int64 in ``[0, P)``.

    Example (needs scipy): the two parts of :func:`surface_samples`' example, a triangle at ``z = 0`` and one at
    ``z = 1``:

        >>> tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        >>> parts = np.stack([tri, tri + [0, 0, 1]])  # (P, V, 3)
        >>> points = np.array([[0.2, 0.2, 0.1], [0.2, 0.2, 0.8], [3.0, 0.0, 0.4]])  # (N, 3)
        >>> assign_to_parts(points, parts, np.array([[0, 1, 2]]))
        array([0, 1, 0])
    """
    try:
        from scipy.spatial import cKDTree
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingPackageError("part-quality evaluation needs scipy: pip install 'cerberus-core[eval]', "
                          "or pass `skip=('part_quality',)`") from exc

    samples, part = surface_samples(part_vertices, faces, density)
    _, idx = cKDTree(samples).query(_np(points, np.float64), k=1)
    return part[idx]


def vertex_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(V,)`` a third of the area of every face incident to each vertex (sums to the surface area).

    Example: the unit square as two triangles sharing the diagonal from vertex 0 to vertex 2:

        >>> square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
        >>> vertex_areas(square, np.array([[0, 1, 2], [0, 2, 3]])).round(4)  # the diagonal's ends touch both
        array([0.3333, 0.1667, 0.3333, 0.1667])
    """
    v = _np(vertices, np.float64)
    f = _np(faces, np.int64)
    area = trimesh.triangles.area(v[f])
    return np.bincount(f.reshape(-1), weights=np.repeat(area / 3.0, 3), minlength=len(v))


def overlap_matrix(assignment: np.ndarray, gt_labels: np.ndarray, num_parts: int, num_gt_parts: int,
                   weights: np.ndarray | None = None) -> np.ndarray:
    """``(P, K)`` float64: ``M[p, k]`` = total weight of points with ground-truth label ``k`` assigned
    to predicted part ``p`` (weights default to 1 per point).

    Example: four points, three predicted parts, two ground-truth parts:

        >>> assignment, gt = np.array([0, 0, 1, 2]), np.array([1, 1, 0, 1])
        >>> overlap_matrix(assignment, gt, 3, 2)  # part 0 holds both points of gt part 1
        array([[0., 2.],
               [1., 0.],
               [0., 1.]])
        >>> overlap_matrix(assignment, gt, 3, 2, weights=np.array([1.0, 2.0, 3.0, 4.0]))
        array([[0., 3.],
               [3., 0.],
               [0., 4.]])
    """
    a = _np(assignment, np.int64)
    g = _np(gt_labels, np.int64)
    check_shapes("overlap_matrix", assignment=(a, "N"), gt_labels=(g, "N"))
    if a.size and (a.min() < 0 or a.max() >= num_parts):
        raise MeshError(f"overlap_matrix: assignments must lie in [0, {num_parts}); pass part indices below "
                        "`num_parts`")
    if g.size and (g.min() < 0 or g.max() >= num_gt_parts):
        raise MeshError(f"overlap_matrix: ground-truth labels must lie in [0, {num_gt_parts}); pass labels below "
                        "`num_gt_parts`")
    w = np.ones(a.shape[0]) if weights is None else _np(weights, np.float64)
    return np.bincount(a * num_gt_parts + g, weights=w, minlength=num_parts * num_gt_parts).reshape(
        num_parts, num_gt_parts)


def image_overlap(part_vertices: np.ndarray, faces: np.ndarray, gt_vertices: np.ndarray, gt_faces: np.ndarray,
                  gt_labels: np.ndarray, num_gt_parts: int, *, weighting: str = "area", density: int = 4) -> np.ndarray:
    """The ``P x K`` overlap matrix of one image: assignment, weights and counting in one call.

    Args:
        part_vertices: ``(P, V, 3)`` posed predicted parts; faces ``(F, 3)``.
        gt_vertices, gt_faces: the ground-truth mesh (same world frame).
        gt_labels: ``(V_gt,)`` ground-truth part of each vertex.
        weighting: ``"area"`` (vertex area, default) or ``"count"`` (one per vertex).

    Example (needs scipy): the ground truth is the unit square of :func:`vertex_areas`' example, its left edge
    labelled 0 and its right edge 1; two predicted triangles lie along those edges:

        >>> square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
        >>> square_faces, labels = np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 1, 1, 0])
        >>> tri = np.array([[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 1.0, 0.0]])
        >>> parts, faces = np.stack([tri, tri + [1, 0, 0]]), np.array([[0, 1, 2]])  # (P, V, 3), (F, 3)
        >>> image_overlap(parts, faces, square, square_faces, labels, 2, weighting="count")
        array([[2., 0.],
               [0., 2.]])
        >>> image_overlap(parts, faces, square, square_faces, labels, 2)  # by area: the square's 1.0 in all
        array([[0.5, 0. ],
               [0. , 0.5]])
    """
    if weighting not in ("area", "count"):
        raise ConfigError.about("weighting", weighting, "must be 'area' or 'count'")
    assignment = assign_to_parts(gt_vertices, part_vertices, faces, density)
    weights = vertex_areas(gt_vertices, gt_faces) if weighting == "area" else None
    return overlap_matrix(assignment, gt_labels, _np(part_vertices).shape[0], num_gt_parts, weights)


_SIDE_SUFFIX = re.compile(r"[._-](l|r|left|right)$", re.IGNORECASE)
_SIDE_WORDS = {"l", "r", "left", "right"}


def side_free(name: str) -> str:
    """A part name without its side: ``shin.L`` → ``shin``, ``front_left_leg`` → ``front_leg``,
    ``left_hand`` → ``hand``; a name without one is returned as it is.

    Example:
        >>> [side_free(n) for n in ["shin.L", "front_left_leg", "left_hand", "Hand_R", "head"]]
        ['shin', 'front_leg', 'hand', 'Hand', 'head']
    """
    base = _SIDE_SUFFIX.sub("", name)
    words = [w for w in base.split("_") if w.lower() not in _SIDE_WORDS or w == base]
    return "_".join(words) or name


def merge_sides(names: Sequence[str]) -> tuple[list[str], np.ndarray]:
    """Merge the left and right versions of part names (:func:`side_free`).

    Returns:
        ``(merged, index)``: the merged names in first-seen order and ``(K,)`` int64, each name's
        position in ``merged``.

    Example:
        >>> merge_sides(["shin.L", "shin.R", "head", "front_left_leg", "front_right_leg"])
        (['shin', 'head', 'front_leg'], array([0, 0, 1, 2, 2]))
    """
    merged = list(dict.fromkeys(side_free(n) for n in names))
    return merged, np.array([merged.index(side_free(n)) for n in names], dtype=np.int64)


def _entropy_bits(counts: Sequence[int]) -> float:
    total = float(sum(counts))
    return float(-sum((c / total) * math.log2(c / total) for c in counts if c > 0)) + 0.0 if total else 0.0


def segmentation_iou(overlap: np.ndarray, labels: np.ndarray, names: Sequence[str]) -> dict[str, float]:
    """Per ground-truth part, the IoU of the learned parts renamed to it against it, by area (step 4 of the module
    docstring).

    Args:
        overlap: ``(P, K)`` the overlap matrices summed over the images (:func:`overlap_matrix`: the area, or
            vertex count, of ground-truth part ``k`` assigned to learned part ``p``).
        labels: ``(P,)`` each learned part's label, an index into ``names`` (-1: never used, renamed to none).
        names: the ``K`` ground-truth part names.
    Returns:
        ``{name: IoU}`` in [0, 1], by area: of ground-truth part ``k`` against the learned parts labelled ``k``, the
        area they share (``overlap[p, k]`` over those parts) over the area of either (their rows' totals plus
        column ``k``'s, less the shared); NaN for a part with no area on either side (nothing to score, as
        :func:`~cerberus_core.eval.masks.mask_iou` says of two empty masks).

    Example:
        >>> overlap = np.array([[3.0, 1.0, 0.0], [0.0, 2.0, 0.0], [1.0, 0.0, 0.0]])  # 3 learned, 3 gt parts
        >>> segmentation_iou(overlap, np.array([0, 1, 0]), ["head", "body", "tail"])  # head: 4 of 3 + 1 + 1
        {'head': 0.8, 'body': 0.666..., 'tail': nan}
    """
    overlap, labels = np.asarray(overlap, dtype=np.float64), np.asarray(labels)
    check_shapes("segmentation_iou", overlap=(overlap, f"P {len(names)}"), labels=(labels, "P"))
    renamed = labels[:, None] == np.arange(len(names))[None, :]  # (P, K): part p is labelled k
    shared = (overlap * renamed).sum(0)  # (K,)
    either = (overlap.sum(1, keepdims=True) * renamed).sum(0) + overlap.sum(0) - shared
    with np.errstate(invalid="ignore", divide="ignore"):
        ious = np.where(either > 0, shared / either, np.nan)
    return dict(zip(names, ious.tolist(), strict=True))


@dataclass
class PartQuality:
    """The learned parts against the ground-truth semantic parts over a test set: the accumulator of the
    ``part_quality`` row of :data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS`. One ``(P, K)`` overlap
    matrix per image (:func:`image_overlap`), in one part vocabulary; then consistency and segmentation IoU.

    The evaluation feeds it :class:`~cerberus_core.eval.accumulators.BatchResult` s (:meth:`update`);
    :meth:`add` takes one image's overlap matrix directly.

    Args:
        weighting: vertex weights of the overlap, ``"area"`` or ``"count"``; density: surface lattice steps
            per predicted triangle edge (:func:`image_overlap`).
        num_parts: predicted parts ``P`` (``None``: the first batch's).
        gt_part_names: names of the ``K`` ground-truth parts (``None``: the first image's).

    Example: two learned parts, two ground-truth parts, two images' ``(P, K)`` overlap matrices added by hand
    (areas):

        >>> pq = PartQuality(num_parts=2, gt_part_names=["head", "tail"])
        >>> pq.add(np.array([[3.0, 1.0], [0.0, 2.0]]), "s1")  # image 1: part 0 covers mostly head
        >>> pq.add(np.array([[1.0, 2.0], [0.0, 4.0]]), "s1")  # image 2: part 0 covers mostly tail
        >>> pq.labels()  # the majority over both images: part 0 -> head (4 of 7), part 1 -> tail
        array([0, 1])
        >>> s = pq.summary()
        >>> [(p["label"], p["agreement"], p["entropy_bits"], round(p["purity"], 3)) for p in s["parts"]]
        [('head', 0.5, 1.0, 0.571), ('tail', 1.0, 0.0, 1.0)]
        >>> s["consistency"], s["mean_entropy_bits"], {k: round(v, 3) for k, v in s["segmentation_iou"].items()}
        (0.75, 0.5, {'head': 0.571, 'tail': 0.667})
    """

    weighting: str = "area"
    density: int = 4
    num_parts: int | None = None
    gt_part_names: list[str] | None = None
    overlaps: list[np.ndarray] = field(default_factory=list)
    groups: list[str] = field(default_factory=list)

    @classmethod
    def for_evaluation(cls, context: Any) -> PartQuality:
        """From an :class:`~cerberus_core.eval.accumulators.EvalContext`: its config's weighting and density."""
        return cls(context.config.weighting, context.config.density)

    @property
    def num_gt_parts(self) -> int:
        return len(self.gt_part_names)

    def update(self, batch: Any) -> None:
        """Add each image's overlap matrix (its subject as the group); every image must share the first one's
        ground-truth part names, else a :class:`DatasetError`."""
        faces = batch.recon.faces.numpy()
        for b, item, one, _, _ in batch.scored():
            body = batch.bodies[b]
            self.gt_part_names = one_vocabulary(self.gt_part_names, item.index, body.part_names, "part quality")
            self.num_parts = batch.recon.num_parts if self.num_parts is None else self.num_parts
            self.add(image_overlap(one.posed()[0].numpy(), faces, body.vertices, body.faces, body.vertex_parts,
                                   len(body.part_names), weighting=self.weighting, density=self.density), item.subject)

    def add(self, overlap: np.ndarray, group: str = "") -> None:
        """Record one image's ``(P, K)`` overlap matrix; ``group`` is its subject or species."""
        vocabulary_set("PartQuality", self.gt_part_names, self.num_parts, key="gt_part_names")
        m = np.asarray(overlap, dtype=np.float64)
        check_shapes("PartQuality.add", overlap=(m, f"{self.num_parts} {self.num_gt_parts}"))
        self.overlaps.append(m)
        self.groups.append(str(group))

    def labels(self) -> np.ndarray:
        """``(P,)`` each predicted part's majority ground-truth part over all images (-1: never used)."""
        total = np.sum(self.overlaps, axis=0)
        return np.where(total.sum(1) > 0, total.argmax(1), -1)

    def merged_sides(self) -> PartQuality | None:
        """The same images with left and right ground-truth parts merged (:func:`merge_sides`), or
        ``None`` when no part name has a side."""
        names, index = merge_sides(self.gt_part_names)
        if len(names) == self.num_gt_parts:
            return None
        onehot = np.zeros((self.num_gt_parts, len(names)))
        onehot[np.arange(self.num_gt_parts), index] = 1.0
        return replace(self, gt_part_names=names, overlaps=[m @ onehot for m in self.overlaps], groups=list(self.groups))

    def summary(self) -> dict[str, Any] | None:
        """Consistency per predicted part and the segmentation IoU (see the module docstring).

        Returns a dict: ``images`` (int), ``gt_parts`` (K names), ``part_labels`` (bool: at least two
        ground-truth parts carry area; ``False``: no part labels, nothing is scored), ``note`` (one
        line when ``part_labels`` is ``False``, else ``None``), ``parts`` (one dict per learned part:
        part, label, images, agreement, entropy_bits, purity, agreement_by_group), ``consistency``,
        ``mean_entropy_bits``, ``gt_parts_covered`` (how many of the ``K`` ground-truth parts are some learned
        part's label: consistency and entropy are only meaningful beside it, since one part labelled ``torso`` in
        every image scores consistency 1 and entropy 0), ``unused_parts``, ``segmentation_iou`` ({gt part: IoU}) and
        ``mean_segmentation_iou`` (floats in [0, 1], entropy in bits; ``None`` without part labels),
        and ``sides_merged``: the same summary with left and right merged (:meth:`merged_sides`;
        ``None`` without part labels or when no part has a side); ``None`` when no image was added.
        """
        if not self.overlaps:
            return None
        stack = np.stack(self.overlaps)  # (N, P, K)
        present = [self.gt_part_names[k] for k in np.flatnonzero(stack.sum(axis=(0, 1)) > 0)]
        if len(present) < 2:
            return {
                "images": len(self.overlaps),
                "gt_parts": list(self.gt_part_names),
                "part_labels": False,
                "note": (f"no part labels: the ground truth has {len(present)} labelled part"
                         f"{'' if len(present) == 1 else 's'} ({', '.join(present) or 'none'}), so part quality "
                         "is not scored; give the meshes per-vertex part labels (parts.npy) to score it"),
                "parts": [],
                "consistency": None,
                "mean_entropy_bits": None,
                "gt_parts_covered": None,
                "unused_parts": [],
                "segmentation_iou": {},
                "mean_segmentation_iou": None,
                "sides_merged": None,
            }
        labels = self.labels()
        names = self.gt_part_names
        parts = []
        for p in range(self.num_parts):
            used = stack[:, p].sum(1) > 0
            majority = stack[used, p].argmax(1)
            row: dict[str, Any] = {"part": p, "label": names[labels[p]] if labels[p] >= 0 else None,
                                   "images": int(used.sum())}
            if labels[p] >= 0:
                agree = majority == labels[p]
                row["agreement"] = float(agree.mean())
                row["entropy_bits"] = _entropy_bits(list(Counter(majority.tolist()).values()))
                row["purity"] = float(stack[:, p, labels[p]].sum() / stack[:, p].sum())
                groups = np.asarray(self.groups)[used]
                row["agreement_by_group"] = {str(g): float(agree[groups == g].mean()) for g in sorted(set(groups))}
            parts.append(row)
        used_rows = [r for r in parts if r["label"] is not None]

        iou = segmentation_iou(stack.sum(0), labels, names)
        valid = [v for v in iou.values() if not math.isnan(v)]  # a part with no area on either side has no IoU
        return {
            "images": len(self.overlaps),
            "gt_parts": list(names),
            "part_labels": True,
            "note": None,
            "parts": parts,
            "consistency": float(np.mean([r["agreement"] for r in used_rows])) if used_rows else float("nan"),
            "mean_entropy_bits": float(np.mean([r["entropy_bits"] for r in used_rows])) if used_rows else float("nan"),
            "gt_parts_covered": len({int(k) for k in labels if k >= 0}),
            "unused_parts": [r["part"] for r in parts if r["label"] is None],
            "segmentation_iou": iou,
            "mean_segmentation_iou": float(np.mean(valid)) if valid else float("nan"),
            "sides_merged": None if (merged := self.merged_sides()) is None else merged.summary(),
        }


def part_quality_section(result: Mapping[str, Any]) -> list[str]:
    """The report's part-quality section from a result's JSON form: consistency per learned part (with its
    visibility in the input view when that ran) and segmentation IoU per ground-truth part, per side and
    with left and right merged; one line when the data has no part labels."""
    pq, vis = result["part_quality"], result.get("part_visibility")
    if pq.get("part_labels") is False:  # data without part labels: say so, score nothing
        return ["## Part quality", "", f"Not scored: {pq['note']}.", ""]
    out = ["## Part quality (ground-truth semantic parts, never seen in training)", "",
           f"Consistency (mean agreement) {fmt(pq['consistency'])}, mean entropy "
           f"{fmt(pq['mean_entropy_bits'], 3)} bits, mean segmentation IoU {fmt(pq['mean_segmentation_iou'])} "
           f"over {pq['images']} images; the learned parts' labels cover {_covered(pq)} ground-truth parts. "
           "Consistency and entropy are only meaningful together with that count: a model whose one part is "
           "labelled the same part in every image scores consistency 1 and entropy 0 while covering 1 of them.", ""]
    out += [visibility_sentence(vis), ""] if vis else []
    prow = [[p["part"], p["label"] or "(unused)", p.get("agreement"), p.get("entropy_bits"), p.get("purity"),
             p["images"], *visibility_cells(vis, p["part"])] for p in pq["parts"]]
    out += [markdown_table(["Learned part", "Majority GT part", "Agreement", "Entropy (bits)", "Purity", "Images",
                            *visibility_header(vis)], prow, 3), ""]
    out += [markdown_table(["GT part", "Segmentation IoU"], list(pq["segmentation_iou"].items()), 3), ""]
    merged = pq.get("sides_merged")
    return out + (_merged_sides(merged) if merged else [])


def _covered(pq: Mapping[str, Any]) -> str:
    """``"4 of 8"``: how many of the ground-truth parts the learned parts' labels cover (counted from the labels of
    ``parts`` in a ``results.json`` written before ``gt_parts_covered`` was recorded)."""
    covered = pq.get("gt_parts_covered")
    if covered is None:
        covered = len({p["label"] for p in pq["parts"] if p.get("label") is not None})
    return f"{covered} of {len(pq['gt_parts'])}"


def _merged_sides(merged: Mapping[str, Any]) -> list[str]:
    """The part-quality tables again, with left and right merged."""
    rows = [[p["part"], p["label"] or "(unused)", p.get("agreement"), p.get("entropy_bits"), p.get("purity")]
            for p in merged["parts"]]
    return ["### With left and right merged", "",
            "A grey, untextured body seen from the front or the back looks the same, so no image says which "
            "limb is the body's left: per-side agreement is capped near 0.5 by the data, not the model. "
            f"Merged: consistency {fmt(merged['consistency'])}, mean entropy {fmt(merged['mean_entropy_bits'], 3)} "
            f"bits, mean segmentation IoU {fmt(merged['mean_segmentation_iou'])}; the labels cover {_covered(merged)} "
            "ground-truth parts.", "",
            markdown_table(["Learned part", "Majority GT part", "Agreement", "Entropy (bits)", "Purity"], rows, 3), "",
            markdown_table(["GT part", "Segmentation IoU"], list(merged["segmentation_iou"].items()), 3), ""]
