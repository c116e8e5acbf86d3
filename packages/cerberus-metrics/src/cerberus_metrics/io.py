"""Mesh input: coercion, validation, loading and cleaning through pymeshlab.

Every mesh that enters a metric goes through :func:`load_parts`, which

1. turns the input (file path, ``trimesh.Trimesh``/``trimesh.Scene``,
   ``(vertices, faces)`` pair, :class:`Mesh`, or a list of those = parts)
   into triangle arrays, reading files with pymeshlab;
2. validates the arrays (shape, finite coordinates, face indices in range),
   raising :class:`MeshInputError` that names the argument/file, the problem
   and the fix;
3. cleans the mesh with pymeshlab (duplicate vertices, duplicate faces,
   zero-area faces, unreferenced vertices), in that order;
4. measures watertightness and manifoldness (pymeshlab topological measures)
   and, optionally, self-intersections, into a :class:`MeshReport`;
5. optionally closes holes with pymeshlab (``open_mesh="close"``).

Units: coordinates are returned unchanged (float64, the caller's units).
"""

from __future__ import annotations

import errno
import hashlib
import os
import stat
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pymeshlab

from .errors import MetricsError
from .filecheck import FileDefect, check_counts, scan_mesh_file

__all__ = [
    "MeshInputError",
    "OpenMeshError",
    "MeshQualityWarning",
    "Mesh",
    "MeshReport",
    "load_mesh",
    "load_parts",
    "content_digest",
    "MESH_SUFFIXES",
]

#: File suffixes treated as meshes when a folder is scanned (pymeshlab reads more).
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf", ".3ds", ".dae", ".wrl", ".ptx")

OPEN_MESH_POLICIES = ("warn", "close", "error")


class MeshInputError(MetricsError, ValueError):
    """An input mesh cannot be evaluated. The message names the input, the problem and the fix."""


class OpenMeshError(MeshInputError):
    """A mesh that must be closed is not watertight (``open_mesh="error"``, or a ground truth under
    ``gt_open_mesh="error"``: :func:`~cerberus_metrics.api.prediction_grids`,
    :class:`~cerberus_metrics.scoring.VoxelIoUScorer`). ``report``: its :class:`MeshReport` (the defect counts)."""

    def __init__(self, message: str, report: MeshReport) -> None:
        super().__init__(message)
        self.report = report


class MeshQualityWarning(UserWarning):
    """An input mesh is evaluated, but is open, non-manifold or self-intersecting (see the message)."""


@dataclass(frozen=True)
class MeshReport:
    """What cleaning removed and what is still wrong with one mesh (after cleaning).

    Counts are numbers of elements; ``volume`` is the signed enclosed volume in
    the mesh's units cubed (divergence theorem; meaningful only when watertight).
    ``self_intersecting_faces`` is ``None`` when the check was not run;
    ``self_intersection_check`` says how it was answered: ``"pymeshlab"``,
    ``"star-shaped certificate"`` (see :func:`star_shaped`) or ``"skipped"``.
    """

    name: str
    vertices: int
    faces: int
    removed_duplicate_vertices: int = 0
    removed_duplicate_faces: int = 0
    removed_null_faces: int = 0
    removed_unreferenced_vertices: int = 0
    boundary_edges: int = 0
    non_manifold_edges: int = 0
    non_manifold_vertices: int = 0
    self_intersecting_faces: int | None = None
    self_intersection_check: str = "skipped"
    holes_closed: int = 0
    volume: float = 0.0

    @property
    def watertight(self) -> bool:
        """True when every edge has exactly two faces (no boundary, no non-manifold edge)."""
        return self.boundary_edges == 0 and self.non_manifold_edges == 0

    @property
    def self_intersecting(self) -> bool:
        return bool(self.self_intersecting_faces)

    def problems(self) -> list[str]:
        """Human-readable list of the defects left after cleaning (empty when clean)."""
        out = []
        if self.boundary_edges:
            out.append(f"{self.boundary_edges} boundary (open) edges")
        if self.non_manifold_edges:
            out.append(f"{self.non_manifold_edges} non-manifold edges")
        if self.non_manifold_vertices:
            out.append(f"{self.non_manifold_vertices} non-manifold vertices")
        if self.self_intersecting_faces:
            out.append(f"{self.self_intersecting_faces} self-intersecting faces")
        return out

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["watertight"] = self.watertight
        return d


@dataclass(frozen=True)
class Mesh:
    """A validated, cleaned triangle mesh.

    vertices: (V, 3) float64, the caller's units. faces: (F, 3) int64 indices into vertices.
    """

    vertices: np.ndarray
    faces: np.ndarray
    name: str
    report: MeshReport | None = field(default=None, compare=False)

    @property
    def triangles(self) -> np.ndarray:
        """(F, 3, 3) float64 corner coordinates."""
        return self.vertices[self.faces]


# --------------------------------------------------------------------------- coercion


def _is_vf_pair(obj: Any) -> bool:
    """A 2-sequence of array-likes of ndim 2 is one mesh (vertices, faces), not two parts."""
    if not isinstance(obj, (tuple, list)) or len(obj) != 2:
        return False
    if any(isinstance(x, (str, os.PathLike, Mesh)) or hasattr(x, "vertices") for x in obj):
        return False
    try:
        return all(np.asarray(x).ndim == 2 for x in obj)
    except (ValueError, TypeError):  # ragged nested lists are not arrays
        return False


def _split_parts(obj: Any) -> list[Any]:
    """Flatten an input into a list of single-mesh inputs."""
    if obj is None:
        raise MeshInputError("mesh input is None; pass a file path, a trimesh, or a (vertices, faces) pair")
    if isinstance(obj, (str, os.PathLike, Mesh)) or _is_vf_pair(obj) or hasattr(obj, "faces"):
        return [obj]
    if hasattr(obj, "dump") and hasattr(obj, "geometry"):  # trimesh.Scene
        return list(obj.dump())
    if isinstance(obj, dict) and "vertices" in obj and "faces" in obj:
        return [(obj["vertices"], obj["faces"])]
    if isinstance(obj, (list, tuple)):
        out: list[Any] = []
        for item in obj:
            out.extend(_split_parts(item))
        return out
    raise MeshInputError(
        f"unsupported mesh input of type {type(obj).__name__}; pass a file path, a trimesh.Trimesh, "
        "a (vertices, faces) pair of arrays, or a list of those (parts)"
    )


def _arrays_of(obj: Any, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Raw (vertices, faces) of an in-memory mesh input, before validation."""
    if isinstance(obj, Mesh):
        return obj.vertices, obj.faces
    if hasattr(obj, "vertices") and hasattr(obj, "faces"):  # trimesh.Trimesh or alike
        return np.asarray(obj.vertices), np.asarray(obj.faces)
    v, f = obj
    try:
        return np.asarray(v, dtype=np.float64), np.asarray(f)
    except (TypeError, ValueError) as exc:
        raise MeshInputError(f"{name}: vertices are not numeric ({exc}); pass a (V, 3) float array") from exc


def validate_arrays(vertices: np.ndarray, faces: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Check shapes, finiteness and index range; return (V,3) float64 and (F,3) int64 C-contiguous arrays."""
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshInputError(f"{name}: vertices must have shape (V, 3), got {v.shape}; reshape or transpose them")
    if f.size == 0 or v.size == 0:
        raise MeshInputError(
            f"{name}: empty mesh ({v.shape[0]} vertices, {f.reshape(-1, 3).shape[0] if f.size else 0} faces); "
            "a metric needs a triangle surface: check the file or the export that produced it"
        )
    if f.ndim != 2 or f.shape[1] != 3:
        raise MeshInputError(
            f"{name}: faces must have shape (F, 3) (triangles), got {f.shape}; triangulate the mesh first"
        )
    try:
        check_counts(v.shape[0], f.shape[0])
    except FileDefect as exc:
        raise MeshInputError(f"{name}: {exc}; {exc.fix}") from None
    if not np.issubdtype(f.dtype, np.integer):
        if np.issubdtype(f.dtype, np.floating) and np.all(np.isfinite(f)) and np.all(f == np.round(f)):
            f = f.astype(np.int64)
        else:
            raise MeshInputError(f"{name}: faces must be integer vertex indices, got dtype {f.dtype}")
    v = np.ascontiguousarray(v, dtype=np.float64)
    f = np.ascontiguousarray(f, dtype=np.int64)
    if not np.isfinite(v).all():
        bad = ~np.isfinite(v).all(axis=1)
        first = int(np.flatnonzero(bad)[0])
        raise MeshInputError(
            f"{name}: {int(bad.sum())} vertices have NaN or infinite coordinates (first: vertex {first} = "
            f"{v[first].tolist()}); remove or repair those vertices before evaluating"
        )
    lo, hi = int(f.min()), int(f.max())
    if lo < 0 or hi >= v.shape[0]:
        which = lo if lo < 0 else hi
        raise MeshInputError(
            f"{name}: faces reference vertex index {which} but only indices 0..{v.shape[0] - 1} exist "
            f"({v.shape[0]} vertices); faces must be 0-based indices into the vertex array"
        )
    return v, f


# --------------------------------------------------------------------------- pymeshlab


def _cone_dets(vertices: np.ndarray, faces: np.ndarray, apex: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per face: det(a, b, d) and |a|, |b|, |d|, a.b, b.d, d.a for corners a, b, d relative to apex.

    vertices (V, 3), faces (F, 3), apex (3,). Written per component: np.cross/einsum are slow
    for the few hundred faces of a typical part. Returns seven (F,) float64 arrays.
    """
    vt = vertices.T - apex[:, None]  # (3, V)
    (ax, ay, az), (bx, by, bz), (dx, dy, dz) = (vt[:, faces[:, i]] for i in range(3))
    det = ax * (by * dz - bz * dy) + ay * (bz * dx - bx * dz) + az * (bx * dy - by * dx)
    la = np.sqrt(ax * ax + ay * ay + az * az)
    lb = np.sqrt(bx * bx + by * by + bz * bz)
    ld = np.sqrt(dx * dx + dy * dy + dz * dz)
    return det, la, lb, ld, ax * bx + ay * by + az * bz, bx * dx + by * dy + bz * dz, dx * ax + dy * ay + dz * az


def star_shaped(vertices: np.ndarray, faces: np.ndarray, dets: tuple[np.ndarray, ...] | None = None) -> bool:
    """True when a closed 2-manifold mesh is provably free of self-intersections (cheap certificate).

    vertices (V, 3), faces (F, 3) of a mesh with no boundary or non-manifold element; dets:
    :func:`_cone_dets` at the vertex centroid, if already computed. The certificate: orientation
    is consistent (every directed edge once, with its reverse), every face is seen with the same
    strictly positive orientation from the vertex centroid c, and the faces' solid angles at c
    add up to 4 pi. Then the central projection from c maps the surface onto the sphere as a
    degree-1 (branched) covering, i.e. one-to-one: every ray from c meets the surface once, so no
    two faces can cross. False means "not proven", not "intersecting".
    """
    n = vertices.shape[0]
    e0, e1 = faces.ravel(), faces[:, [1, 2, 0]].ravel()
    fwd, rev = np.sort(e0 * n + e1), np.sort(e1 * n + e0)
    if (fwd[1:] == fwd[:-1]).any() or not np.array_equal(fwd, rev):
        return False
    det, la, lb, ld, ab, bd, da = dets if dets is not None else _cone_dets(vertices, faces, vertices.mean(axis=0))
    if det.sum() < 0:
        det = -det
    if not (det > 1e-9 * la * lb * ld).all():
        return False
    total = 2 * np.arctan2(det, la * lb * ld + ab * ld + bd * la + da * lb).sum() / (4 * np.pi)
    return bool(abs(total - 1) < 1e-6)


def _clean_current(ms: pymeshlab.MeshSet, name: str, check_self_intersections: bool | str, open_mesh: str,
                   open_mesh_option: str = "open_mesh") -> Mesh:
    """Clean ms.current_mesh() in place and return it as a Mesh with its report. open_mesh_option: the name of the
    option that set ``open_mesh``, which the messages name (see :func:`load_parts`)."""
    m = ms.current_mesh()
    nv0, nf0 = m.vertex_number(), m.face_number()
    box0 = m.bounding_box()  # before cleaning, for the message about a degenerate mesh
    size0, point0 = box0.diagonal(), box0.min().tolist()
    ms.meshing_remove_duplicate_vertices()
    nv1 = ms.current_mesh().vertex_number()
    ms.meshing_remove_duplicate_faces()
    nf1 = ms.current_mesh().face_number()
    ms.meshing_remove_null_faces()
    nf2 = ms.current_mesh().face_number()
    ms.meshing_remove_unreferenced_vertices()
    nv2 = ms.current_mesh().vertex_number()
    if nf2 == 0 or nv2 == 0:
        if nv0 and size0 == 0:
            raise MeshInputError(
                f"{name}: degenerate mesh: all {nv0} vertices are the same point {point0}, so it has no "
                "size, area or volume (no metric and no normalisation is defined); check the file or the export "
                "that produced it"
            )
        raise MeshInputError(
            f"{name}: empty mesh after cleaning ({nf0} faces before, all of them zero-area or duplicated); "
            "a metric needs a triangle surface with area: check the file or the export that produced it"
        )
    topo = ms.get_topological_measures()
    holes_closed = 0
    if topo["boundary_edges"] and open_mesh == "close":
        if topo["non_two_manifold_edges"]:
            raise MeshInputError(
                f"{name}: {open_mesh_option}='close' cannot close holes of a non-manifold mesh "
                f"({topo['non_two_manifold_edges']} non-manifold edges); repair it, or use {open_mesh_option}='warn'"
            )
        nf_before = ms.current_mesh().face_number()
        ms.meshing_close_holes(maxholesize=max(3, int(topo["boundary_edges"]) + 1), selfintersection=False)
        holes_closed = ms.current_mesh().face_number() - nf_before
        topo = ms.get_topological_measures()
    mesh = ms.current_mesh()
    v = np.ascontiguousarray(mesh.vertex_matrix(), dtype=np.float64)
    f = np.ascontiguousarray(mesh.face_matrix(), dtype=np.int64)
    dets = _cone_dets(v, f, v.mean(axis=0))
    volume = float(dets[0].sum() / 6.0)  # cones from the vertex centroid: the enclosed volume if closed
    report = MeshReport(
        name=name,
        vertices=int(v.shape[0]),
        faces=int(f.shape[0]),
        removed_duplicate_vertices=nv0 - nv1,
        removed_duplicate_faces=nf0 - nf1,
        removed_null_faces=nf1 - nf2,
        removed_unreferenced_vertices=nv1 - nv2,
        boundary_edges=int(topo["boundary_edges"]),
        non_manifold_edges=int(topo["non_two_manifold_edges"]),
        non_manifold_vertices=int(topo["non_two_manifold_vertices"]),
        holes_closed=holes_closed,
        volume=volume,
    )
    report = _test_self_intersections(v, f, report, check_self_intersections, dets=dets, ms=ms)
    _refuse_open(name, report, open_mesh, open_mesh_option)
    return Mesh(v, f, name, report)


def _test_self_intersections(v: np.ndarray, f: np.ndarray, report: MeshReport, check: bool | str, *,
                             dets: tuple[np.ndarray, ...] | None = None,
                             ms: pymeshlab.MeshSet | None = None) -> MeshReport:
    """``report`` (of the cleaned mesh v (V, 3), f (F, 3)) with the self-intersection test ``check`` asks for: the
    one test of a mesh cleaned here (:func:`_clean_current`) and of a :class:`Mesh` taken as it is
    (:func:`_tested_as_asked`). True: the :func:`star_shaped` certificate when the report says the mesh is closed
    and 2-manifold, else pymeshlab's test; ``"pymeshlab"``: pymeshlab's test; False: ``report`` unchanged.
    dets: :func:`_cone_dets` at the vertex centroid, if already computed; ms: a MeshSet whose current mesh is
    (v, f), if there is one (else one is made)."""
    if not check:
        return report
    closed = not (report.boundary_edges or report.non_manifold_edges or report.non_manifold_vertices)
    if check is True and closed and star_shaped(v, f, dets):
        return replace(report, self_intersecting_faces=0, self_intersection_check="star-shaped certificate")
    if ms is None:
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f.astype(np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    n_self = int(ms.current_mesh().selected_face_number())
    return replace(report, self_intersecting_faces=n_self, self_intersection_check="pymeshlab")


def _refuse_open(name: str, report: MeshReport, open_mesh: str, open_mesh_option: str) -> None:
    """Raise :class:`OpenMeshError` for the mesh ``name`` when ``open_mesh`` is ``"error"`` and its ``report`` says it
    is not watertight: the one message for a mesh cleaned here and for a :class:`Mesh` taken as it is
    (:func:`_taken_as_is`). open_mesh_option: the name of the option that set ``open_mesh``, which it names."""
    if open_mesh == "error" and not report.watertight:
        raise OpenMeshError(
            f"{name}: mesh is not watertight ({', '.join(report.problems())}) and {open_mesh_option}='error'; "
            f"repair the mesh, or use {open_mesh_option}='warn' (evaluate as is) or 'close' (fill holes)",
            report,
        )


def _read_with_pymeshlab(ms: pymeshlab.MeshSet, path: Path) -> None:
    """``ms.load_new_mesh(path)`` without side effects on the process.

    pymeshlab changes the working directory to the file's folder while it reads (for
    textures and materials) and leaves it there when the read fails, which broke every
    later relative path of a batch. The path is made absolute first and the working
    directory is always restored.
    """
    cwd = os.getcwd()
    try:
        ms.load_new_mesh(str(path.absolute()))
    finally:
        if os.getcwd() != cwd:
            os.chdir(cwd)


def not_a_file(path: Path) -> str | None:
    """Why ``path`` is not a mesh file to read (``"does not exist"``, ``"is a directory"``, ``"is a symlink loop"``,
    ``"is not a regular file (a FIFO, device or socket)"``), or ``None`` for a regular file."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return "is a broken symlink" if path.is_symlink() else "does not exist"
    except OSError as exc:
        return "is a symlink loop" if exc.errno == errno.ELOOP else f"cannot be read ({exc.strerror})"
    if stat.S_ISDIR(mode):
        return "is a directory"
    return None if stat.S_ISREG(mode) else "is not a regular file (a FIFO, device or socket)"


def _load_file(path: Path, name: str, check_self_intersections: bool | str, open_mesh: str,
               open_mesh_option: str = "open_mesh") -> list[Mesh]:
    if what := not_a_file(path):
        raise MeshInputError(f"{name}: mesh file '{path}' {what}; pass the path of a mesh file")
    if path.stat().st_size == 0:
        raise MeshInputError(f"{name}: mesh file '{path}' is empty (0 bytes); check the export that produced it")
    try:
        scan_mesh_file(path)
    except FileDefect as exc:
        raise MeshInputError(f"{name}: {exc}; {exc.fix}") from None
    except OSError as exc:
        raise MeshInputError(f"{name}: cannot read mesh file '{path}' ({exc.strerror}); check its permissions") from exc
    ms = pymeshlab.MeshSet()
    try:
        _read_with_pymeshlab(ms, path)
    except pymeshlab.PyMeshLabException as exc:
        detail = " ".join(str(exc).split())
        raise MeshInputError(
            f"{name}: cannot read mesh file '{path}' ({detail}); check that it is a valid mesh in a format "
            "pymeshlab reads (OBJ, PLY, STL, OFF, GLB/GLTF, ...)"
        ) from exc
    ids = [i for i in range(ms.mesh_number()) if ms.mesh_id_exists(i)] if ms.mesh_number() > 1 else [None]
    meshes = []
    for k, mid in enumerate(ids):
        if mid is not None:
            ms.set_current_mesh(mid)
        label = name if len(ids) == 1 else f"{name} layer {k}"
        m = ms.current_mesh()
        if m.face_number() == 0:
            hint = (
                "; if the file lists vertices, their coordinates may be NaN or non-finite (pymeshlab drops those)"
                if m.vertex_number() == 0
                else ""
            )
            raise MeshInputError(
                f"{label}: empty mesh in '{path}' ({m.vertex_number()} vertices, 0 faces){hint}; "
                "a metric needs a triangle surface (point clouds are not supported)"
            )
        validate_arrays(m.vertex_matrix(), m.face_matrix(), label)  # NaN/inf coordinates in the file
        meshes.append(_clean_current(ms, label, check_self_intersections, open_mesh, open_mesh_option))
    return meshes


def _load_arrays(v: np.ndarray, f: np.ndarray, name: str, check_self_intersections: bool | str, open_mesh: str,
                 open_mesh_option: str = "open_mesh") -> Mesh:
    v, f = validate_arrays(v, f, name)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f.astype(np.int32)))
    return _clean_current(ms, name, check_self_intersections, open_mesh, open_mesh_option)


def _labels(items: Sequence[Any], name: str) -> list[str]:
    """How messages name each of ``items`` (:func:`_split_parts`) of an input called ``name``: the role, its index
    among several parts (``gt[2]``), and a file's path as given (``gt ('scans/a.obj')``; a file of several meshes
    adds `` layer k`` when it is read)."""
    out = []
    for i, item in enumerate(items):
        label = name if len(items) == 1 else f"{name}[{i}]"
        out.append(f"{label} ('{item}')" if isinstance(item, (str, os.PathLike)) else label)
    return out


def _taken_as_is(item: Any, open_mesh: str) -> bool:
    """Whether :func:`load_parts` takes ``item`` as it is: a :class:`Mesh` already validated and cleaned (one with a
    report), unless its holes are to be closed. Its report still answers to ``open_mesh="error"``: an open one is
    refused (:func:`_refuse_open`) as the same mesh read from a file or arrays would be; and to the self-intersection
    test asked for (:func:`_tested_as_asked`)."""
    return isinstance(item, Mesh) and item.report is not None and open_mesh != "close"


def _tested_as_asked(mesh: Mesh, check: bool | str) -> Mesh:
    """A :class:`Mesh` taken as it is (:func:`_taken_as_is`), tested for self-intersections as ``check`` asks.

    Its report's ``self_intersection_check`` says which test answered it. It answers True when any test ran
    (``"star-shaped certificate"`` or ``"pymeshlab"``), ``"pymeshlab"`` only when pymeshlab's ran, and False always
    (a known count is kept). Then ``mesh`` itself is returned (no second test); otherwise that test alone runs on
    it (:func:`_test_self_intersections`, as in a fresh load) and a copy of ``mesh`` is returned, same arrays and
    name, whose report has the new count and test and keeps what the first cleaning removed. So its warnings are
    those of a fresh load, and a cached grid of it (keyed by ``check``) holds them."""
    how = mesh.report.self_intersection_check
    if not check or how == "pymeshlab" or (check is True and how != "skipped"):
        return mesh
    return replace(mesh, report=_test_self_intersections(mesh.vertices, mesh.faces, mesh.report, check))


def mesh_labels(source: Any, name: str = "mesh", open_mesh: str = "warn") -> tuple[str, ...]:
    """How :func:`load_parts` (under ``open_mesh``) names the parts of ``source`` in its messages, without reading
    them (:func:`_labels`; a :class:`Mesh` it takes as it is keeps its own name): so that a cached grid's warnings can
    be told apart from those another input of the same content would raise."""
    items = _split_parts(source)
    labels = _labels(items, name)
    return tuple(item.name if _taken_as_is(item, open_mesh) else label for item, label in zip(items, labels, strict=True))


def load_parts(
    source: Any,
    name: str = "mesh",
    *,
    check_self_intersections: bool | str = True,
    open_mesh: str = "warn",
    open_mesh_option: str = "open_mesh",
) -> list[Mesh]:
    """Load, validate and clean a mesh or a list of part meshes.

    source: file path, ``trimesh.Trimesh``/``Scene``, ``(vertices (V,3), faces (F,3))`` pair,
    :class:`Mesh`, or a list/tuple of those (a multi-part shape). A file holding several
    meshes (e.g. a GLB scene) yields one part per mesh.
    name: how errors and warnings name this input (e.g. ``"pred"``, ``"gt"``); each part is named by it, its index
    among several parts and its file's path (``gt[1] ('scans/a.obj')``; a file of several meshes adds
    `` layer k``).
    open_mesh: ``"warn"`` keep holes (default), ``"close"`` close them with pymeshlab,
    ``"error"`` raise :class:`OpenMeshError` for a non-watertight mesh.
    open_mesh_option: the name of the option that set ``open_mesh``, which the messages name (``"open_mesh"``;
    ``"gt_open_mesh"`` for a ground truth under its own policy, see :func:`~cerberus_metrics.api.prediction_grids`).
    check_self_intersections: True counts self-intersecting faces with pymeshlab unless the
    :func:`star_shaped` certificate already proves there are none; ``"pymeshlab"`` always runs
    pymeshlab's test; False skips the check. A :class:`Mesh` cleaned before (one with a report) is taken as it is
    unless ``open_mesh="close"``; if its report did not run the test asked for, that test alone runs on it
    (:func:`_tested_as_asked`).
    Returns a non-empty list of cleaned :class:`Mesh` (units unchanged).
    """
    if open_mesh not in OPEN_MESH_POLICIES:
        raise MeshInputError(f"{open_mesh_option} must be one of {OPEN_MESH_POLICIES}, got {open_mesh!r}")
    items = _split_parts(source)
    if not items:
        raise MeshInputError(f"{name}: empty list of parts; pass at least one mesh")
    out: list[Mesh] = []
    for item, label in zip(items, _labels(items, name), strict=True):
        if isinstance(item, (str, os.PathLike)):
            out.extend(_load_file(Path(item), label, check_self_intersections, open_mesh, open_mesh_option))
        elif _taken_as_is(item, open_mesh):  # already validated and cleaned, perhaps without the test or under "warn"
            item = _tested_as_asked(item, check_self_intersections)
            _refuse_open(item.name, item.report, open_mesh, open_mesh_option)
            out.append(item)
        else:
            v, f = _arrays_of(item, label)
            out.append(_load_arrays(v, f, label, check_self_intersections, open_mesh, open_mesh_option))
    return out


def load_mesh(source: Any, name: str = "mesh", **kwargs: Any) -> Mesh:
    """Like :func:`load_parts`, but merge all parts into one :class:`Mesh` (faces re-indexed)."""
    parts = load_parts(source, name, **kwargs)
    if len(parts) == 1:
        return parts[0]
    return merge_parts(parts, name)


def merge_parts(parts: Sequence[Mesh], name: str) -> Mesh:
    """Concatenate parts into one Mesh (no vertex welding; report omitted)."""
    offsets = np.cumsum([0] + [p.vertices.shape[0] for p in parts[:-1]])
    v = np.concatenate([p.vertices for p in parts])
    f = np.concatenate([p.faces + o for p, o in zip(parts, offsets, strict=True)])
    return Mesh(v, f, name, None)


_FILE_DIGESTS: dict[tuple[str, int, int], bytes] = {}


def _file_digest(p: Path) -> bytes:
    """SHA-256 of a file's bytes, memoised on (path, size, mtime) so a batch hashes each GT once."""
    st = p.stat()
    key = (str(p.resolve()), st.st_size, st.st_mtime_ns)
    digest = _FILE_DIGESTS.get(key)
    if digest is None:
        h = hashlib.sha256()
        with open(p, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
        digest = h.digest()
        if len(_FILE_DIGESTS) > 4096:
            _FILE_DIGESTS.clear()
        _FILE_DIGESTS[key] = digest
    return digest


def content_digest(source: Any) -> str:
    """SHA-256 hex digest of a mesh input's content (file bytes, or vertex and face arrays).

    Two inputs with the same digest give the same voxels; used as the key of the grid cache.
    Files are hashed by their bytes, so a cache hit skips reading and cleaning the mesh.
    """
    h = hashlib.sha256()
    for item in _split_parts(source):
        if isinstance(item, (str, os.PathLike)):
            p = Path(item)
            if what := not_a_file(p):
                raise MeshInputError(f"mesh file '{p}' {what}; pass the path of a mesh file")
            h.update(b"file" + p.suffix.lower().encode())
            h.update(_file_digest(p))
        else:
            v, f = _arrays_of(item, "mesh")
            h.update(b"arrays")
            h.update(np.ascontiguousarray(v, dtype=np.float64).tobytes())
            h.update(np.ascontiguousarray(f, dtype=np.int64).tobytes())
        h.update(b"|")
    return h.hexdigest()


def iter_mesh_files(folder: Path) -> Iterable[Path]:
    """Mesh files directly inside ``folder`` (by suffix), sorted by name."""
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in MESH_SUFFIXES)
