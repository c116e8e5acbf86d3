"""Public Python API. Every metric takes ``(pred, gt, **options)`` and returns a float.

``pred`` and ``gt`` accept: a mesh file path (anything pymeshlab reads), a
``trimesh.Trimesh``/``trimesh.Scene``, a ``(vertices (V,3), faces (F,3))`` pair of arrays,
a :class:`~cerberus_metrics.io.Mesh`, or a list of those meaning the union of parts.
Coordinates are in the caller's units; the protocol decides how they map to voxels.

These functions are registered under the ``cerberus.metrics`` entry-point group as
``voxel_iou``, ``chamfer_l2`` and ``fscore``.

Each public function has an example (run by ``tests/repo/test_doctests.py``) on a cube of side 0.5 and the
same cube moved by half its side.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from typing import Any

import numpy as np

from .cache import CachedGrid, GridCache
from .distances import PointDistances, check_samples, point_distances
from .io import (
    OPEN_MESH_POLICIES,
    MeshInputError,
    MeshQualityWarning,
    MeshReport,
    OpenMeshError,
    content_digest,
    load_parts,
    mesh_labels,
)
from .protocols import Frame, get_protocol, make_frame
from .voxelize import PartGrids, VoxelGrid, grid_iou, voxelize_parts

__all__ = [
    "voxelize",
    "voxel_iou",
    "voxel_iou_clamped",
    "chamfer_l2",
    "fscore",
    "evaluate_pair",
    "inspect_mesh",
    "METRICS",
]

METRICS = ("voxel_iou", "chamfer_l2", "fscore")


def voxelize(
    mesh: Any,
    protocol: str = "kato",
    resolution: int = 32,
    *,
    frame: Frame | None = None,
    fill: bool = True,
    cache: GridCache | None = None,
    check_self_intersections: bool | str = True,
    open_mesh: str = "warn",
    name: str = "mesh",
    outside: str = "error",
) -> VoxelGrid:
    """Voxelize a mesh (or the union of parts) into a solid occupancy grid.

    mesh: see module docstring. protocol: ``"kato"`` | ``"gt_bbox"`` | ``"gt_bbox_center"``.
    resolution: voxels per grid side R (the paper uses 32).
    frame: lattice frame to use (it fixes the resolution, overriding ``resolution``); default:
    the protocol's frame built from this mesh (so voxelize the ground truth first and pass
    ``frame=gt_grid.frame`` for the prediction).
    fill: False returns only the surface voxels (``surface``-rule protocols).
    cache: a :class:`GridCache`; the key hashes the mesh content and all options.
    open_mesh: ``"warn"`` | ``"close"`` | ``"error"`` for non-watertight meshes (see docs).
    name: how messages name this mesh.
    outside: ``"error"`` (default) | ``"clamp"``: what the ``kato`` protocol does with a part reaching
    outside its grid ``[0, R)^3`` (``[-16/31, 16/31]^3`` mesh units at R = 32). ``"clamp"`` is one rule
    for faces, edges and corners alike: the part is voxelized whole and its voxels outside the grid
    are dropped (a part wholly outside adds no voxel). Returns a :class:`VoxelGrid` whose ``clamped``
    counts the parts so clamped.

    >>> import trimesh
    >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
    >>> grid = voxelize(cube)  # the paper's kato protocol, 32^3
    >>> grid.occupancy.shape, int(grid.occupancy.sum())
    ((32, 32, 32), 4096)
    """
    return _grid(mesh, protocol, resolution, frame=frame, fill=fill, cache=cache,
                 check_self_intersections=check_self_intersections, open_mesh=open_mesh, name=name, outside=outside)


def _grid(mesh: Any, protocol: str, resolution: int, *, frame: Frame | None = None, fill: bool = True,
          cache: GridCache | None = None, check_self_intersections: bool | str = True, open_mesh: str = "warn",
          name: str = "mesh", outside: str = "error", ground_truth: bool = False,
          open_mesh_option: str = "open_mesh") -> VoxelGrid:
    """:func:`voxelize`; ``ground_truth``: the mesh is a ground truth (which is never clamped: only the fix its
    outside-the-grid error names changes, so it is not part of the cache key). ``open_mesh_option``: the name of
    the option that set ``open_mesh``, which the messages name (see :func:`prediction_grids`)."""
    proto = get_protocol(protocol)
    key = labels = None
    if cache is not None:
        labels = mesh_labels(mesh, name, open_mesh)  # a hit replays its warnings only if they name these parts
        key = GridCache.make_key(
            content_digest(mesh),
            protocol=proto.name,
            resolution=resolution,
            frame=None if frame is None else [frame.scale, *frame.shift, frame.resolution, frame.fixed],
            fill=fill,
            self_intersections=check_self_intersections,
            open_mesh=open_mesh,
            **({"outside": outside} if outside != "error" else {}),  # keys of existing caches stay valid
            # The cached warnings name the option; under "error" none does (an open mesh raises), so those keys,
            # and every key of the option "open_mesh", stay those of existing caches.
            **({"open_mesh_option": open_mesh_option} if open_mesh_option != "open_mesh" and open_mesh != "error"
               else {}),
        )
        hit = cache.get(key, labels)
        if hit is not None:
            for msg in hit.messages:
                warnings.warn(msg, MeshQualityWarning, stacklevel=3)
            return hit.grid
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeshQualityWarning)
        grid = _part_grids(mesh, proto.name, resolution, frame, fill, check_self_intersections, open_mesh, name,
                           outside, ground_truth, open_mesh_option).union()
    messages = tuple(str(w.message) for w in caught if issubclass(w.category, MeshQualityWarning))
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if cache is not None and key is not None:
        cache.put(key, CachedGrid(grid, messages, labels))
    return grid


def _part_grids(mesh: Any, protocol: str, resolution: int, frame: Frame | None, fill: bool,
                check_self_intersections: bool | str, open_mesh: str, name: str, outside: str,
                ground_truth: bool = False, open_mesh_option: str = "open_mesh") -> PartGrids:
    """Load ``mesh``'s parts and voxelize each alone (the one voxelization path of this module)."""
    proto = get_protocol(protocol)
    parts = load_parts(mesh, name, check_self_intersections=check_self_intersections, open_mesh=open_mesh,
                       open_mesh_option=open_mesh_option)
    if frame is None:
        frame = make_frame(proto, resolution, np.concatenate([p.vertices for p in parts]))
    return voxelize_parts(parts, proto, frame, fill=fill, outside=outside, ground_truth=ground_truth,
                          open_mesh_option=open_mesh_option)


def _check_gt_open_mesh(gt_open_mesh: str) -> str:
    """``gt_open_mesh``, or a :class:`MeshInputError` when it is not an open-mesh policy."""
    if gt_open_mesh not in OPEN_MESH_POLICIES:
        raise MeshInputError(f"gt_open_mesh must be one of {OPEN_MESH_POLICIES}, got {gt_open_mesh!r}")
    return gt_open_mesh


def _gt_grid(gt: Any, protocol: str, resolution: int, cache: GridCache | None, check_self_intersections: bool | str,
             open_mesh: str, gt_open_mesh: str | None) -> VoxelGrid:
    """The ground truth's grid for :func:`prediction_grids`: under ``open_mesh`` (the prediction's option), or
    under its own ``gt_open_mesh`` when given, which its warnings and its :class:`OpenMeshError` then name."""
    own = gt_open_mesh is not None
    policy = open_mesh if gt_open_mesh is None else _check_gt_open_mesh(gt_open_mesh)
    try:
        return _grid(gt, protocol, resolution, cache=cache, name="gt", ground_truth=True,
                     check_self_intersections=check_self_intersections, open_mesh=policy,
                     open_mesh_option="gt_open_mesh" if own else "open_mesh")
    except OpenMeshError as exc:
        if not own:
            raise
        raise OpenMeshError(
            f"{exc.report.name}: the ground truth is not watertight ({', '.join(exc.report.problems())}), so "
            "the flood fill would enter through its holes and score it as a hollow shell (its surface voxels "
            "alone) against every prediction; close the mesh, or pass gt_open_mesh='close' to close its holes "
            "with pymeshlab",
            exc.report,
        ) from None


def prediction_grids(pred: Any, gt: Any, protocol: str, resolution: int, cache: GridCache | None, outside: str,
                     check_self_intersections: bool | str = True, open_mesh: str = "warn", *,
                     gt_open_mesh: str | None = None, gt_check_self_intersections: bool | str | None = None,
                     quiet_pred: bool = False) -> tuple[PartGrids, VoxelGrid]:
    """Voxelize a prediction against a ground truth: the grids :func:`voxel_iou_clamped` and
    :class:`~cerberus_metrics.scoring.VoxelIoUScorer` score, with the prediction kept part by part. The ground
    truth is voxelized (and cached in ``cache``) as by :func:`voxelize`, each part of ``pred`` (one per mesh of
    the list, mesh units) alone in the ground truth's frame. ``grid_iou(parts.union(), gt)`` is the voxel IoU and
    ``parts.clamped`` the number of parts clamped into the grid.

    protocol, resolution, cache: as :func:`voxel_iou_clamped`'s. outside, check_self_intersections, open_mesh:
    the prediction's options (see :func:`voxelize`), and the ground truth's unless given apart:
    gt_open_mesh: the ground truth's ``"warn"`` | ``"close"`` | ``"error"`` (default None: ``open_mesh``); its
    warnings and errors then name ``gt_open_mesh``, and an open ground truth it refuses raises
    :class:`~cerberus_metrics.io.OpenMeshError` saying that the flood fill would score a hollow shell.
    gt_check_self_intersections: the ground truth's (default None: ``check_self_intersections``).
    quiet_pred: silence the prediction's :class:`MeshQualityWarning` (the ground truth's are still issued).
    A ground truth outside the ``kato`` grid is always an error, whatever ``outside`` says.
    Returns ``(parts, gt)``: the prediction's :class:`PartGrids` (occupancy (P, nx, ny, nz) bool) and the ground
    truth's :class:`VoxelGrid` (occupancy (nx', ny', nz') bool), on one frame; their boxes may differ (a
    ``gt_bbox`` lattice grows to hold the prediction), and :func:`grid_iou` aligns them by their origins.

    >>> import trimesh
    >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
    >>> parts, gt = prediction_grids([cube, moved], cube, "kato", 32, None, "clamp", gt_open_mesh="error")
    >>> parts.occupancy.shape, gt.occupancy.shape, parts.clamped
    ((2, 32, 32, 32), (32, 32, 32), 0)
    >>> round(grid_iou(parts.union(), gt), 4)  # 4096 of the union's 6144 voxels
    0.6667
    """
    g_check = check_self_intersections if gt_check_self_intersections is None else gt_check_self_intersections
    g = _gt_grid(gt, protocol, resolution, cache, g_check, open_mesh, gt_open_mesh)
    with warnings.catch_warnings():  # the caller's filters come back on the way out
        if quiet_pred:
            warnings.simplefilter("ignore", MeshQualityWarning)
        parts = _part_grids(pred, protocol, resolution, g.frame, True, check_self_intersections, open_mesh, "pred",
                            outside)
    return parts, g


def voxel_iou_clamped(
    pred: Any,
    gt: Any,
    protocol: str = "kato",
    resolution: int = 32,
    *,
    cache: GridCache | None = None,
    check_self_intersections: bool | str = True,
    open_mesh: str = "warn",
    outside: str = "clamp",
) -> tuple[float, int]:
    """:func:`voxel_iou` that also says how many prediction parts were clamped into the grid.

    outside: for the prediction only (see :func:`voxelize`; default ``"clamp"``); a ground truth
    outside the ``kato`` grid is always an error, since it is a data problem, not a score.
    Returns ``(iou in [0, 1], number of prediction parts clamped)``.

    >>> import trimesh
    >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
    >>> iou, clamped = voxel_iou_clamped(cube, moved)
    >>> round(iou, 2), clamped
    (0.34, 0)
    """
    p, g = prediction_grids(pred, gt, protocol, resolution, cache, outside,
                            check_self_intersections=check_self_intersections, open_mesh=open_mesh)
    return grid_iou(p.union(), g), p.clamped


def voxel_iou(
    pred: Any,
    gt: Any,
    protocol: str = "kato",
    resolution: int = 32,
    *,
    cache: GridCache | None = None,
    check_self_intersections: bool | str = True,
    open_mesh: str = "warn",
    outside: str = "error",
) -> float:
    """Voxel IoU |P & G| / |P | G| between a prediction (mesh or list of parts) and a ground truth.

    protocol/resolution: see :func:`voxelize`; the default is the paper's ``kato`` at 32^3.
    cache: optional :class:`GridCache` for ground-truth grids (keyed by content hash).
    outside: ``"error"`` | ``"clamp"`` for prediction parts outside the ``kato`` grid (see
    :func:`voxelize`); :func:`voxel_iou_clamped` and :func:`evaluate_pair` also report the count.
    Returns a float in [0, 1].

    >>> import trimesh
    >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
    >>> voxel_iou(cube, cube), round(voxel_iou(cube, moved), 2)  # a third of the union is shared
    (1.0, 0.34)
    """
    return voxel_iou_clamped(pred, gt, protocol, resolution, cache=cache, outside=outside,
                             check_self_intersections=check_self_intersections, open_mesh=open_mesh)[0]


def _distances(pred: Any, gt: Any, n_samples: int, seed: int, normalize: bool) -> PointDistances:
    check_samples(n_samples)  # before the meshes are read
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MeshQualityWarning)  # surface sampling needs no closed surface
        p = load_parts(pred, "pred", check_self_intersections=False)
        g = load_parts(gt, "gt", check_self_intersections=False)
    return point_distances(p, g, n_samples, seed, normalize)


def chamfer_l2(pred: Any, gt: Any, n_samples: int = 100_000, seed: int = 0, normalize: bool = False) -> float:
    """Chamfer-L2: mean squared nearest distance pred->gt plus gt->pred, on sampled surfaces.

    n_samples points per surface, seeds ``seed`` (pred) and ``seed + 1`` (gt). A shape of parts is sampled on
    all its parts' surfaces, also where a part lies inside another (unlike the voxel IoU, which scores the
    union of the solids): see :func:`~cerberus_metrics.distances.sample_surface`.
    normalize: scale both by the GT bounding box (centre at 0, longest side 1) first.
    Returns mesh units squared (or GT-relative units when normalize=True).

    >>> import trimesh
    >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
    >>> chamfer_l2(cube, moved, n_samples=2000) > chamfer_l2(cube, cube, n_samples=2000)
    True
    """
    return _distances(pred, gt, n_samples, seed, normalize).chamfer_l2()


def fscore(
    pred: Any,
    gt: Any,
    threshold: float = 0.01,
    n_samples: int = 100_000,
    seed: int = 0,
    normalize: bool = False,
) -> float:
    """F-score at ``threshold`` (mesh units, or GT-relative when normalize=True) on sampled surfaces.

    Sampling as :func:`chamfer_l2`'s: surface of a part buried inside another part is sampled too, so it
    counts against precision where it lies farther than ``threshold`` from the ground truth.

    >>> import trimesh
    >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
    >>> fscore(cube, cube, threshold=0.05, n_samples=2000)
    1.0
    """
    return _distances(pred, gt, n_samples, seed, normalize).fscore(threshold)[0]


def evaluate_pair(
    pred: Any,
    gt: Any,
    metrics: Iterable[str] = ("voxel_iou",),
    *,
    protocol: str = "kato",
    resolution: int = 32,
    n_samples: int = 100_000,
    seed: int = 0,
    threshold: float = 0.01,
    normalize: bool = False,
    cache: GridCache | None = None,
    check_self_intersections: bool | str = True,
    open_mesh: str = "warn",
    outside: str = "error",
) -> dict[str, float]:
    """Several metrics for one pair; surfaces are sampled once for Chamfer and F-score.

    outside: ``"error"`` | ``"clamp"`` for prediction parts outside the ``kato`` grid (see
    :func:`voxelize`; Chamfer and F-score use the meshes as they are).
    Returns ``{"voxel_iou": .., "clamped_parts": .., "chamfer_l2": .., "fscore": .., "precision": ..,
    "recall": ..}`` restricted to the requested metrics (precision/recall come with fscore,
    ``clamped_parts``, the number of prediction parts clamped into the grid, with voxel_iou).

    >>> import trimesh
    >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
    >>> evaluate_pair(cube, moved)
    {'voxel_iou': 0.343..., 'clamped_parts': 0}
    """
    metrics = list(metrics)
    unknown = sorted(set(metrics) - set(METRICS))
    if unknown:
        raise MeshInputError(f"unknown metric(s) {unknown}; choose from {list(METRICS)}")
    out: dict[str, float] = {}
    if "voxel_iou" in metrics:
        out["voxel_iou"], out["clamped_parts"] = voxel_iou_clamped(
            pred,
            gt,
            protocol,
            resolution,
            cache=cache,
            check_self_intersections=check_self_intersections,
            open_mesh=open_mesh,
            outside=outside,
        )
    if "chamfer_l2" in metrics or "fscore" in metrics:
        d = _distances(pred, gt, n_samples, seed, normalize)
        if "chamfer_l2" in metrics:
            out["chamfer_l2"] = d.chamfer_l2()
        if "fscore" in metrics:
            out["fscore"], out["precision"], out["recall"] = d.fscore(threshold)
    return out


def inspect_mesh(mesh: Any, name: str = "mesh", check_self_intersections: bool | str = True) -> list[MeshReport]:
    """Clean a mesh (or parts) with pymeshlab and report what was removed and what is still wrong.

    >>> import trimesh
    >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
    >>> report, = inspect_mesh(cube)
    >>> report.faces, report.boundary_edges, report.volume
    (12, 0, 0.125)
    """
    return [p.report for p in load_parts(mesh, name, check_self_intersections=check_self_intersections)]
