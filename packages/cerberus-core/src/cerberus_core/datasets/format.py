"""The on-disk dataset format: shards, checksums, atomic writes (see docs/data_format.md); the
manifest itself is :mod:`cerberus_core.datasets.manifest`.

A dataset is a folder::

    DIR/manifest.json                   format name + version, config, scene, subjects, splits, shards
    DIR/<split>/shard-NNNNN.images.npy  (N, 3, H, W) uint8 rendered images
    DIR/<split>/shard-NNNNN.views.npy   (N,) structured VIEW_DTYPE: subject, pose, view, camera ...
    DIR/<split>/shard-NNNNN.quads.npy   (Q, 4) int32 image indices (a0, a1, b0, b1) within the shard
    DIR/<split>/shard-NNNNN.vertices.npy (sum V, 3) float32 ground-truth vertices   [if meshes stored]
    DIR/<split>/shard-NNNNN.meshes.npz  offsets, topologies (faces, part labels)      [if meshes stored]

Every ``.npy`` opens with ``np.load(mmap_mode="r")``. A shard counts only once the manifest lists
it, with the size and sha256 of each of its files; files are written to a temporary name, fsynced
and renamed (:func:`atomic_write`), and the manifest is rewritten the same way after each shard, so
a killed run never leaves a shard that a reader accepts half-written.
"""
from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import numpy as np

from cerberus_core.datasets.manifest import MANIFEST, FileRecord, Manifest, ShardRecord, canonical_json
from cerberus_core.errors import DatasetError, ShapeError  # DatasetError re-exported: the format's readers raise it
from cerberus_core.plumbing.atomic import atomic_write, is_temporary
from cerberus_core.plumbing.outputs import resolved
from cerberus_core.shapes import check_shapes

VIEW_DTYPE = np.dtype([
    ("subject", "<i4"),     # index into Manifest.subjects
    ("pose", "<i4"),        # pose id, unique within the subject
    ("view", "<i2"),        # view index within the pose (0/1 in a pair, 0..V-1 on a grid)
    ("canonical", "?"),     # the subject's canonical pose (Hard Human test)
    ("mesh", "<i4"),        # index of the ground-truth mesh in the shard, -1 if meshes are not stored
    ("azimuth", "<f4"),     # degrees
    ("elevation", "<f4"),   # degrees
    ("distance", "<f4"),    # normalised units
    ("fov_y", "<f4"),       # degrees
])
"""One record per image (packed, 31 bytes)."""

# ------------------------------------------------------------------------------------ atomic I/O
def atomic_save_npy(path: Path, array: np.ndarray) -> None:
    """``np.save`` atomically (no pickles)."""
    atomic_write(path, lambda fh: np.save(fh, np.ascontiguousarray(array), allow_pickle=False))


def atomic_save_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """``np.savez`` (uncompressed) atomically."""
    atomic_write(path, lambda fh: np.savez(fh, **arrays))


def sha256_file(path: Path, chunk: int = 1 << 22) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def config_hash(config: dict) -> str:
    return hashlib.sha256(canonical_json(config).encode()).hexdigest()


def clean_temporaries(folder: Path) -> int:
    """Remove the temporaries an interrupted run left under ``folder`` (called under the folder's lock):
    only those that carry the atomic writer's marker (:func:`cerberus_core.plumbing.atomic.is_temporary`),
    never a file or folder that merely has such a name. Returns the count."""
    found = [p for pattern in (".*.tmp", ".*.old") for p in Path(folder).rglob(pattern) if is_temporary(p)]
    for tmp in found:
        shutil.rmtree(tmp, ignore_errors=True)
    return len(found)


# ------------------------------------------------------------------------------------ paths
def resolve_inside(root: Path, rel: str) -> Path:
    """The path ``root / rel``, refusing any path that leaves ``root``.

    Raises:
        DatasetError: for absolute paths, ``..`` components or symlinks escaping the folder.
    """
    root = Path(root)
    p = Path(rel)
    if p.is_absolute() or ".." in p.parts or rel.strip() == "":
        raise DatasetError(f"{root / MANIFEST}: file path {rel!r} escapes the dataset folder; a manifest may only "
                           "name files inside its own folder (regenerate the dataset or fix the manifest)")
    full = root / p
    real_root, real = resolved(root, "data"), resolved(full, "data")
    if not real.is_relative_to(real_root):
        raise DatasetError(f"{root / MANIFEST}: file path {rel!r} resolves to {real}, outside the dataset "
                           f"folder {real_root} (a symlink?); copy the file into the dataset folder")
    return full


# ------------------------------------------------------------------------------------ shard records
def file_record(root: Path, path: Path, array_shape: tuple[int, ...] | None, dtype: str | None) -> FileRecord:
    """The record of one written shard file: relative path, bytes, sha256 (and array shape, dtype)."""
    return FileRecord(path.relative_to(root).as_posix(), path.stat().st_size, sha256_file(path),
                      None if array_shape is None else tuple(array_shape), dtype)


# ------------------------------------------------------------------------------------ verification
def check_shard_files(root: Path, shard: ShardRecord, *, checksums: bool) -> list[str]:
    """Problems with one shard's files (empty list if fine): missing, wrong size, wrong checksum,
    array header not matching the manifest, path escaping the folder."""
    problems = []
    for role, rec in shard.files.items():
        try:
            path = resolve_inside(root, rec.path)
        except DatasetError as exc:
            problems.append(str(exc))
            continue
        if not path.is_file():
            what = ("missing" if not path.exists() else "a folder, not a file" if path.is_dir()
                    else "not a regular file (a FIFO, device or socket)")
            problems.append(f"{path}: {what} ({role} of {shard.name}); delete it if it is there and resume the "
                            "generation to rebuild it")
            continue
        size = path.stat().st_size
        if size != rec.bytes:
            problems.append(f"{path}: {size} bytes, the manifest records {rec.bytes} (truncated or replaced); "
                            "delete it and resume the generation")
            continue
        if checksums and sha256_file(path) != rec.sha256:
            problems.append(f"{path}: sha256 mismatch (corrupt); delete it and resume the generation")
            continue
        if rec.shape is not None and path.suffix == ".npy":
            try:
                arr = np.load(path, mmap_mode="r", allow_pickle=False)
            except Exception as exc:  # noqa: BLE001 - any header problem is corruption
                problems.append(f"{path}: unreadable .npy ({exc})")
                continue
            if arr.shape != rec.shape or arr.dtype.str != rec.dtype:
                problems.append(f"{path}: array {arr.dtype.str}{list(arr.shape)} but the manifest records "
                                f"{rec.dtype}{list(rec.shape)}")
    return problems


MESH_ARRAYS = ("subject", "pose", "vertex_offsets", "topology", "face_offsets", "faces", "part_offsets", "vertex_parts")
"""The arrays of a shard's ``meshes.npz`` (:func:`pack_meshes`; ``pose_params`` is optional)."""


def check_shard_arrays(manifest: Manifest, split: str, shard: ShardRecord) -> list[str]:
    """The first problem (a one-line list, or ``[]``) between a shard's record and its arrays, once its files
    are sound (:func:`check_shard_files`): counts, shapes and dtypes against the manifest's numbers, indices
    within their ranges (quadruplets within the shard's images, views' subjects within the manifest's, mesh
    indices within the shard's meshes), and a ``meshes.npz`` of the arrays :func:`pack_meshes` writes, none of
    them an object array."""
    root, files = manifest.root, shard.files
    where = f"{root / MANIFEST}: {split}/{shard.name}"
    needed = ["images", "views", "quads", *(["vertices", "meshes"] if shard.meshes else [])]
    if missing := [r for r in needed if r not in files]:
        return [f"{where} has no {missing[0]} file; the dataset is corrupt — regenerate it"]

    def load(role: str) -> np.ndarray:
        return np.load(resolve_inside(root, files[role].path), mmap_mode="r", allow_pickle=False)

    def bad(what: str) -> list[str]:
        return [f"{where}: {what}; the dataset is corrupt — regenerate it"]

    n, size = shard.images, manifest.image_size
    images, views, quads = load("images"), load("views"), load("quads")
    if images.dtype != np.uint8 or images.shape != (n, 3, size, size):
        return bad(f"images are {images.dtype}{list(images.shape)}, the manifest says uint8[{n}, 3, {size}, {size}]")
    if views.dtype != VIEW_DTYPE or views.shape != (n,):
        return bad(f"views are {views.dtype}[{len(views)}], the manifest says {n} view records")
    if quads.dtype != np.int32 or quads.shape != (shard.quadruplets, 4):
        return bad(f"quadruplets are {quads.dtype}{list(quads.shape)}, the manifest says int32[{shard.quadruplets}, 4]")
    if quads.size and (int(quads.min()) < 0 or int(quads.max()) >= n):
        return bad(f"quadruplets index images {int(quads.min())}..{int(quads.max())}, the shard has {n}")
    if n and (int(views["subject"].min()) < 0 or int(views["subject"].max()) >= len(manifest.subjects)):
        return bad(f"views name subjects {int(views['subject'].min())}..{int(views['subject'].max())}, the manifest "
                   f"has {len(manifest.subjects)}")
    if n and (int(views["mesh"].min()) < -1 or int(views["mesh"].max()) >= shard.meshes):
        return bad(f"views name meshes {int(views['mesh'].min())}..{int(views['mesh'].max())}, the shard has "
                   f"{shard.meshes}")
    return _check_meshes(load, where, shard.meshes, len(manifest.part_names), bad) if shard.meshes else []


def _check_meshes(load, where: str, m: int, parts: int, bad) -> list[str]:  # noqa: ANN001 - check_shard_arrays's helpers
    """:func:`check_shard_arrays` for the ``vertices`` and ``meshes.npz`` of a shard with ``m`` meshes whose part
    labels index the manifest's ``parts`` part names."""
    vertices = load("vertices")
    if vertices.dtype != np.float32 or vertices.ndim != 2 or vertices.shape[1] != 3:
        return bad(f"vertices are {vertices.dtype}{list(vertices.shape)}, not float32[V, 3]")
    try:
        with load("meshes") as z:
            arrays = {k: z[k] for k in z.files}
    except ValueError as exc:  # an object array: loading it would run pickle
        return bad(f"meshes.npz holds an array numpy cannot read without pickle ({exc})")
    if missing := [k for k in MESH_ARRAYS if k not in arrays]:
        return bad(f"meshes.npz lacks the array {missing[0]!r}")
    if odd := [k for k, a in arrays.items() if a.dtype.kind not in "iuf"]:
        return bad(f"meshes.npz array {odd[0]!r} is {arrays[odd[0]].dtype}, not numbers")
    topologies = len(arrays["face_offsets"]) - 1
    checks = [
        (all(len(arrays[k]) == m for k in ("subject", "pose", "topology")), f"subject, pose and topology hold {m} meshes"),
        (len(arrays["vertex_offsets"]) == m + 1 and int(arrays["vertex_offsets"][-1]) == len(vertices)
         and bool((np.diff(arrays["vertex_offsets"]) >= 0).all()), f"vertex_offsets run over the {len(vertices)} vertices"),
        (topologies >= 0 and len(arrays["part_offsets"]) == topologies + 1, "face and part offsets give one topology each"),
        (not m or (int(arrays["topology"].min()) >= 0 and int(arrays["topology"].max()) < topologies),
         f"topology indices are within its {topologies} topologies"),
        (topologies < 0 or int(arrays["face_offsets"][-1]) == len(arrays["faces"]), "face_offsets run over the faces"),
        (topologies < 0 or int(arrays["part_offsets"][-1]) == len(arrays["vertex_parts"]),
         "part_offsets run over the part labels"),
        (arrays["faces"].ndim == 2 and arrays["faces"].shape[1] == 3 and (not arrays["faces"].size
                                                                          or int(arrays["faces"].min()) >= 0),
         "faces are (F, 3) vertex indices"),
        (not arrays["vertex_parts"].size or (int(arrays["vertex_parts"].min()) >= 0
                                             and int(arrays["vertex_parts"].max()) < parts),
         f"part labels index the manifest's {parts} part names"),
    ]
    failed = next((what for ok, what in checks if not ok), None)
    return [] if failed is None else bad(f"meshes.npz does not agree with the manifest (expected: {failed})")


EMPTY_VIEW_FRACTION = 1e-3
"""A view whose foreground (pixels that differ from the scene's background colour) covers less than
this fraction of the image (at least 1 pixel) renders empty: :func:`empty_views` flags it. Bodies fill
most of the frame (:mod:`cerberus_core.datasets.scene`), so a sound view has thousands of times more."""


def empty_views(manifest: Manifest, split: str, shard: ShardRecord, chunk: int = 256) -> list[str]:
    """One problem line for a shard with views that render empty (no body on the background), or none.

    Args:
        manifest: the dataset's manifest (its folder, scene background, subjects); split: the shard's
            split; shard: its record, files already checked.
        chunk: images compared at a time (``(chunk, 3, H, W)`` uint8 in memory).
    Returns:
        ``[]``, or one line naming the images file, how many views are empty, the first few (subject,
        pose, view, foreground pixels) and the likely cause and fix.
    """
    root, files = manifest.root, shard.files
    if "images" not in files or "views" not in files:
        return []
    images = np.load(resolve_inside(root, files["images"].path), mmap_mode="r", allow_pickle=False)
    views = np.load(resolve_inside(root, files["views"].path), mmap_mode="r", allow_pickle=False)
    background = np.asarray(manifest.scene.background, dtype=np.float64)
    bg = np.round(np.clip(background, 0.0, 1.0) * 255).astype(np.int16).reshape(1, 3, 1, 1)
    h, w = images.shape[-2:]
    least = max(1, int(np.ceil(EMPTY_VIEW_FRACTION * h * w)))
    counts = np.concatenate([(np.asarray(images[i:i + chunk], dtype=np.int16) != bg).any(axis=1).sum(axis=(1, 2))
                             for i in range(0, len(images), chunk)]) if len(images) else np.zeros(0, np.int64)
    bad = np.flatnonzero(counts < least)
    if bad.size == 0:
        return []
    subjects = manifest.subjects

    def name(i: int) -> str:
        v = views[i]
        s, pose = int(v["subject"]), int(v["pose"])
        sub = subjects[s] if 0 <= s < len(subjects) else None
        poses = sub.pose_names if sub is not None else None
        pose_name = f" ({poses[pose]})" if poses is not None and 0 <= pose < len(poses) else ""
        return (f"image {i}: subject {sub.name if sub is not None else s} "
                f"pose {pose}{pose_name} view {int(v['view'])}, {int(counts[i])} foreground pixels")

    shown = "; ".join(name(int(i)) for i in bad[:3]) + (f"; and {bad.size - 3} more" if bad.size > 3 else "")
    return [f"{resolve_inside(root, files['images'].path)}: {bad.size} of {len(images)} views of split {split!r} "
            f"render empty (fewer than {least} of {h}x{w} pixels differ from the background): {shown}; the body is "
            "outside the camera or a few pixels small (a pose in another unit than its subject's other poses?): "
            "fix the meshes or the scene and regenerate the dataset"]


# ------------------------------------------------------------------------------------ meshes
def pack_meshes(bodies: list, subject_index: list[int]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Pack ground-truth meshes of one shard; topologies (faces + part labels) are stored once.

    Args:
        bodies: ``M`` :class:`~cerberus_core.bodies.body.PosedBody`.
        subject_index: ``M`` manifest subject indices.

    Returns:
        ``vertices`` ``(sum V, 3)`` float32 and the ``meshes.npz`` arrays: ``subject``, ``pose``
        ``(M,)`` int32; ``vertex_offsets`` ``(M+1,)`` int64; ``topology`` ``(M,)`` int32;
        ``face_offsets`` ``(T+1,)`` int64 into ``faces`` ``(sum F, 3)`` int32; ``part_offsets``
        ``(T+1,)`` int64 into ``vertex_parts`` ``(sum V_t,)`` int16; and, when every body carries
        ``meta["pose_params"]`` of one length, ``pose_params`` ``(M, D)`` float32.
    """
    topo_key: dict[bytes, int] = {}
    faces, parts, topology = [], [], []
    for b in bodies:
        key = hashlib.sha1(b.faces.astype(np.int32).tobytes() + b"|" + b.vertex_parts.tobytes()).digest()
        if key not in topo_key:
            topo_key[key] = len(faces)
            faces.append(b.faces.astype(np.int32))
            parts.append(b.vertex_parts.astype(np.int16))
        topology.append(topo_key[key])
    counts = [len(b.vertices) for b in bodies]
    out = {
        "subject": np.asarray(subject_index, dtype=np.int32),
        "pose": np.asarray([b.pose_id for b in bodies], dtype=np.int32),
        "vertex_offsets": np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        "topology": np.asarray(topology, dtype=np.int32),
        "face_offsets": np.concatenate([[0], np.cumsum([len(f) for f in faces])]).astype(np.int64),
        "faces": np.concatenate(faces) if faces else np.zeros((0, 3), np.int32),
        "part_offsets": np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64),
        "vertex_parts": np.concatenate(parts) if parts else np.zeros((0,), np.int16),
    }
    params = [b.meta.get("pose_params") for b in bodies]
    if bodies and all(p is not None for p in params) and len({np.asarray(p).shape for p in params}) == 1:
        out["pose_params"] = np.stack([np.asarray(p, dtype=np.float32).reshape(-1) for p in params])
    vertices = (np.concatenate([b.vertices for b in bodies]).astype(np.float32) if bodies
                else np.zeros((0, 3), np.float32))
    return vertices, out


def unpack_mesh(vertices: np.ndarray, meshes: dict[str, np.ndarray],
                i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mesh ``i`` of a shard packed by :func:`pack_meshes`: ``(vertices (V,3) float32, faces (F,3)
    int64, vertex_parts (V,) int16)`` (copies, safe to keep after the shard is closed)."""
    v0, v1 = meshes["vertex_offsets"][i], meshes["vertex_offsets"][i + 1]
    t = int(meshes["topology"][i])
    f0, f1 = meshes["face_offsets"][t], meshes["face_offsets"][t + 1]
    p0, p1 = meshes["part_offsets"][t], meshes["part_offsets"][t + 1]
    verts = np.array(vertices[v0:v1], dtype=np.float32)
    parts = np.array(meshes["vertex_parts"][p0:p1], dtype=np.int16)
    if len(parts) != len(verts):
        raise DatasetError(f"mesh {i}: {len(verts)} vertices but {len(parts)} part labels; the shard is corrupt")
    return verts, np.array(meshes["faces"][f0:f1], dtype=np.int64), parts


def write_shard(root: Path, split: str, index: int, images: np.ndarray, views: np.ndarray, quads: np.ndarray,
                meshes: tuple[np.ndarray, dict[str, np.ndarray]] | None, *,
                subjects: tuple[int, ...] = ()) -> ShardRecord:
    """Write one shard's files atomically and return its record (not yet in the manifest).

    Args:
        images: ``(N, 3, H, W)`` uint8.
        views: ``(N,)`` :data:`VIEW_DTYPE`.
        quads: ``(Q, 4)`` int32 indices into the shard's images.
        meshes: the output of :func:`pack_meshes`, or ``None`` when meshes are not stored.
        subjects: the manifest indices of the subjects whose bodies the shard holds.
    """
    root = Path(root)
    check_shapes("write_shard", images=(images, "N 3 H W", (np.dtype(np.uint8),)))
    if views.dtype != VIEW_DTYPE or views.shape != (len(images),):
        raise ShapeError("write_shard: views must be one VIEW_DTYPE record per image")
    quads = np.asarray(quads, dtype=np.int32).reshape(-1, 4)
    if quads.size and (quads.min() < 0 or quads.max() >= len(images)):
        raise ShapeError("write_shard: quadruplet indices outside the shard's images")
    name = f"shard-{index:05d}"
    folder = root / split
    arrays: dict[str, np.ndarray] = {"images": images, "views": views, "quads": quads}
    if meshes is not None:
        arrays["vertices"] = meshes[0]
    files = {}
    for role, arr in arrays.items():
        path = folder / f"{name}.{role}.npy"
        atomic_save_npy(path, arr)
        files[role] = file_record(root, path, arr.shape, arr.dtype.str)
    if meshes is not None:
        path = folder / f"{name}.meshes.npz"
        atomic_save_npz(path, meshes[1])
        files["meshes"] = file_record(root, path, None, None)
    return ShardRecord(index, name, int(len(images)), int(len(quads)), 0 if meshes is None else int(len(meshes[1]["pose"])),
                       files, tuple(int(s) for s in subjects))
