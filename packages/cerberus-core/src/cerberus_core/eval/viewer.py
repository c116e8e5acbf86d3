"""An interactive 3D viewer of reconstructions: one self-contained ``index.html`` beside the GLBs.

The page shows one card per image: the input picture (with its voxel IoU where the evaluation scored it), a
3D view (orbit with the mouse, wheel to zoom, right-drag to pan; it opens at the input camera's view), a
switch between the models of that image (the reconstruction; the ground truth, where there is one; the
new pose of Figure 1 (f)), one visibility toggle per part in its colour, named by the part's label where
it is known (``head (part_05)``: the ground-truth part it covers most, from ``cerberus eval``'s part
quality or a shipped model's card), and a light control (the training light, which follows the camera,
or Figure 1 (d)'s new light, and its direction).

It uses three.js, vendored at a pinned version in ``cerberus_core/vendor/three-<version>/`` (MIT;
see the README there). Everything is inlined, so the page works offline from ``file://`` (where Chromium blocks
module files and ``fetch``) as well as over HTTP: the GLBs and pictures are base64 strings in the page,
and the three.js modules are ``data:`` URLs of an import map. That costs about 1.3 MB for three.js
plus the meshes, so the number of cards is bounded (``limit``, default :data:`DEFAULT_LIMIT`) and the
page says how many of how many images it shows.

API: :func:`write_viewer` writes a page from :class:`ViewerEntry` items (files already on disk);
:func:`write_reconstruction_viewer` exports what the page needs for a batch of reconstructions
(``<stem>.glb``, ``<stem>_new_pose.glb``, ``<stem>_gt.glb``) and writes the page, as ``cerberus
reconstruct`` and ``cerberus eval`` do.
"""
from __future__ import annotations

import base64
import html
import io
import json
import posixpath
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import trimesh
from PIL import Image

from cerberus_core.errors import ConfigError, ShapeError
from cerberus_core.eval.export import export_parts, part_name
from cerberus_core.parts import PartSet, pose_donors, transfer_pose
from cerberus_core.plumbing.atomic import atomic_write, atomic_write_text
from cerberus_core.plumbing.names import printable
from cerberus_core.render.camera import Camera
from cerberus_core.render.light import NEW_LIGHT_CAMERA_DIRECTION
from cerberus_core.viz import part_colors, to_uint8

THREE_VERSION = "0.184.0"
ASSETS = Path(__file__).with_name("viewer_assets")
#: Third-party files, each with its licence (``cerberus_core/vendor/README.md``).
VENDOR = Path(__file__).resolve().parents[1] / "vendor"
THREE_DIR = VENDOR / f"three-{THREE_VERSION}"
#: The vendored files the page needs (paths inside the three.js package); the first is ``three``.
THREE_FILES = ("build/three.module.min.js", "build/three.core.min.js", "examples/jsm/controls/OrbitControls.js",
               "examples/jsm/loaders/GLTFLoader.js", "examples/jsm/utils/BufferGeometryUtils.js",
               "examples/jsm/utils/SkeletonUtils.js")
MODULE_PREFIX = "cerberus-three/"
#: Cards on one page unless told otherwise.
DEFAULT_LIMIT = 12
CANVAS_SIZE = 360
#: Shown when an entry has no camera: the datasets' usual view.
DEFAULT_CAMERA = {"azimuth": 0.0, "elevation": 10.0, "distance": 2.7, "fov_y": 30.0}
#: The light presets, in the camera's frame (+x right, +y up, +z towards the viewer): the datasets'
#: light following the camera (:meth:`cerberus_core.render.interface.Light.following`) and Figure 1
#: (d)'s new light (:func:`cerberus_core.eval.figures.camera_relative_light`).
LIGHTS = {
    "training": {"label": "training (from the camera)", "direction": [0.0, 0.0, 1.0], "ambient": 0.4, "diffuse": 0.6},
    "new": {"label": "new light (Figure 1 d)", "direction": list(NEW_LIGHT_CAMERA_DIRECTION),
            "ambient": 0.25, "diffuse": 0.75},
}
MODEL_LABELS = {"reconstruction": "Reconstruction", "ground_truth": "Ground truth", "new_pose": "New pose"}


@dataclass
class ViewerEntry:
    """One card of the page.

    Attributes:
        name: its title (e.g. the input's file stem).
        image: the input picture: a PNG/JPEG file, its bytes, or a ``(3, H, W)`` tensor in [0, 1].
        reconstruction: GLB of the posed parts (:func:`cerberus_core.eval.export.export_parts`).
        ground_truth: GLB of the ground-truth body, if there is one (:func:`export_body_glb`).
        new_pose: GLB of the parts in another image's pose (Figure 1 (f)), if any.
        camera: the input camera as ``{"azimuth", "elevation", "distance", "fov_y"}`` (degrees; look-at
            the origin, +Y up): the view the page opens at (:func:`camera_view`). Default
            :data:`DEFAULT_CAMERA`.
        note: a line under the title.
        iou: the reconstruction's voxel IoU against the ground truth, where the evaluation scored it
            (``None``: not scored).
    """

    name: str
    image: Path | str | bytes | torch.Tensor
    reconstruction: Path | str
    ground_truth: Path | str | None = None
    new_pose: Path | str | None = None
    camera: dict | None = None
    note: str = ""
    iou: float | None = None


# ------------------------------------------------------------------ three.js as an import map
_RELATIVE_IMPORT = re.compile(r"""(\bfrom\s*|\bimport\s*\(?\s*)(["'])(\.\.?/[^"'\s]+)\2""")


def _specifier(path: str) -> str:
    return "three" if path == THREE_FILES[0] else MODULE_PREFIX + path


def vendored_modules() -> dict[str, str]:
    """``{module specifier: source}`` of the vendored three.js files, each relative import rewritten to
    the specifier of the vendored file it names (``data:`` modules have no base URL to resolve against).

    Raises:
        FileNotFoundError: if a vendored file is missing (a broken install).
    """
    sources = {p: (THREE_DIR / p).read_text(encoding="utf-8") for p in THREE_FILES}

    def rewrite(path: str, text: str) -> str:
        def sub(m: re.Match) -> str:
            target = posixpath.normpath(posixpath.join(posixpath.dirname(path), m.group(3)))
            if target not in sources:  # e.g. a path in a comment: leave it
                return m.group(0)
            return f"{m.group(1)}{m.group(2)}{_specifier(target)}{m.group(2)}"
        return _RELATIVE_IMPORT.sub(sub, text)

    return {_specifier(p): rewrite(p, text) for p, text in sources.items()}


def import_map() -> dict:
    """The page's import map: every vendored module as a base64 ``data:`` URL."""
    return {"imports": {spec: "data:text/javascript;base64," + base64.b64encode(src.encode()).decode()
                        for spec, src in vendored_modules().items()}}


# ------------------------------------------------------------------ meshes for the page
def camera_view(camera: Camera) -> dict:
    """``{"azimuth", "elevation", "distance", "fov_y"}`` of a batch-1 look-at camera aimed at the origin."""
    if camera.batch_size != 1:
        raise ShapeError(f"camera_view: expected one camera, got {camera.batch_size}; pass `camera.index([i])`")
    az, el, dist = camera.spherical()
    return {"azimuth": float(az[0]), "elevation": float(el[0]), "distance": float(dist[0]),
            "fov_y": float(camera.fov_y_deg.reshape(-1)[0])}


def body_scene(body) -> trimesh.Scene:
    """A ground-truth body (:class:`cerberus_core.bodies.body.PosedBody`) as one node per semantic part
    (a face belongs to the part of its first vertex), named by the part, each in its own colour."""
    vertices = np.asarray(body.vertices, dtype=np.float64)
    faces = np.asarray(body.faces, dtype=np.int64)
    labels = np.asarray(body.vertex_parts, dtype=np.int64)[faces[:, 0]]
    names = list(body.part_names)
    colors = np.round(part_colors(len(names)).numpy() * 255).astype(np.uint8)
    scene = trimesh.Scene()
    for k, name in enumerate(names):
        sel = faces[labels == k]
        if not len(sel):
            continue
        used, inverse = np.unique(sel, return_inverse=True)
        mesh = trimesh.Trimesh(vertices[used], inverse.reshape(-1, 3), process=False)
        material = trimesh.visual.material.PBRMaterial(name=name, baseColorFactor=[*colors[k], 255],
                                                       metallicFactor=0.0, roughnessFactor=0.9)
        mesh.visual = trimesh.visual.TextureVisuals(material=material)
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    return scene


def export_body_glb(body, path: str | Path) -> Path:
    """Write a ground-truth body as a GLB (:func:`body_scene`), atomically."""
    data = body_scene(body).export(file_type="glb")
    atomic_write(Path(path), lambda fh: fh.write(data))
    return Path(path)


def _image_png(image: Path | str | bytes | torch.Tensor) -> tuple[str, bytes]:
    if isinstance(image, torch.Tensor):
        buf = io.BytesIO()
        Image.fromarray(to_uint8(image.reshape(1, *image.shape[-3:]))[0]).save(buf, format="PNG")
        return "image/png", buf.getvalue()
    data = image if isinstance(image, bytes) else Path(image).read_bytes()
    return ("image/jpeg" if data[:3] == b"\xff\xd8\xff" else "image/png"), data


def _b64(path: Path | str) -> str:
    return base64.b64encode(Path(path).read_bytes()).decode()


# ------------------------------------------------------------------ the page
@dataclass(frozen=True)
class ViewerPage:
    """How a viewer page is made (:func:`write_viewer`, :func:`write_reconstruction_viewer`).

    Attributes:
        title: the page's heading.
        limit: at most this many cards (the page says how many it left out).
        limit_hint: the setting that shows more, e.g. ``"viewer_images"``.
        background: the 3D views' background colour, RGB in [0, 1].
        part_labels: the label of learned part ``k`` (the node ``part_NN`` of the reconstruction and new-pose
            GLBs, :func:`~cerberus_core.eval.export.part_name`), ``None`` where unknown; the part toggles say
            ``LABEL (part_NN)``. Default: the node names alone.
    """

    title: str = "Cerberus reconstructions"
    limit: int = DEFAULT_LIMIT
    limit_hint: str = ""
    background: Sequence[float] = (1.0, 1.0, 1.0)
    part_labels: Sequence[str | None] | None = None


def write_viewer(out_dir: str | Path, entries: Sequence[ViewerEntry], page: ViewerPage | None = None, *,
                 total: int | None = None, filename: str = "index.html") -> Path:
    """Write the viewer page ``out_dir/filename`` for the first ``page.limit`` entries.

    Args:
        entries: the cards, in order; their files are read and inlined now.
        page: title, limit, background and part labels (:class:`ViewerPage`; default its defaults).
        total: how many images there were in all (default ``len(entries)``), for that sentence.
    Returns:
        The page's path.
    """
    page = page or ViewerPage()
    title, limit, limit_hint, background, part_labels = (page.title, page.limit, page.limit_hint, page.background,
                                                         page.part_labels)
    if limit < 1:
        raise ConfigError.about("limit", limit, "write_viewer: must be >= 1", "`limit=1` or more")
    entries = list(entries)
    total = len(entries) if total is None else total
    shown = entries[:limit]
    if not shown:
        raise ConfigError("write_viewer: no entries; pass at least one `ViewerEntry` in `entries`", key="entries")
    data_entries, cards = [], []
    for i, e in enumerate(shown):
        models = [(k, getattr(e, k)) for k in ("reconstruction", "ground_truth", "new_pose") if getattr(e, k)]
        data_entries.append({"index": i, "name": printable(e.name), "camera": e.camera, "iou": e.iou,
                             "models": [{"key": k, "label": MODEL_LABELS[k], "glb": _b64(p)} for k, p in models]})
        mime, png = _image_png(e.image)
        note = f'<p class="meta">{_html(e.note)}</p>' if e.note else ""
        caption = "Input" if e.iou is None else f"Input · voxel IoU {e.iou:.3f}"
        cards.append(f'<section class="card" data-index="{i}"><h2>{_html(e.name)}</h2>{note}'
                     f'<div class="row"><figure><img alt="input picture of {_html(e.name)}" '
                     f'src="data:{mime};base64,{base64.b64encode(png).decode()}"><figcaption>{_html(caption)}'
                     f'</figcaption></figure><div class="view"></div></div></section>')
    labels = {part_name(k): printable(label) for k, label in enumerate(part_labels or []) if label}
    data = {"canvas_size": CANVAS_SIZE, "background": [float(c) for c in background], "lights": LIGHTS,
            "default_camera": DEFAULT_CAMERA, "entries": data_entries, "part_labels": labels,
            "labelled_models": ["reconstruction", "new_pose"]}
    count = (f"All {total} image(s)." if len(shown) == total else
             f"The first {len(shown)} of {total} images" + (f" ({limit_hint} sets how many)." if limit_hint else "."))
    html = _PAGE.format(
        title=_html(title), count=_html(count), version=THREE_VERSION,
        css=(ASSETS / "viewer.css").read_text(encoding="utf-8"),
        importmap=_script_json(import_map()), data=_script_json(data), cards="\n".join(cards),
        js=(ASSETS / "viewer.js").read_text(encoding="utf-8"))
    path = Path(out_dir) / filename
    atomic_write_text(path, html)
    return path


def _html(text: object) -> str:
    """Text for HTML content or a quoted attribute: control characters and undecodable bytes shown as
    escapes (:func:`cerberus_core.plumbing.names.printable`), then ``& < > " '`` as character references."""
    return html.escape(printable(text), quote=True)


def _script_json(obj) -> str:
    """JSON safe inside a ``<script>`` element: ``<``, ``>`` and ``&`` as ``\\u`` escapes, so no data can
    close the element (``</script>``), open a comment (``<!--``) or a script (``<script``), whatever
    names it holds; non-ASCII (U+2028 too) is escaped by ``json.dumps``. ``JSON.parse`` reads it back
    unchanged."""
    text = json.dumps(obj, separators=(",", ":"), ensure_ascii=True)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


_PAGE = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>
{css}</style>
<script>
window.cerberusViewer = {{ ready: false, errors: [], meshCount: 0, cards: [] }};
window.addEventListener('error', (e) => window.cerberusViewer.errors.push(String(e.message || e)));
window.addEventListener('unhandledrejection', (e) => window.cerberusViewer.errors.push(String(e.reason)));
</script>
<script type="importmap">{importmap}</script>
</head>
<body data-viewer="loading">
<header>
<h1>{title}</h1>
<p>{count} Drag to orbit, wheel to zoom, right-drag to pan; the view opens at the input camera's.</p>
</header>
<main>
{cards}
</main>
<footer>Rendered with three.js {version} (MIT licence), vendored in the page: works offline.</footer>
<pre id="viewer-status" hidden></pre>
<script type="application/json" id="cerberus-viewer-data">{data}</script>
<script type="module">
{js}</script>
</body>
</html>
"""


# ------------------------------------------------------------------ one call for the commands
@dataclass(frozen=True)
class CardDetails:
    """What each image's card shows beside its reconstruction (:func:`write_reconstruction_viewer`), one entry per
    image, or ``None`` for nothing.

    Attributes:
        bodies: the ground-truth :class:`PosedBody` of each image (its mesh beside the reconstruction).
        notes: a line per image: why the input is out of the training domain, ``""`` for none (an image
            with a note lends its pose only where no other can).
        ious: each image's voxel IoU where the evaluation scored it (``None`` where not).
    """

    bodies: Sequence | None = None
    notes: Sequence[str] | None = None
    ious: Sequence[float | None] | None = None


def write_reconstruction_viewer(out_dir: str | Path, images: torch.Tensor, recon: PartSet, camera: Camera,
                                stems: Sequence[str], page: ViewerPage | None = None,
                                details: CardDetails | None = None) -> list[Path]:
    """Export the meshes of the first ``page.limit`` images and write ``out_dir/index.html``.

    For image ``i`` named ``stems[i]`` writes ``<stem>.glb`` (the reconstruction), ``<stem>_new_pose.glb``
    (its parts with the rotations and translations predicted from another image, as the ``new_pose``
    picture of :func:`cerberus_core.eval.figures.save_image_pictures`: the next one in the training domain,
    :func:`~cerberus_core.parts.pose_donors`; only with two or more images) and, with ``bodies``
    (``bodies[i]`` the ground-truth :class:`PosedBody` of image ``i``), ``<stem>_gt.glb``.

    Args:
        images: ``(N, 3, H, W)`` the inputs in [0, 1]; camera: their ``N`` cameras; recon: batch ``N``.
        stems: each image's name.
        page: the page (:class:`ViewerPage`; its ``limit`` of cards, ``0``: write nothing).
        details: what the cards show besides (:class:`CardDetails`: ground truth, notes, IoUs).
    Returns:
        The files written, the page last.
    """
    page, details = page or ViewerPage(), details or CardDetails()
    bodies, notes, ious, limit, part_labels = (details.bodies, details.notes, details.ious, page.limit,
                                               page.part_labels)
    n = recon.batch_size
    if notes is not None and len(notes) != n:
        raise ShapeError(f"write_reconstruction_viewer: {n} reconstructions but {len(notes)} notes; pass one note "
                         "per image (\"\" for none)")
    if ious is not None and len(ious) != n:
        raise ShapeError(f"write_reconstruction_viewer: {n} reconstructions but {len(ious)} IoUs; pass one per image "
                         "(None where not scored)")
    if part_labels is not None and len(part_labels) != recon.num_parts:
        raise ShapeError(f"write_reconstruction_viewer: {recon.num_parts} parts but {len(part_labels)} part labels; "
                         "pass one label per learned part (None where unknown), or `part_labels=None`")
    if len(stems) != n or images.shape[0] != n or camera.batch_size != n or (bodies is not None and len(bodies) != n):
        raise ShapeError(f"write_reconstruction_viewer: {n} reconstructions but {images.shape[0]} images, "
                         f"{camera.batch_size} cameras, {len(stems)} names"
                         + ("" if bodies is None else f", {len(bodies)} bodies")
                         + "; pass one image, camera, name (and body) per reconstruction")
    if limit <= 0:
        return []
    out_dir = Path(out_dir)
    faces = recon.faces.detach().cpu().numpy()
    donors = pose_donors(n, None if notes is None else [bool(x) for x in notes])
    written, entries = [], []
    for i in range(min(limit, n)):
        stem, one = stems[i], recon.index([i])
        written += export_parts(one.posed()[0].detach().cpu().numpy(), faces, out_dir, stem, formats=("glb",))
        entry = ViewerEntry(stems[i], images[i], out_dir / f"{stem}.glb", camera=camera_view(camera.index([i])),
                            iou=None if ious is None else ious[i])
        if bodies is not None:
            entry.ground_truth = export_body_glb(bodies[i], out_dir / f"{stem}_gt.glb")
            written.append(entry.ground_truth)
        j = donors[i]
        if j is not None:
            posed = transfer_pose(one, recon.index([j])).posed()[0].detach().cpu().numpy()
            written += export_parts(posed, faces, out_dir, f"{stem}_new_pose", formats=("glb",))
            entry.new_pose = out_dir / f"{stem}_new_pose.glb"
            flagged = ", which is out of the training domain (no other image is in it)" if notes and notes[j] else ""
            entry.note = (f"New pose: these parts with the rotations and translations predicted from "
                          f"{stems[j]}{flagged}.")
        if notes is not None and notes[i]:
            entry.note = f"{notes[i][:1].upper()}{notes[i][1:]}. {entry.note}".strip()
        entries.append(entry)
    written.append(write_viewer(out_dir, entries, page, total=n))
    return written
