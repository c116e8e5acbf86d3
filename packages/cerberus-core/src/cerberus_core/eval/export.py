"""Export posed part meshes: one GLB per image (parts as named, coloured nodes) and OBJ files.

Layout for an image exported under ``stem`` into ``out_dir``::

    out_dir/stem.glb                 every part as a node "part_00", "part_01", ... with its own
                                     material colour (cerberus_core.viz.part_colors)
    out_dir/stem.obj                 all parts in one OBJ, vertex-coloured by part, each part its own
                                     object and group (``o part_00`` / ``g part_00``)
    out_dir/stem_parts/part_00.obj   each part alone, vertex-coloured

Coordinates are the world frame of the dataset (+Y up, normalised units). Every file is written to a
temporary name and renamed (:func:`cerberus_core.plumbing.atomic.atomic_write`), so an interrupted export
never leaves a truncated mesh.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
import trimesh

from cerberus_core.errors import ConfigError, MeshError, ShapeError
from cerberus_core.parts import PartSet
from cerberus_core.plumbing.atomic import atomic_write
from cerberus_core.shapes import check_shapes
from cerberus_core.viz import part_colors

FORMATS = ("glb", "obj")


def part_name(k: int) -> str:
    """Node / file name of part ``k``: ``part_00``, ``part_01``, ...

    Example:
        >>> part_name(3), part_name(120)
        ('part_03', 'part_120')
    """
    return f"part_{k:02d}"


def _rgba(colors: torch.Tensor | np.ndarray | None, n: int) -> np.ndarray:
    c = part_colors(n) if colors is None else colors
    c = np.asarray(c.detach().cpu() if hasattr(c, "detach") else c, dtype=np.float64)
    check_shapes("export", colours=(c, f"{n} 3"))
    return np.concatenate([np.round(np.clip(c, 0, 1) * 255), np.full((n, 1), 255)], axis=1).astype(np.uint8)


def _part_meshes(part_vertices: np.ndarray, faces: np.ndarray) -> list[trimesh.Trimesh]:
    pv = np.asarray(part_vertices, dtype=np.float64)
    check_shapes("export", part_vertices=(pv, "P V 3"))
    if not np.isfinite(pv).all():
        raise MeshError("export: part vertices contain NaN or inf; the reconstruction is broken, nothing was written "
                        "(export a reconstruction of a checkpoint whose training losses stayed finite)")
    f = np.asarray(faces, dtype=np.int64)
    return [trimesh.Trimesh(v, f, process=False) for v in pv]


def part_scene(part_vertices: np.ndarray, faces: np.ndarray,
               colors: torch.Tensor | np.ndarray | None = None) -> trimesh.Scene:
    """A scene with one node per part, named ``part_00``..., each with a PBR material of its colour.

    Args:
        part_vertices: ``(P, V, 3)`` posed vertices.
        faces: ``(F, 3)``.
        colors: ``(P, 3)`` RGB in [0, 1] (default :func:`cerberus_core.viz.part_colors`).
    """
    meshes = _part_meshes(part_vertices, faces)
    rgba = _rgba(colors, len(meshes))
    scene = trimesh.Scene()
    for k, mesh in enumerate(meshes):
        material = trimesh.visual.material.PBRMaterial(name=part_name(k), baseColorFactor=rgba[k],
                                                       metallicFactor=0.0, roughnessFactor=0.9)
        mesh.visual = trimesh.visual.TextureVisuals(material=material)
        scene.add_geometry(mesh, node_name=part_name(k), geom_name=part_name(k))
    return scene


def _coloured(mesh: trimesh.Trimesh, rgba: np.ndarray) -> trimesh.Trimesh:
    return trimesh.Trimesh(mesh.vertices, mesh.faces, process=False,
                           vertex_colors=np.tile(rgba, (len(mesh.vertices), 1)))


def _obj_text(mesh: trimesh.Trimesh) -> bytes:
    return trimesh.exchange.obj.export_obj(mesh, include_normals=False, include_color=True).encode()


def _grouped_obj_text(meshes: Sequence[trimesh.Trimesh], rgba: np.ndarray) -> bytes:
    """All parts in one OBJ, each under ``o part_NN`` / ``g part_NN``, vertex colours as ``v x y z r g b``."""
    lines = ["# Cerberus part meshes: one object and group per part"]
    offset = 1
    for k, mesh in enumerate(meshes):
        rgb = rgba[k, :3] / 255.0
        lines += [f"o {part_name(k)}", f"g {part_name(k)}"]
        lines += [f"v {x:.8g} {y:.8g} {z:.8g} {rgb[0]:.4g} {rgb[1]:.4g} {rgb[2]:.4g}" for x, y, z in mesh.vertices]
        lines += [f"f {a + offset} {b + offset} {c + offset}" for a, b, c in np.asarray(mesh.faces)]
        offset += len(mesh.vertices)
    return ("\n".join(lines) + "\n").encode()


def _write(path: Path, data: bytes) -> Path:
    atomic_write(path, lambda fh: fh.write(data))
    return path


def export_parts(part_vertices: np.ndarray, faces: np.ndarray, out_dir: str | Path, stem: str, *,
                 formats: Sequence[str] = FORMATS, colors: torch.Tensor | np.ndarray | None = None) -> list[Path]:
    """Write one image's posed parts (see the module docstring for the layout).

    Args:
        part_vertices: ``(P, V, 3)`` posed world vertices.
        faces: ``(F, 3)``.
        out_dir: output folder (created).
        stem: file name stem, e.g. the input image's name.
        formats: any of ``"glb"``, ``"obj"``.
        colors: ``(P, 3)`` part colours (default :func:`cerberus_core.viz.part_colors`).
    Returns:
        The paths written.

    Example: two tetrahedra (``(P, V, 3) = (2, 4, 3)``, world units) written to a temporary folder:

        >>> import tempfile
        >>> corners = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]) * 0.1
        >>> faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
        >>> tmp = tempfile.TemporaryDirectory()
        >>> written = export_parts(np.stack([corners, corners + [0.2, 0.0, 0.0]]), faces, tmp.name, "recon")
        >>> [p.relative_to(tmp.name).as_posix() for p in written]
        ['recon.glb', 'recon.obj', 'recon_parts/part_00.obj', 'recon_parts/part_01.obj']
        >>> obj = written[1].read_text().splitlines()
        >>> obj[1:4], sum(line.startswith("f ") for line in obj)  # part 0's object, group, first vertex (xyz rgb)
        (['o part_00', 'g part_00', 'v 0 0 0 0.949 0.3333 0.3333'], 8)
        >>> glb = trimesh.load(written[0])  # one node per part
        >>> sorted(glb.geometry), glb.bounds.round(2).tolist()
        (['part_00', 'part_01'], [[0.0, 0.0, 0.0], [0.3, 0.1, 0.1]])
        >>> tmp.cleanup()
    """
    unknown = set(formats) - set(FORMATS)
    if unknown:
        raise ConfigError.about("formats", sorted(unknown), "unknown format(s)", f"choose from {list(FORMATS)}")
    if not stem or "/" in stem or "\\" in stem:
        raise ConfigError.about("stem", stem, "must be a plain file name",
                                "a name without a folder, e.g. `stem=\"recon\"`")
    out_dir = Path(out_dir)
    meshes = _part_meshes(part_vertices, faces)
    rgba = _rgba(colors, len(meshes))
    written = []
    if "glb" in formats:
        glb = part_scene(part_vertices, faces, colors).export(file_type="glb")
        written.append(_write(out_dir / f"{stem}.glb", glb))
    if "obj" in formats:
        coloured = [_coloured(m, rgba[k]) for k, m in enumerate(meshes)]
        written.append(_write(out_dir / f"{stem}.obj", _grouped_obj_text(meshes, rgba)))
        for k, mesh in enumerate(coloured):
            written.append(_write(out_dir / f"{stem}_parts" / f"{part_name(k)}.obj", _obj_text(mesh)))
    return written


def export_reconstruction(recon: PartSet, out_dir: str | Path, stems: Sequence[str] | None = None, *,
                          formats: Sequence[str] = FORMATS) -> list[Path]:
    """Export every image of a reconstruction (``stems[i]`` names image ``i``; default ``recon_000``...).

    Example: two images of three parts each (icospheres of 12 vertices), to a temporary folder:

        >>> import tempfile
        >>> from cerberus_core.render.templates import icosphere
        >>> ball = icosphere(0, radius=0.1)
        >>> recon = PartSet.from_posed(ball.vertices.expand(2, 3, -1, -1), ball.faces)  # (B, P, V, 3)
        >>> tmp = tempfile.TemporaryDirectory()
        >>> [p.name for p in export_reconstruction(recon, tmp.name, formats=("glb",))]
        ['recon_000.glb', 'recon_001.glb']
        >>> len(export_reconstruction(recon, tmp.name, ["front", "side"], formats=("obj",)))  # 2 x (1 + 3 parts)
        8
        >>> export_reconstruction(recon, tmp.name, ["front"])
        Traceback (most recent call last):
        ...
        cerberus_core.errors.ShapeError: export_reconstruction: 2 reconstructions need 2 names, got 1; ...
        >>> tmp.cleanup()
    """
    stems = [f"recon_{i:03d}" for i in range(recon.batch_size)] if stems is None else list(stems)
    if len(stems) != recon.batch_size:
        raise ShapeError(f"export_reconstruction: {recon.batch_size} reconstructions need {recon.batch_size} names, "
                         f"got {len(stems)}; pass one name per reconstruction or `stems=None`")
    posed = recon.posed().detach().cpu().numpy()
    faces = recon.faces.detach().cpu().numpy()
    written = []
    for i, stem in enumerate(stems):
        written += export_parts(posed[i], faces, out_dir, stem, formats=formats)
    return written
