"""Bring your own meshes: a folder of posed meshes becomes a body source.

Layout (any format trimesh reads: .obj .ply .stl .off .glb .gltf)::

    DIR/part_names.txt             optional, one part name per line (index = label)
    DIR/<subject>/<pose>.<ext>     one posed mesh per file; poses sort naturally by file name
    DIR/<subject>/<pose>.parts.npy optional (V,) integer part label per vertex of that pose
    DIR/<subject>/parts.npy        optional (V,) labels shared by all poses of the subject
    DIR/<subject>/canonical.<ext>  optional canonical pose (flagged in test splits: Hard Human test);
                                   ``canonical=POSE`` names another pose file stem instead

Every mesh is first turned so that its ``up_axis`` (``+y``, the toolkit's world convention, or
``-y``, ``+z``, ``-z``, ``+x``, ``-x``) becomes +Y, by a proper rotation (no mirroring: faces keep
their orientation), in float64. Every subject is then normalised with
:func:`~cerberus_core.bodies.body.normalise_subject` (one scale per subject, each pose centred on its
bounding box), still in float64, and only the result is cast to float32: meshes in any unit (metres,
millimetres, 1e6 or 1e-6 of them) give the same bodies. Meshes are read with ``process=False`` so
vertex order, hence sidecar labels, is kept.

The poses of one subject must share a unit: a pose in millimetres among poses in metres is refused
(:class:`~cerberus_core.errors.DatasetError` naming the file, the factor and the fix), not rescaled.
One scale per subject is the normalisation's point: a subject's poses keep their true sizes relative
to each other (a crouch is smaller than a stand, and the Hard Human test poses one pose's shapes into
another), so normalising each pose by its own size would distort them, and guessing a per-pose unit
factor could silently rescale a different body filed under the same subject. Kept as is, the odd
pose would set the subject's scale and shrink the others to a few pixels (views that render empty).
A pose's size is measured by the square root of its surface area, which articulation hardly changes;
a pose more than :data:`UNIT_MISMATCH_FACTOR` times larger or smaller than the median of the
subject's other poses is refused. Subjects are split by name: ``test_subjects``
explicitly, or the last ``round(test_fraction * n)`` subjects in sorted order (at least one when
there are two or more); ``test_fraction=1`` makes every subject a test subject (a test-only dataset,
to evaluate a trained model on your meshes). Someone with SMPL or SMAL meshes reproduces the
paper's setting this way (presets ``pairs`` for the Human protocol, ``grid`` for the Animal protocol).

Every file is opened and checked when the source is built, so an unreadable, empty or degenerate
mesh (no triangles, all vertices at one point, every triangle of zero area) or a bad label file is
reported (by name) before anything is written. :meth:`FolderSource.up_axis_warning` says when the
meshes' extents suggest another up axis (``cerberus data generate`` prints it).
"""
from __future__ import annotations

import hashlib
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from cerberus_core.bodies.body import (
    FILL,
    BodySource,
    PosedBody,
    Subject,
    flagged,
    no_subjects_hint,
    normalise_subject,
)
from cerberus_core.errors import ConfigError, DatasetError
from cerberus_core.fields import Checked, Range
from cerberus_core.plumbing.names import printable
from cerberus_core.plumbing.outputs import resolved

MESH_EXTENSIONS = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
CANONICAL_STEM = "canonical"
"""The file stem of a subject's canonical pose unless ``canonical=`` names another."""

UNIT_MISMATCH_FACTOR = 1.5
"""Largest ratio of one pose's size (the square root of its surface area) to the median of its
subject's other poses before the folder source refuses the subject as mixing units. Posing changes a
body's area by a few per cent; unit mix-ups are factors of 2.54 (inch, centimetre), 10, 25.4, 100,
1000 or more."""

_UNIT_FACTORS = ((2.54, "inches among centimetres"), (10.0, "millimetres among centimetres"),
                 (25.4, "inches among millimetres"), (39.37, "inches among metres"),
                 (100.0, "centimetres among metres"), (1000.0, "millimetres among metres"))

DEFAULT_UP_AXIS = "+y"
"""The toolkit's world convention (:mod:`cerberus_core.bodies.body`): +Y up."""

_UP_ROTATIONS: dict[str, tuple[tuple[int, int, int], ...]] = {
    "+y": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "-y": ((1, 0, 0), (0, -1, 0), (0, 0, -1)),  # half a turn about x
    "+z": ((1, 0, 0), (0, 0, 1), (0, -1, 0)),  # a quarter turn about x: Blender's -Y (front) becomes +Z
    "-z": ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
    "+x": ((0, -1, 0), (1, 0, 0), (0, 0, 1)),  # a quarter turn about z
    "-x": ((0, 1, 0), (-1, 0, 0), (0, 0, 1)),
}
UP_AXES: tuple[str, ...] = tuple(_UP_ROTATIONS)
"""The accepted ``up_axis`` values (``cerberus data generate --up-axis``)."""


def up_axis_rotation(up_axis: str) -> np.ndarray:
    """The ``(3, 3)`` float64 rotation (determinant +1) that turns ``up_axis`` into +Y: a mesh's
    vertices become ``vertices @ R.T``.

    Raises:
        ConfigError: an unknown axis (the message lists :data:`UP_AXES`).
    """
    if up_axis not in _UP_ROTATIONS:
        raise ConfigError.about("up_axis", up_axis, f"must be one of {', '.join(UP_AXES)}")
    return np.asarray(_UP_ROTATIONS[up_axis], dtype=np.float64)


@dataclass(frozen=True)
class FolderOptions(Checked):
    """The options of the folder source (stored in the manifest, :meth:`FolderSource.stored_options`).

    Attributes:
        root: the folder of meshes (made absolute).
        test_subjects: names of the test subjects (``None``: the last ``test_fraction`` of them).
        test_fraction: fraction of subjects (last in sorted order) held out for testing
            (:func:`test_subject_count`); ``1``: every subject (a test-only dataset).
        up_axis: the meshes' up axis (:data:`UP_AXES`), turned into +Y before normalisation; ``None``:
            ``+y``, with a warning when the meshes look otherwise (:meth:`FolderSource.up_axis_warning`).
        canonical: file stem of each subject's canonical pose; every test subject must have it.
            Default: the stem ``canonical``, where a subject has one.
    """

    root: str | None = flagged(None, "source", "folder source: the folder of meshes, "
                               "SOURCE/<subject>/<pose>.<obj|ply|glb|off|stl>")
    test_subjects: list[str] | None = flagged(None, "test_subjects", "folder source: comma-separated test subject "
                                              "names (default: `test_fraction` decides)")
    test_fraction: float = flagged(0.3, "test_fraction", "folder source: fraction of subjects (last in sorted order) "
                                   "held out for testing (default 0.3; 1: a test-only dataset, to evaluate a trained "
                                   "model on your meshes)", allowed=Range(ge=0, le=1))
    up_axis: Literal["+y", "-y", "+z", "-z", "+x", "-x"] | None = flagged(
        None, "up_axis", "folder source: the meshes' up axis, +y -y +z -z +x -x, turned into +Y (default +y, the "
        "toolkit's world; Blender, anny and many scans are +z); recorded in the manifest")
    canonical: str | None = flagged(None, "canonical", "folder source: the pose file stem that is each subject's "
                                    "canonical pose, rendered and flagged in the test split for the Hard Human test of "
                                    "cerberus eval (default: a pose named 'canonical')", metavar="POSE")

    def validate(self) -> None:
        if self.root is None:
            raise ConfigError.about("root", None, "the folder source needs its folder of meshes: `root=DIR`")
        object.__setattr__(self, "root", str(resolved(self.root, "root")))  # a symlink loop: one line
        if self.test_subjects is not None and not self.test_subjects:
            raise ConfigError.about("test_subjects", [], "names no subject; name the test subjects, or leave it out "
                                    "(`test_fraction` decides)")


def test_subject_count(fraction: float, subjects: int) -> int:
    """How many of ``subjects`` subjects ``test_fraction=fraction`` holds out: ``round(fraction * subjects)``,
    at least one when ``fraction > 0`` and there are two or more subjects (the folder source's split rule)."""
    k = int(round(fraction * subjects))
    return max(1, k) if fraction > 0 and subjects >= 2 else k


def _natural_key(text: str) -> list:
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", text)]


def load_mesh(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read one mesh file: ``(vertices (V, 3) float64, faces (F, 3) int64)``, vertex order kept.

    Raises:
        DatasetError: naming the file and the problem, if it cannot be read, holds no triangles, has
            NaN/inf or face indices out of range, or is degenerate (:func:`check_mesh`).
    """
    import trimesh

    try:
        mesh = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many types for bad files
        raise DatasetError(f"{path}: cannot read it as a mesh ({type(exc).__name__}: {exc}); "
                           "fix or remove the file") from exc
    vertices = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=np.float64)
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64)
    if len(faces) == 0 or len(vertices) == 0 or faces.ndim != 2 or faces.shape[1] != 3:
        raise DatasetError(f"{path}: no triangles found; a pose file must hold one triangle mesh")
    if not np.isfinite(vertices).all():
        raise DatasetError(f"{path}: vertices contain NaN or inf")
    check_mesh(vertices, faces, path)
    return vertices, faces


def check_mesh(vertices: np.ndarray, faces: np.ndarray, path: Path | str) -> None:
    """Refuse a mesh that would render blank, naming the file and the problem.

    Args:
        vertices: ``(V, 3)`` float64, finite, any unit.
        faces: ``(F, 3)`` int64, ``F >= 1``.

    Raises:
        DatasetError: face indices outside ``0..V-1``; all vertices the faces use at one point (zero
            extent); or every triangle of zero area (collinear vertices: a line, or a file whose
            coordinates were written with too few digits for their unit).
    """
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise DatasetError(f"{path}: faces index vertices outside 0..{len(vertices) - 1}; fix the file")
    used = vertices[np.unique(faces)]
    lo, hi = used.min(0), used.max(0)
    extent = float((hi - lo).max())
    if not np.isfinite(extent):
        raise DatasetError(f"{path}: coordinates too large for float64 arithmetic; rescale the mesh")
    if extent == 0.0:
        raise DatasetError(f"{path}: degenerate mesh: all {len(used)} vertices of its {len(faces)} triangles are at "
                           "one point (zero extent); fix or remove the file")
    v = (vertices - lo) / extent  # unit-free: the test below does not depend on the mesh's unit
    tri = v[faces]
    doubled = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not (doubled > 1e-12).any():
        raise DatasetError(f"{path}: degenerate mesh: all {len(faces)} triangles have zero area (its vertices lie on "
                           "a line, or were written with too few digits for their unit); fix or remove the file")


def surface_size(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The square root of a mesh's surface area, in the mesh's length unit: a size that posing
    hardly changes. ``vertices`` ``(V, 3)`` float64 (any unit, finite), ``faces`` ``(F, 3)`` int64.
    Computed on the mesh scaled to a unit extent first, so huge or tiny units cannot overflow."""
    used = vertices[np.unique(faces)]
    lo = used.min(0)
    extent = float((used.max(0) - lo).max())
    tri = ((vertices - lo) / extent)[faces]
    area = 0.5 * float(np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum())
    return extent * float(np.sqrt(area))


def check_units(subject_dir: Path, files: Sequence[Path], sizes: Sequence[float]) -> None:
    """Refuse a subject whose poses come in different units (module docstring).

    Args:
        subject_dir: the subject's folder (for the message).
        files: its pose files; sizes: their :func:`surface_size` values (file units), one per file.
    Raises:
        DatasetError: naming the pose that differs most from the median of the others, the factor,
            a likely unit pair, and the fix.
    """
    if len(sizes) < 2:
        return
    logs = np.log(np.asarray(sizes, dtype=np.float64))
    k = int(np.argmax(np.abs(logs - np.median(logs))))
    factor = float(np.exp(logs[k] - np.median(np.delete(logs, k))))
    big = max(factor, 1.0 / factor)
    if big <= UNIT_MISMATCH_FACTOR:
        return
    guess = next((f", {name}?" for f, name in _UNIT_FACTORS if abs(big / f - 1.0) < 0.1), "")
    others = [f.name for i, f in enumerate(files) if i != k]
    shown = ", ".join(others[:3]) + (f" and {len(others) - 3} more" if len(others) > 3 else "")
    raise DatasetError(
        f"{files[k]}: this pose is {big:.3g}x {'larger' if factor > 1 else 'smaller'} than the other poses of "
        f"subject {subject_dir.name!r} ({shown}) by surface area, so it is in another unit{guess}; a subject's "
        "poses share one scale, so re-export it in the others' unit (or move it to a subject folder of its own)")


def _load_labels(path: Path, n_vertices: int, mesh: Path) -> np.ndarray:
    try:
        labels = np.load(path, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001
        raise DatasetError(f"{path}: cannot read the part labels ({exc}); it must be a (V,) integer .npy") from exc
    labels = np.asarray(labels)
    if labels.shape != (n_vertices,) or not np.issubdtype(labels.dtype, np.integer):
        raise DatasetError(f"{path}: part labels must be ({n_vertices},) integers to match {mesh.name}, "
                           f"got {labels.dtype} {labels.shape}")
    if labels.size and (labels.min() < 0 or labels.max() > np.iinfo(np.int16).max):
        raise DatasetError(f"{path}: part labels must lie in 0..32767")
    return labels.astype(np.int16)


class FolderSource(BodySource):
    """Posed meshes from a folder (module docstring).

    Args:
        root: the folder.
        options: the other fields of :class:`FolderOptions` (``test_subjects``, ``test_fraction``,
            ``up_axis``, ``canonical``).
    """

    name = "folder"
    Options = FolderOptions
    default_size = "pairs"
    canonical_hint = ("generate the dataset with each subject's canonical pose named: the folder source's "
                      "`canonical` option")

    @classmethod
    def body_kind(cls) -> str | None:
        return None  # your meshes: any kind of body

    def __init__(self, root: str | Path, **options: Any) -> None:
        self.options = opts = FolderOptions(root=str(root), **options)
        self.root = Path(root)
        if not self.root.is_dir():
            what = "is a file, not a folder" if self.root.exists() else "does not exist"
            raise DatasetError(f"mesh folder {printable(self.root)} {what}; pass the folder that holds "
                               "<subject>/<pose> mesh files")
        self.up_axis = opts.up_axis or DEFAULT_UP_AXIS
        self._rotation = up_axis_rotation(self.up_axis)
        canonical = self.canonical = opts.canonical
        self._canonical_stem = CANONICAL_STEM if canonical is None else canonical
        self._files: dict[str, list[Path]] = {}
        for sub in sorted((p for p in self.root.iterdir() if p.is_dir() and not p.name.startswith(".")),
                          key=lambda p: _natural_key(p.name)):
            meshes = sorted((f for f in sub.iterdir() if f.is_file() and f.suffix.lower() in MESH_EXTENSIONS),
                            key=lambda f: _natural_key(f.stem))
            stems = [f.stem for f in meshes]
            dup = sorted({s for s in stems if stems.count(s) > 1})
            if dup:
                raise DatasetError(f"{sub}: pose {dup[0]!r} exists in several formats; keep one file per pose")
            if meshes:
                self._files[sub.name] = meshes
        if not self._files:
            raise DatasetError(f"{self.root}: no subject folders with meshes found; expected "
                               f"{self.root}/<subject>/<pose>{{{','.join(MESH_EXTENSIONS)}}}")
        names = list(self._files)
        if opts.test_subjects is not None:
            unknown = sorted(set(opts.test_subjects) - set(names))
            if unknown:
                raise DatasetError(f"{self.root}: test subject(s) {unknown} not found; subjects are {names}")
            test = [n for n in names if n in set(opts.test_subjects)]
        else:
            k = test_subject_count(opts.test_fraction, len(names))
            test = names[len(names) - k:] if k else []
        self._split = {"train": [n for n in names if n not in test], "test": test}
        if canonical is not None:
            for subject in test:
                stems = [f.stem for f in self._files[subject]]
                if canonical not in stems:
                    raise DatasetError(f"{self.root / subject}: no pose file {canonical!r} (the canonical pose named by "
                                       f"`canonical`); its poses are {stems}; add it or name another pose")
        self.part_names = self._read_part_names()
        self._scan()  # opens every file: errors surface before anything is written


    def reads(self) -> list[Path]:
        """The folder of meshes: a dataset is never written into it."""
        return [Path(self.options.root)]

    def _read_part_names(self) -> list[str]:
        path = self.root / "part_names.txt"
        if path.is_file():
            names = [ln.strip() for ln in path.read_text().splitlines() if ln.strip()]
            if not names:
                raise DatasetError(f"{path}: empty; list one part name per line or remove the file")
            return names
        return []

    def _label_file(self, mesh: Path) -> Path | None:
        own = mesh.with_name(mesh.stem + ".parts.npy")
        if own.is_file():
            return own
        shared = mesh.parent / "parts.npy"
        return shared if shared.is_file() else None

    def _digest_file(self, digest: Any, path: Path) -> None:
        digest.update(path.relative_to(self.root).as_posix().encode() + hashlib.sha256(path.read_bytes()).digest())

    def _load(self, path: Path) -> tuple[np.ndarray, np.ndarray]:
        """A mesh file turned +Y up: ``(vertices (V, 3) float64, faces (F, 3) int64)``."""
        v, faces = load_mesh(path)
        return v @ self._rotation.T, faces

    def _scan(self) -> None:
        """Open every mesh and label file; record bounding boxes, the subject scales, the meshes'
        tallest axes and a fingerprint."""
        digest = hashlib.sha256()
        self._bbox: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
        self._scale: dict[str, float] = {}
        self._tallest: list[int] = []  # per mesh: the file axis (0 x, 1 y, 2 z) of its largest extent
        labelled, unlabelled = [], []
        max_label = -1
        for subject, files in self._files.items():
            boxes, sizes = [], []
            for f in files:
                v, faces = self._load(f)
                boxes.append((v.min(0), v.max(0)))
                sizes.append(surface_size(v, faces))
                self._tallest.append(int(np.argmax(np.abs(self._rotation.T @ (v.max(0) - v.min(0))))))
                lab = self._label_file(f)
                if lab is None:
                    unlabelled.append(f)
                else:
                    labelled.append(f)
                    max_label = max(max_label, int(_load_labels(lab, len(v), f).max(initial=0)))
                    self._digest_file(digest, lab)
                self._digest_file(digest, f)
            self._bbox[subject] = boxes
            check_units(self.root / subject, files, sizes)
            try:
                self._scale[subject], _ = normalise_subject([np.stack(b) for b in boxes], fill=FILL)
            except ValueError as exc:
                raise DatasetError(f"{self.root / subject}: {exc}") from exc
        if labelled and unlabelled:
            raise DatasetError(f"{unlabelled[0]}: no part labels ({unlabelled[0].stem}.parts.npy or parts.npy) while "
                               f"other poses have them (e.g. {labelled[0]}); label every pose or none")
        if (self.root / "part_names.txt").is_file():
            digest.update((self.root / "part_names.txt").read_bytes())
        if not labelled:
            self.part_names = self.part_names or ["body"]
        elif not self.part_names:
            self.part_names = [f"part{i}" for i in range(max_label + 1)]
        elif max_label >= len(self.part_names):
            raise DatasetError(f"{self.root / 'part_names.txt'} names {len(self.part_names)} parts but labels go "
                               f"up to {max_label}")
        self.fingerprint = digest.hexdigest()

    # -- BodySource ----------------------------------------------------------------------------
    def subjects(self, split: str, n: int | None, seed: int) -> list[Subject]:
        if split not in self._split:
            raise ConfigError.about("splits", split, "the folder source has splits train and test only",
                                    "name the splits `train` and `test`")
        names = self._split[split][: n if n is not None else None]
        return [Subject(s, {"poses": [f.stem for f in self._files[s]], "folder": s}) for s in names]

    def _subject_files(self, subject: Subject) -> list[Path]:
        if subject.name not in self._files:
            raise DatasetError(f"{self.root}: no subject folder {subject.name!r}; subjects are {list(self._files)}")
        return self._files[subject.name]

    def pose_pool(self, subject: Subject, split: str, n: int | None) -> list[int]:
        ids = list(range(len(self._subject_files(subject))))
        return ids[: n if n is not None else None]

    def canonical_pose(self, subject: Subject) -> int | None:
        stems = [f.stem for f in self._subject_files(subject)]
        return stems.index(self._canonical_stem) if self._canonical_stem in stems else None

    def bodies(self, subject: Subject, pose_ids: Sequence[int]) -> list[PosedBody]:
        files = self._subject_files(subject)
        scale = self._scale[subject.name]
        out = []
        for pid in pose_ids:
            f = files[pid]
            v, faces = self._load(f)
            lo, hi = self._bbox[subject.name][pid]
            vn = ((v - 0.5 * (lo + hi)) * scale).astype(np.float32)  # float64 until here: any unit works
            lab = self._label_file(f)
            parts = np.zeros(len(v), np.int16) if lab is None else _load_labels(lab, len(v), f)
            out.append(PosedBody(vn, faces, parts, self.part_names, subject.name, int(pid), meta={"file": f.name}))
        return out

    def up_axis_warning(self) -> str | None:
        """A one-line warning when most meshes are tallest along a file axis other than the up axis
        (e.g. z-up meshes read as +Y up would lie on their backs), naming ``up_axis`` and the likely
        value; ``None`` when the extents agree with the up axis. Long bodies (quadrupeds) can be
        longest along a horizontal axis: hence a warning, not an error."""
        up = int(np.argmax(np.abs(self._rotation[1])))  # the file axis that becomes +Y
        counts = np.bincount(self._tallest, minlength=3)
        tallest = int(np.argmax(counts))
        if tallest == up or 2 * counts[tallest] <= len(self._tallest):
            return None
        axis = "xyz"[tallest]
        return (f"{self.root}: {counts[tallest]} of {len(self._tallest)} meshes are tallest along {axis}, not along "
                f"the up axis {self.up_axis}; if they are {axis}-up (Blender, anny and many scans are z-up), pass "
                f"`up_axis=+{axis}` (or -{axis} if they come out upside down); if they are long bodies "
                f"(quadrupeds) already {self.up_axis} up, pass `up_axis={self.up_axis}` to silence this")

    def warnings(self) -> list[str]:
        hint = self.up_axis_warning() if self.options.up_axis is None else None  # a given up axis silences it
        return [hint] if hint else []

    @classmethod
    def stored_options(cls, options: Any) -> dict[str, Any]:
        return {**super().stored_options(options), "up_axis": options.up_axis or DEFAULT_UP_AXIS}

    @classmethod
    def empty_split_hint(cls, options: Mapping[str, Any], subjects: int, split: str, root: str | Path) -> str:
        """The hint with the dataset's own counts, e.g. for a folder of one subject with the default
        ``test_fraction=0.3``: "the dataset has no test subjects: `test_fraction=0.3` of its 1 subject gives
        round(0.3 x 1) = 0 test subjects; ..." (the rule of :func:`test_subject_count`)."""
        n, fraction, named = subjects, options.get("test_fraction"), options.get("test_subjects")
        if split == "train":
            cause = " (its only subject is a test subject" if n == 1 else f" (all {n} subjects are test subjects"
            return no_subjects_hint(split, n, root, cause + (", `test_fraction=1`)" if fraction == 1 else ")"))
        if named:
            cause = f": `test_subjects` named {len(named)} subject(s), none of them in it"
        elif fraction is not None:
            f = float(fraction)
            cause = (f": `test_fraction={f:g}` of its {n} subject{'' if n == 1 else 's'} gives "
                     f"{'0 (a fraction of 0)' if f == 0 else f'round({f:g} x {n}) = {test_subject_count(f, n)}'} "
                     "test subjects")
        else:
            return no_subjects_hint(split, n, root)
        return no_subjects_hint(split, n, root, cause, "regenerate it with `test_fraction=1` (every subject a test "
                                "subject, for evaluation) or `test_subjects=NAME[,NAME]`, or add subjects")

    def describe(self) -> dict[str, Any]:
        return {"fingerprint": self.fingerprint, "test_subjects": list(self._split["test"]),
                "train_subjects": list(self._split["train"]), "up_axis": self.up_axis,
                "canonical": self._canonical_stem}
