"""Checks of mesh files *before* pymeshlab reads them.

pymeshlab's readers silently drop what they cannot represent: an OBJ or OFF face whose
vertex index is out of range is dropped (OFF may even read past its vertex array), and a
vertex with a NaN or infinite coordinate disappears together with every face that uses it.
The metric would then be computed on a different mesh than the file holds. So the formats
whose structure is cheap to read (OBJ, OFF, ASCII and binary PLY with the usual layout,
ASCII and binary STL) are scanned here first, and any such defect raises
:class:`~cerberus_metrics.io.MeshInputError` naming the file, the line (or element number),
the bad index or vertex and the vertex count.

The scan is a validator, not a reader: when a file's layout is not one it understands (an
unusual PLY element order, a packed format), it returns without a verdict and the
post-load checks of :mod:`cerberus_metrics.io` apply. Coordinates and indices are never
taken from the scan.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

__all__ = ["MAX_FACES", "FileDefect", "check_counts", "scan_mesh_file"]

MAX_FACES = 2_000_000
"""The most faces (and vertices) a mesh may have; a larger one (or a header claiming one) is refused before it is
read, in one line. Reading, cleaning and voxelizing cost about 1 KB and, on the 2-core test machine, 0.3 ms a face
when idle and several times that when busy (``cerberus-metrics iou`` of a 1,310,720-face sphere against a
327,680-face one: 364 s at load 6, 548 s at load 10.6; issue 39), so a 10-million-face mesh ran for most of an
hour with no output. A mesh at this bound takes minutes; decimate a larger one first."""


class FileDefect(Exception):
    """A defect found in a mesh file; ``str()`` says what and where (the caller adds the file and the fix)."""

    def __init__(self, message: str, fix: str) -> None:
        super().__init__(message)
        self.fix = fix


_FIX_INDEX = "fix the face indices (or the export that produced the file)"
_FIX_NAN = "remove or repair those vertices (or the export that produced the file)"


def check_counts(n_v: int, n_f: int) -> None:
    """:class:`FileDefect` when a mesh's vertex or face count is negative or above :data:`MAX_FACES`."""
    for what, n in (("vertices", n_v), ("faces", n_f)):
        if n < 0 or n > MAX_FACES:
            raise FileDefect(f"{n} {what}: a mesh may have 0..{MAX_FACES} (a larger one takes most of an hour)",
                             "simplify the mesh (e.g. quadric decimation: pymeshlab's "
                             "meshing_decimation_quadric_edge_collapse) or check the header that states the count")


def _nan_defect(count: int, total: int, where: str, text: str) -> FileDefect:
    return FileDefect(
        f"{count} of {total} vertices have NaN or non-finite coordinates (first: {where}: {text!r}); "
        "pymeshlab would silently drop them with their faces",
        _FIX_NAN,
    )


def scan_mesh_file(path: Path) -> None:
    """Raise :class:`FileDefect` for out-of-range face indices or non-finite vertices in ``path``.

    Handles ``.obj``, ``.off``, ``.ply`` and ``.stl``; other suffixes (and layouts it does not
    understand) pass unchecked. Reads the file once; cost is linear in its size.
    """
    suffix = path.suffix.lower()
    if suffix == ".obj":
        _scan_obj(path)
    elif suffix == ".off":
        _scan_off(path)
    elif suffix == ".ply":
        _scan_ply(path)
    elif suffix == ".stl":
        _scan_stl(path)


def _finite(tokens: list[bytes]) -> bool:
    try:
        return all(math.isfinite(float(t)) for t in tokens)
    except ValueError:
        return True  # unparsable text is the reader's business, not a NaN


def _scan_obj(path: Path) -> None:
    """OBJ: ``v x y z`` lines and ``f a[/t[/n]] ...`` lines; 1-based indices, negative = relative.

    Line by line (about 1.5 us per line; an 80k-face OBJ takes ~0.15 s, half of pymeshlab's read).
    """
    n_v = 0
    bad_v, first_bad = 0, ("", "")
    late: list[tuple[int, int, bytes]] = []  # positive indices past the vertices read so far: check at the end
    with open(path, "rb") as fh:
        for lineno, raw in enumerate(fh, 1):
            line = raw.strip()
            if line.startswith(b"v ") or line.startswith(b"v\t"):
                n_v += 1
                coords = line.split()[1:4]
                if len(coords) < 3:
                    return  # malformed vertex: the reader reports it
                if not _finite(coords):
                    bad_v += 1
                    if bad_v == 1:
                        first_bad = (f"line {lineno}, vertex {n_v}", line.decode(errors="replace"))
            elif line.startswith(b"f ") or line.startswith(b"f\t"):
                for tok in line.split()[1:]:
                    try:
                        idx = int(tok.split(b"/", 1)[0])
                    except ValueError:
                        return  # not plain OBJ: leave it to the reader
                    if idx == 0 or idx < -n_v:
                        _obj_index_defect(lineno, line, idx, n_v, "at that line")
                    if idx > n_v:
                        late.append((lineno, idx, line))
    for lineno, idx, line in late:
        if idx > n_v:
            _obj_index_defect(lineno, line, idx, n_v, "in the file")
    if bad_v:
        raise _nan_defect(bad_v, n_v, *first_bad)


def _obj_index_defect(lineno: int, line: bytes, idx: int, n_v: int, when: str) -> None:
    raise FileDefect(
        f"face on line {lineno} ({line.decode(errors='replace')!r}) references vertex {idx}, but there are "
        f"{n_v} vertices {when} (valid: 1..{n_v}, or -1..-{n_v} counted back)",
        _FIX_INDEX,
    )


def _tokens(path: Path):
    """(line number, tokens) of the non-empty lines of a text file, '#' comments removed."""
    with open(path, "rb") as fh:
        for lineno, raw in enumerate(fh, 1):
            toks = raw.split(b"#", 1)[0].split()
            if toks:
                yield lineno, toks


def _scan_off(path: Path) -> None:
    """OFF: header ``[ST][C][N][4][n]OFF``, counts ``V F E``, V vertex lines, F lines ``k i1 .. ik``."""
    it = _tokens(path)
    try:
        _, head = next(it)
        if not re.fullmatch(rb"(ST)?C?N?OFF", head[0]):
            return  # 4D, nD or binary OFF: not scanned
        counts = head[1:]
        if len(counts) < 2:
            _, counts = next(it)
        n_v, n_f = int(counts[0]), int(counts[1])
        check_counts(n_v, n_f)
        bad_v, first_bad = 0, ("", "")
        for k in range(n_v):
            lineno, toks = next(it)
            if not _finite(toks[:3]):
                bad_v += 1
                if bad_v == 1:
                    first_bad = (f"line {lineno}, vertex {k}", b" ".join(toks).decode(errors="replace"))
        for j in range(n_f):
            lineno, toks = next(it)
            k = int(toks[0])
            for tok in toks[1 : 1 + k]:
                idx = int(tok)
                if not 0 <= idx < n_v:
                    raise FileDefect(
                        f"face {j} on line {lineno} ({b' '.join(toks).decode(errors='replace')!r}) references "
                        f"vertex {idx}, but the file has {n_v} vertices (valid: 0..{n_v - 1})",
                        _FIX_INDEX,
                    )
    except (StopIteration, ValueError, IndexError):
        return  # truncated or unusual: the reader reports it
    if bad_v:
        raise _nan_defect(bad_v, n_v, *first_bad)


_PLY_TYPES = {
    b"char": "i1", b"int8": "i1", b"uchar": "u1", b"uint8": "u1", b"short": "i2", b"int16": "i2",
    b"ushort": "u2", b"uint16": "u2", b"int": "i4", b"int32": "i4", b"uint": "u4", b"uint32": "u4",
    b"float": "f4", b"float32": "f4", b"double": "f8", b"float64": "f8",
}


def _scan_ply(path: Path) -> None:
    """PLY whose first element is ``vertex`` (scalar properties x, y, z among them) followed by
    ``face`` with a single list property; other layouts pass unchecked."""
    with open(path, "rb") as fh:
        if fh.readline().strip() != b"ply":
            return
        fmt, elements = None, []  # elements: [name, count, [(prop name, type) | (name, count type, item type)]]
        while True:
            line = fh.readline()
            if not line:
                return
            toks = line.split()
            if not toks or toks[0] in (b"comment", b"obj_info"):
                continue
            if toks[0] == b"end_header":
                break
            if toks[0] == b"format" and len(toks) >= 2:
                fmt = toks[1]
            elif toks[0] == b"element" and len(toks) == 3:
                elements.append([toks[1], int(toks[2]), []])
            elif toks[0] == b"property" and elements:
                elements[-1][2].append(tuple(toks[1:]))
        if len(elements) < 2 or elements[0][0] != b"vertex" or elements[1][0] != b"face":
            return
        (_, n_v, vprops), (_, n_f, fprops) = elements[0], elements[1]
        check_counts(n_v, n_f)
        if any(len(p) != 2 or p[0] not in _PLY_TYPES for p in vprops):
            return
        names = [p[1] for p in vprops]
        if not {b"x", b"y", b"z"} <= set(names) or len(fprops) != 1 or fprops[0][0] != b"list":
            return
        xyz = [names.index(c) for c in (b"x", b"y", b"z")]
        if fmt == b"ascii":
            _scan_ply_ascii(fh, n_v, n_f, xyz)
        elif fmt in (b"binary_little_endian", b"binary_big_endian"):
            end = "<" if fmt == b"binary_little_endian" else ">"
            count_t, item_t = _PLY_TYPES.get(fprops[0][1]), _PLY_TYPES.get(fprops[0][2])
            if count_t is None or item_t is None:
                return
            vdtype = np.dtype([(f"p{i}", end + _PLY_TYPES[p[0]]) for i, p in enumerate(vprops)])
            _scan_ply_binary(fh, n_v, n_f, vdtype, xyz, np.dtype(end + count_t), np.dtype(end + item_t))


def _scan_ply_ascii(fh, n_v: int, n_f: int, xyz: list[int]) -> None:
    bad_v, first_bad = 0, ("", "")
    try:
        for k in range(n_v):
            toks = fh.readline().split()
            if not _finite([toks[i] for i in xyz]):
                bad_v += 1
                if bad_v == 1:
                    first_bad = (f"vertex {k}", b" ".join(toks).decode(errors="replace"))
        for j in range(n_f):
            toks = fh.readline().split()
            idx = [int(t) for t in toks[1 : 1 + int(toks[0])]]
            bad = [i for i in idx if not 0 <= i < n_v]
            if bad:
                raise FileDefect(
                    f"face {j} ({' '.join(map(str, idx))}) references vertex {bad[0]}, but the file has {n_v} "
                    f"vertices (valid: 0..{n_v - 1})",
                    _FIX_INDEX,
                )
    except (ValueError, IndexError):
        return
    if bad_v:
        raise _nan_defect(bad_v, n_v, *first_bad)


def _scan_ply_binary(fh, n_v: int, n_f: int, vdtype, xyz, count_t, item_t) -> None:
    data = fh.read(n_v * vdtype.itemsize)
    if len(data) < n_v * vdtype.itemsize:
        return
    v = np.frombuffer(data, vdtype, n_v)
    coords = np.stack([v[f"p{i}"].astype(np.float64) for i in xyz], axis=1)
    finite = np.isfinite(coords).all(axis=1)
    # Faces: fast path when every face is a triangle (the common case), else walk them.
    tri = np.dtype([("n", count_t), ("i", item_t, (3,))])
    rest = fh.read()
    faces: list[np.ndarray] = []
    if len(rest) >= n_f * tri.itemsize:
        f = np.frombuffer(rest, tri, n_f)
        if (f["n"] == 3).all():
            faces = [f["i"].astype(np.int64)]
    if not faces and n_f:
        off = 0
        for _ in range(n_f):
            if off + count_t.itemsize > len(rest):
                return
            k = int(np.frombuffer(rest, count_t, 1, off)[0])
            off += count_t.itemsize
            if off + k * item_t.itemsize > len(rest):
                return
            faces.append(np.frombuffer(rest, item_t, k, off).astype(np.int64))
            off += k * item_t.itemsize
    if len(faces) == 1 and faces[0].ndim == 2:  # all triangles: one vectorised test
        rows = np.flatnonzero(((faces[0] < 0) | (faces[0] >= n_v)).any(axis=1))
        faces = [faces[0][rows[0]]] if rows.size else []
        first = int(rows[0]) if rows.size else 0
    else:
        first = 0
    for j, idx in enumerate(faces, first):
        bad = idx[(idx < 0) | (idx >= n_v)]
        if bad.size:
            raise FileDefect(
                f"face {j} ({' '.join(map(str, idx.tolist()))}) references vertex {int(bad[0])}, but the file "
                f"has {n_v} vertices (valid: 0..{n_v - 1})",
                _FIX_INDEX,
            )
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        raise _nan_defect(int((~finite).sum()), n_v, f"vertex {k}", str(coords[k].tolist()))


def _scan_stl(path: Path) -> None:
    """STL (binary or ASCII): triangle corners must be finite (no indices to check)."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
        if len(head) == 84:
            n = int(np.frombuffer(head, "<u4", 1, 80)[0])
            if size == 84 + 50 * n:  # binary
                rec = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
                tri = np.frombuffer(fh.read(50 * n), rec, n)["v"]
                bad = ~np.isfinite(tri).all(axis=(1, 2))
                if bad.any():
                    k = int(np.flatnonzero(bad)[0])
                    raise FileDefect(
                        f"{int(bad.sum())} of {n} triangles have NaN or non-finite corner coordinates (first: "
                        f"triangle {k}: {tri[k].tolist()}); pymeshlab would silently drop them",
                        _FIX_NAN,
                    )
                return
    if not head.lstrip().startswith(b"solid"):  # nor binary (its size), nor ASCII: pymeshlab would read on and on
        claimed = f"its header claims {n} triangles ({84 + 50 * n} bytes)" if len(head) == 84 else "shorter than a header"
        raise FileDefect(f"'{path}' is neither an ASCII STL (it does not start with 'solid') nor a whole binary STL "
                         f"({claimed}, the file has {size} bytes)", "re-export the mesh; a truncated download or copy "
                         "is the usual cause")
    n_v = bad_v = 0
    first_bad = ("", "")
    for lineno, toks in _tokens(path):
        if toks[0] == b"vertex":
            n_v += 1
            if not _finite(toks[1:4]):
                bad_v += 1
                if bad_v == 1:
                    first_bad = (f"line {lineno}", b" ".join(toks).decode(errors="replace"))
    if bad_v:
        raise _nan_defect(bad_v, n_v, *first_bad)
