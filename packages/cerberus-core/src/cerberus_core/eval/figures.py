"""Pictures of reconstructions: Figure 1 (b)-(f) and Table 2 of the paper, and per-image outputs.

Every function renders with a backend from :func:`cerberus_core.make_renderer` through
:func:`cerberus_core.render_parts`, and takes the :class:`PartSet` and the input camera.
Cameras are look-at cameras aimed at the world origin (as the datasets render); new viewpoints keep
the input camera's elevation, distance and field of view and change the azimuth.

Figure 1 panels: (a) input, (b) 3D output, (c) parts in colours, (d) new lighting, (e) new viewpoint,
(f) new pose (the parts of this image with the rotations and translations predicted from another).
Table 2 columns: input, keypoints (each part's keypoint on the input, in its part colour: where the
translation head put it; :mod:`cerberus_core.eval.allocation`), any number of baselines, ours, parts, turn
(ours from another azimuth); the
figure ``cerberus eval`` writes adds the voxels the IoU scores, seen from the front and the side
(:func:`voxel_views`: hits grey, missed voxels red, off-body voxels blue). :func:`paired_plot` draws two or more
evaluations of one test set image by image (``cerberus compare --plot``), :func:`trade_plot` each one's voxel IoU
against its Hard Human IoU (``cerberus compare --trade-plot``).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from PIL import Image, ImageDraw
from tqdm import tqdm

from cerberus_core.errors import ConfigError, DatasetError, ShapeError
from cerberus_core.eval.allocation import keypoints
from cerberus_core.eval.compare import check_comparable, image_mean, image_pairs, paired_difference
from cerberus_core.eval.runner import collate, spread_evenly
from cerberus_core.eval.standard import Voxels, VoxelScorer
from cerberus_core.eval.viewer import CardDetails, ViewerPage, write_reconstruction_viewer
from cerberus_core.parts import PartSet, pose_donors, transfer_pose
from cerberus_core.plumbing.names import printable
from cerberus_core.render.api import render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.render.light import NEW_LIGHT_CAMERA_DIRECTION, Light
from cerberus_core.shapes import check_shapes
from cerberus_core.viz import (
    GRID_PAD,
    INK,
    atomic_save_png,
    chart_frame,
    draw_text,
    figure_font,
    image_grid,
    part_colors,
    text_width,
    to_uint8,
    wrap_text,
)

Tensor = torch.Tensor
RGB = tuple[float, float, float]

#: Uniform grey albedo of the datasets' bodies.
DEFAULT_ALBEDO: RGB = (0.8, 0.8, 0.8)
#: Figure background (the datasets render on white).
DEFAULT_BACKGROUND: RGB = (1.0, 1.0, 1.0)

# ------------------------------------------------------------------ lights
def camera_relative_light(camera: Camera, direction_cam: Sequence[float] = NEW_LIGHT_CAMERA_DIRECTION,
                          ambient: float = 0.25, diffuse: float = 0.75) -> Light:
    """Figure 1 (d)'s new light: white, given in each camera's frame (:meth:`Light.camera_relative`).

    Args:
        camera: the ``B`` cameras the light is given relative to.
        direction_cam: the direction *towards* the light in camera coordinates (+x right, +y up, +z towards the
            viewer; any length, normalised; default :data:`~cerberus_core.render.light.NEW_LIGHT_CAMERA_DIRECTION`:
            from the upper left, slightly in front).
        ambient, diffuse: the white light's ambient and directional intensities (unitless, per RGB channel: a
            surface gets ``albedo * (ambient + diffuse * max(0, n · direction))``).
    Returns:
        A :class:`Light` of ``B`` lights: ``direction`` ``(B, 3)`` unit vectors in world coordinates, ``ambient`` and
        ``diffuse`` ``(B, 3)``.
    """
    return Light.camera_relative(camera, direction_cam, ambient, diffuse)


# ------------------------------------------------------------------ renders
def render_reconstruction(renderer: Renderer, recon: PartSet, camera: Camera, *,
                          light: Light | None = None, parts: bool = False, albedo: RGB = DEFAULT_ALBEDO,
                          background: RGB = DEFAULT_BACKGROUND) -> Tensor:
    """``(B, 3, H, W)`` images of the posed parts: shaded grey, or each part in its colour (``parts``).

    The light defaults to the datasets' (white, following the camera, ambient 0.4, diffuse 0.6).
    """
    if recon.batch_size != camera.batch_size:
        raise ShapeError(f"render_reconstruction: {recon.batch_size} reconstructions but {camera.batch_size} cameras; "
                         "pass one camera per reconstruction")
    recon = recon.to(camera.device)
    alb = part_colors(recon.num_parts).to(camera.device) if parts else albedo
    with torch.no_grad():
        out = render_parts(renderer, recon.posed(), recon.faces, camera, light, albedo=alb, background=background)
    return out.image


def turntable(renderer: Renderer, recon: PartSet, camera: Camera, n_views: int = 8, *,
              parts: bool = False, background: RGB = DEFAULT_BACKGROUND) -> Tensor:
    """``(n_views, 3, H, W)``: one reconstruction seen from ``n_views`` azimuths evenly spaced from the
    input camera's, each lit by a light following that view."""
    if recon.batch_size != 1:
        raise ShapeError(f"turntable: expected one reconstruction, got {recon.batch_size}; pass `recon.index([i])`")
    if n_views < 1:
        raise ConfigError.about("n_views", n_views, "turntable: must be >= 1", "`n_views=1` or more")
    cams = camera.orbit([k * 360.0 / n_views for k in range(n_views)])
    many = recon.index([0] * n_views)
    return render_reconstruction(renderer, many, cams, parts=parts, background=background)


def relit(renderer: Renderer, recon: PartSet, camera: Camera, light: Light | None = None, *,
          background: RGB = DEFAULT_BACKGROUND) -> Tensor:
    """The reconstruction under a new light (default :func:`camera_relative_light`).

    Args:
        renderer: a backend; recon: ``B`` reconstructions (world frame); camera: their ``B`` cameras.
        light: the light (default :func:`camera_relative_light` of ``camera``); background: RGB in [0, 1].
    Returns:
        ``(B, 3, H, W)`` float images in [0, 1] (``H x W``: the camera's size), shaded grey, on the camera's device.
    """
    light = camera_relative_light(camera) if light is None else light
    return render_reconstruction(renderer, recon, camera, light=light, background=background)


def reposed(renderer: Renderer, shapes: PartSet, poses: PartSet, camera: Camera, *,
            parts: bool = False, background: RGB = DEFAULT_BACKGROUND) -> Tensor:
    """The parts of ``shapes`` with the rotations and translations of ``poses`` (Figure 1 (f)).

    Args:
        renderer: a backend; shapes: the reconstructions whose part shapes are shown (batch ``B``, or 1 for all);
            poses: the ``B`` reconstructions whose rotations and translations pose them (:func:`transfer_pose`);
            camera: ``B`` cameras.
        parts: each part in its colour (:func:`cerberus_core.viz.part_colors`) instead of shaded grey.
    Returns:
        ``(B, 3, H, W)`` float images in [0, 1] (``H x W``: the camera's size), on the camera's device.
    """
    return render_reconstruction(renderer, transfer_pose(shapes, poses), camera, parts=parts, background=background)


# ------------------------------------------------------------------ files
def save_png(image: Image.Image | Tensor, path: str | Path) -> Path:
    """Write a PIL image or a ``(3, H, W)`` tensor in [0, 1] as PNG, atomically."""
    if isinstance(image, Tensor):
        image = Image.fromarray(to_uint8(image[None])[0])
    return atomic_save_png(image, path)


# ------------------------------------------------------------------ Figure 1
FIGURE_ONE_TITLES = {"input": "(a) Input", "output": "(b) 3D Output", "parts": "(c) Parts",
                     "new_lighting": "(d) New Lighting", "new_viewpoint": "(e) New Viewpoint",
                     "new_pose": "(f) New Pose"}


def figure_one_panels(renderer: Renderer, image: Tensor, recon: PartSet, camera: Camera, *,
                      pose_donor: PartSet | None = None, view_offset_deg: float = 90.0,
                      light: Light | None = None, background: RGB = DEFAULT_BACKGROUND) -> dict[str, Tensor]:
    """The panels of Figure 1 for one image, each ``(3, H, W)``.

    Args:
        image: ``(3, H, W)`` the input.
        recon, camera: its reconstruction and camera (batch 1).
        pose_donor: a reconstruction (batch 1) of another image whose rotations and translations give
            the new pose; without it the ``new_pose`` panel is left out.
        view_offset_deg: azimuth change of the new viewpoint.
        light: the new light (default :func:`camera_relative_light`).
    """
    if recon.batch_size != 1 or camera.batch_size != 1:
        raise ShapeError("figure_one_panels: expected one reconstruction and one camera; pass `recon.index([i])` and "
                         "`camera.index([i])`")
    panels = {
        "input": image.detach().float().cpu().clamp(0, 1),
        "output": render_reconstruction(renderer, recon, camera, background=background)[0],
        "parts": render_reconstruction(renderer, recon, camera, parts=True, background=background)[0],
        "new_lighting": relit(renderer, recon, camera, light, background=background)[0],
        "new_viewpoint": render_reconstruction(renderer, recon, camera.orbit([view_offset_deg]),
                                               background=background)[0],
    }
    if pose_donor is not None:
        panels["new_pose"] = reposed(renderer, recon, pose_donor, camera, parts=True, background=background)[0]
    return {k: v.cpu() for k, v in panels.items()}


def note_banner(text: str, width: int) -> Image.Image:
    """``text`` in dark red on white, wrapped to ``width`` pixels (a warning above a figure)."""
    font = figure_font(11)
    lines = wrap_text(text, font, width - 2 * GRID_PAD)
    out = Image.new("RGB", (width, 14 * len(lines) + GRID_PAD), "white")
    draw = ImageDraw.Draw(out)
    for k, text_line in enumerate(lines):
        draw_text(draw, (GRID_PAD, GRID_PAD // 2 + 14 * k), text_line, font=font, fill=(160, 0, 0))
    return out


def figure_one(panels: Mapping[str, Tensor], scale: int = 2, columns: int = 3, note: str = "") -> Image.Image:
    """Lay the panels of :func:`figure_one_panels` out in rows of ``columns`` with captions above, and
    ``note`` (e.g. that the input is out of the training domain) in red above them all."""
    keys = [k for k in FIGURE_ONE_TITLES if k in panels]
    rows = [keys[i:i + columns] for i in range(0, len(keys), columns)]
    images = [image_grid([[panels[k] for k in row]], column_titles=[FIGURE_ONE_TITLES[k] for k in row],
                         scale=scale) for row in rows]
    if note:
        images.insert(0, note_banner(note, max(im.width for im in images)))
    width = max(im.width for im in images)
    out = Image.new("RGB", (width, sum(im.height for im in images)), "white")
    y = 0
    for im in images:
        out.paste(im, (0, y))
        y += im.height
    return out


# ------------------------------------------------------------------ Table 2
def draw_keypoints(images: Tensor, points: Tensor) -> Tensor:
    """Mark points on images, point ``k`` in part colour ``k`` (:func:`cerberus_core.viz.part_colors`).

    Args:
        images: ``(N, 3, H, W)`` in [0, 1]; points: ``(N, P, 2)`` pixel coordinates ``(u, v)`` (centres at
            ``j + 0.5``, :func:`~cerberus_core.eval.allocation.keypoints`).
    Returns:
        ``(N, 3, H, W)`` a copy with a 5-pixel cross at each point that lies in the image (its arms
        clipped at the border), later parts drawn over earlier ones.

    Example:
        >>> out = draw_keypoints(torch.zeros(1, 3, 8, 8), torch.tensor([[[2.5, 5.5]]]))
        >>> out[0, :, 5, 2].tolist() == part_colors(1)[0].tolist(), int(out[0, 0].gt(0).sum())
        (True, 5)
    """
    check_shapes("draw_keypoints", images=(images, "N 3 H W"), points=(points, "N P 2"))
    out = images.detach().float().cpu().clone()
    h, w = out.shape[-2:]
    colours = part_colors(points.shape[1])
    cells = points.detach().float().cpu().floor()
    for n in range(out.shape[0]):
        for k in range(points.shape[1]):
            col, row = cells[n, k].tolist()
            if not (0 <= col < w and 0 <= row < h):
                continue
            for dc, dr in ((0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)):
                c, r = int(col) + dc, int(row) + dr
                if 0 <= c < w and 0 <= r < h:
                    out[n, :, r, c] = colours[k]
    return out


def table2_rows(renderer: Renderer, images: Tensor, camera: Camera, ours: PartSet,
                baselines: Mapping[str, PartSet] | None = None, *, turn_deg: float = 90.0,
                background: RGB = DEFAULT_BACKGROUND) -> tuple[list[str], list[list[Tensor]]]:
    """The cells of a Table-2 figure: for each image, input | keypoints | baselines... | ours | parts | turn.

    Args:
        images: ``(N, 3, H, W)`` inputs; camera: their ``N`` cameras.
        ours: our reconstructions (batch ``N``).
        baselines: ``{name: reconstruction (batch N)}`` of other models; a single-mesh model is a
            one-part reconstruction (:meth:`PartSet.from_posed`). Rendered shaded grey.
        turn_deg: azimuth change of the "Turn" column.
    Returns:
        ``(column titles, rows of (3, H, W) cells)``, for :func:`~cerberus_core.viz.image_grid`
        (:func:`evaluation_figures` adds two columns of voxels).
    """
    baselines = dict(baselines or {})
    n = images.shape[0]
    for name, rec in [("ours", ours), *baselines.items()]:
        if rec.batch_size != n:
            raise ShapeError(f"table2_rows: {name} has {rec.batch_size} reconstructions for {n} images; pass one "
                             "reconstruction per image for every baseline")
    columns = {"Input": images.detach().float().cpu().clamp(0, 1)}
    columns["Keypoints"] = draw_keypoints(columns["Input"], keypoints(ours, camera))
    for name, rec in baselines.items():
        columns[name] = render_reconstruction(renderer, rec, camera, background=background).cpu()
    columns["Ours"] = render_reconstruction(renderer, ours, camera, background=background).cpu()
    columns["Parts"] = render_reconstruction(renderer, ours, camera, parts=True, background=background).cpu()
    turned = Camera.cat([camera.index([i]).orbit([turn_deg]) for i in range(n)])
    columns["Turn"] = render_reconstruction(renderer, ours, turned, background=background).cpu()
    titles = list(columns)
    return titles, [[columns[t][i] for t in titles] for i in range(n)]


# ------------------------------------------------------------------ voxels: hits, missed, off the body
#: Colours of :func:`voxel_views`, in the order that breaks ties: voxels both have, only the prediction
#: has (off the body), only the ground truth has (missed); a later one wins a tie.
VOXEL_COLOURS: dict[str, RGB] = {"hit": (0.7, 0.7, 0.7), "off-body": (0.15, 0.4, 0.95), "missed": (0.9, 0.1, 0.1)}


def voxel_views(voxels: Voxels, size: int, background: RGB = DEFAULT_BACKGROUND) -> Tensor:
    """The voxels of one score in two orthographic views: front (seen from +z, the way the body faces at
    azimuth 0: x to the right, y up) and side (seen from +x: z to the left, y up).

    A pixel shows a line of voxels in the colour of the kind most of them are (:data:`VOXEL_COLOURS`:
    grey hit, blue off the body (prediction only), red missed (ground truth only); a tie goes to
    missed, then off-body), or the background where the line is empty: a forearm the prediction
    misses is a red limb beside a grey trunk.

    Args:
        voxels: :meth:`~cerberus_core.eval.standard.VoxelScorer.voxels` of one image.
        size: output side in pixels (the lattice box is padded to a square, then scaled by nearest).
    Returns:
        ``(2, 3, size, size)`` images in [0, 1]: front, side.
    """
    pred, gt = voxels.union, voxels.gt
    kinds = [pred & gt, pred & ~gt, gt & ~pred]  # the order of VOXEL_COLOURS
    palette = torch.tensor([background, *VOXEL_COLOURS.values()], dtype=torch.float32)  # (4, 3)
    views = []
    for axis, orient in ((2, lambda a: a.T[::-1]), (0, lambda a: a[::-1, ::-1])):  # (X, Y) → rows y, cols x;
        counts = np.stack([orient(k.sum(axis=axis)) for k in kinds])  # (Y, Z) → rows y, cols -z
        winner = (counts.shape[0] - 1 - counts[::-1].argmax(0)) + 1  # last of the largest: ties to missed
        winner[counts.sum(0) == 0] = 0
        side = max(winner.shape)
        index = np.zeros((side, side), np.int64)
        top, left = (side - winner.shape[0]) // 2, (side - winner.shape[1]) // 2
        index[top:top + winner.shape[0], left:left + winner.shape[1]] = winner
        image = palette[torch.from_numpy(index)].permute(2, 0, 1)
        views.append(torch.nn.functional.interpolate(image[None], size=(size, size), mode="nearest")[0])
    return torch.stack(views)


def voxel_legend(width: int) -> Image.Image:
    """A one-line key to :data:`VOXEL_COLOURS`, ``width`` pixels wide."""
    font = figure_font(11)
    out = Image.new("RGB", (width, 16 + GRID_PAD), "white")
    draw = ImageDraw.Draw(out)
    x = GRID_PAD
    labels = {"hit": "voxels both have", "missed": "missed (ground truth only)",
              "off-body": "off the body (prediction only)"}
    for kind in ("hit", "missed", "off-body"):
        draw.rectangle((x, GRID_PAD, x + 10, GRID_PAD + 10), fill=tuple(round(255 * c) for c in VOXEL_COLOURS[kind]))
        draw_text(draw, (x + 14, GRID_PAD - 1), labels[kind], font=font, fill=(0, 0, 0))
        x += 14 + int(text_width(labels[kind], font)) + 3 * GRID_PAD
    return out


# ------------------------------------------------------------------ one image, every picture
@dataclass(frozen=True)
class PictureStyle:
    """How the pictures of a reconstruction are drawn (:func:`save_image_pictures`).

    Attributes:
        renderer: the backend.
        background: RGB in [0, 1] behind the renders.
        scale: the upscaling of the turntable and Figure 1 (single panels are ``H x W`` pixels).
        n_views: azimuths of the turntable.
    """

    renderer: Renderer
    background: RGB = DEFAULT_BACKGROUND
    scale: int = 2
    n_views: int = 8


def save_image_pictures(style: PictureStyle, image: Tensor, recon: PartSet, camera: Camera, out_dir: str | Path,
                        stem: str, *, pose_donor: PartSet | None = None, note: str = "") -> list[Path]:
    """Every picture of one reconstruction, as PNGs named ``<stem>_<what>.png`` in ``out_dir``.

    Writes ``input``, ``reconstruction``, ``parts``, ``new_lighting``, ``turntable`` (two rows of
    ``style.n_views`` azimuths: shaded and parts), ``new_pose`` (if ``pose_donor`` is given) and ``figure1``
    (all panels together, ``note`` in red above them). Single panels are ``H x W`` pixels; the others
    are upscaled by ``style.scale``.
    """
    renderer, background, scale, n_views = style.renderer, style.background, style.scale, style.n_views
    panels = figure_one_panels(renderer, image, recon, camera, pose_donor=pose_donor, background=background)
    out_dir = Path(out_dir)
    names = {"input": "input", "output": "reconstruction", "parts": "parts", "new_lighting": "new_lighting",
             "new_pose": "new_pose"}
    written = [save_png(panels[k], out_dir / f"{stem}_{v}.png") for k, v in names.items() if k in panels]
    shaded = turntable(renderer, recon, camera, n_views, background=background).cpu()
    coloured = turntable(renderer, recon, camera, n_views, parts=True, background=background).cpu()
    titles = [f"{round(k * 360 / n_views)}°" for k in range(n_views)]
    grid = image_grid([shaded, coloured], column_titles=titles, row_titles=["shaded", "parts"], scale=scale)
    written.append(save_png(grid, out_dir / f"{stem}_turntable.png"))
    written.append(save_png(figure_one(panels, scale=scale, note=note), out_dir / f"{stem}_figure1.png"))
    return written



@dataclass(frozen=True)
class FigureModels:
    """The models a figure shows (:func:`evaluation_figures`).

    Attributes:
        ours: an object with ``reconstruct(images, camera) -> PartSet`` (a :class:`~cerberus_core.model.Cerberus`).
        baselines: more such objects by name, drawn beside ours.
        device: where they run.
        progress: show a progress bar over the pictured images while their pictures are drawn (the slow part:
            Figure 1's panels and two turntables per image).
    """

    ours: object
    baselines: Mapping[str, object] = field(default_factory=dict)
    device: str | torch.device = "cpu"
    progress: bool = False


def evaluation_figures(renderer: Renderer, dataset, models: FigureModels, out: Path, *, n_images: int = 5,
                       scorer: VoxelScorer | None = None, page: ViewerPage | None = None,
                       ious: Mapping[int, float] | None = None) -> Path:
    """The pictures ``cerberus eval`` writes for ``n_images`` test images spread over ``dataset``: the
    Table-2 figure ``out/table2.png`` (with two more columns: our voxels seen from the front and the
    side, :func:`voxel_views`, under a key), Figure 1's panels per image in ``out/pictures/``, and the
    interactive viewer ``out/pictures/index.html`` with the reconstruction, ground-truth and new-pose
    meshes of the first ``page.limit`` (0: none).

    Args:
        models: ours, the baselines and their device (:class:`FigureModels`).
        scorer: the voxels' scorer (default ``VoxelScorer()``: the paper's protocol).
        page: the viewer's title, number of images (``limit``, 0: none) and part labels (:class:`ViewerPage`;
            its background is the dataset's).
        ious: ``{dataset index: voxel IoU}`` the evaluation computed
            (:meth:`~cerberus_core.eval.runner.EvaluationResult.image_ious`), shown on the viewer's cards; the
            pictured images are spread over these images (default: over the whole dataset), so each card has one.
    Returns:
        The path of the Table-2 figure.
    """
    out = Path(out)
    scored = sorted(ious) if ious else list(range(len(dataset)))
    n = min(n_images, len(scored))
    idx = [scored[k] for k in spread_evenly(len(scored), n)]
    batch = collate([dataset[i] for i in idx])
    camera = dataset.cameras(batch)
    images = batch["images"]
    dev_images, dev_camera = images.to(models.device), camera.to(models.device)
    with torch.no_grad():
        ours = models.ours.reconstruct(dev_images, dev_camera).to("cpu")
        others = {name: other.reconstruct(dev_images, dev_camera).to("cpu") for name, other in models.baselines.items()}
    background = tuple(dataset.scene.background)
    titles, rows = table2_rows(renderer, images, camera, ours, others, background=background)
    bodies = [dataset.gt_mesh(i) for i in idx]
    scorer = scorer or VoxelScorer()
    for k, (row, body) in enumerate(zip(rows, bodies, strict=True)):
        row.extend(voxel_views(scorer.voxels(ours.index([k]).part_meshes(0), (body.vertices, body.faces)),
                               images.shape[-1]))
    grid = image_grid(rows, column_titles=[*titles, "Voxels: front", "Voxels: side"], scale=2)
    legend = voxel_legend(grid.width)
    fig = Image.new("RGB", (grid.width, grid.height + legend.height), "white")
    fig.paste(grid, (0, 0))
    fig.paste(legend, (0, grid.height))
    stems = [f"test_{i:05d}" for i in idx]
    donors = pose_donors(len(stems))  # test images are in the training domain: each borrows the next one's pose
    bar = tqdm(stems, desc="figures", unit="img", disable=not models.progress)
    for k, stem in enumerate(bar):  # Figure 1 (b)-(f) per image
        donor = None if donors[k] is None else ours.index([donors[k]])
        save_image_pictures(PictureStyle(renderer, background), images[k], ours.index([k]), camera.index([k]),
                            out / "pictures", stem, pose_donor=donor)
    page = replace(page or ViewerPage(title="cerberus eval"), background=background)
    write_reconstruction_viewer(out / "pictures", images, ours, camera, stems, page,
                                CardDetails(bodies=bodies, ious=[(ious or {}).get(i) for i in idx]))
    return save_png(fig, out / "table2.png")


def paired_plot(evaluations: Mapping[str, Mapping[str, Any]], path: str | Path, key: str = "iou",
                size: tuple[int, int] = (560, 560)) -> Path:
    """Each image's ``key`` (voxel IoU) of every evaluation (up) against the first's (across): points above the
    diagonal are images the evaluation scores better; one colour per evaluation, its paired difference in the
    legend. Written atomically as a PNG.

    Args:
        evaluations: ``{name: results.json dict}``, the baseline first (at least two); the images are paired as
            ``cerberus compare``'s table pairs them (:func:`~cerberus_core.eval.compare.image_pairs`).
        path: the PNG to write.
        key: the per-image value of the records (``"iou"``, ``"hard_iou"``...).
    Returns:
        ``path``.

    Raises:
        DatasetError: fewer than two evaluations, two that scored different images under one index (different
            test sets), or evaluations measured under different settings (an
            :class:`~cerberus_core.errors.IncomparableEvaluationsError`:
            :func:`~cerberus_core.eval.compare.check_comparable`); nothing is written then.
    """
    names = list(evaluations)
    if len(names) < 2:
        raise DatasetError(f"a paired plot needs two evaluations or more, got {len(names)}; pass the baseline first")
    check_comparable(evaluations)
    base = evaluations[names[0]]
    pairs = {name: image_pairs(evaluations[name], base, key) for name in names[1:]}  # (its, base's): as the table
    values = [v for points in pairs.values() for xy in points for v in xy]
    lo, hi = (math.floor(min(values) * 10) / 10, math.ceil(max(values) * 10) / 10) if values else (0.0, 1.0)
    hi = hi if hi > lo else lo + 0.1
    legend = 16 * (len(names) - 1)
    chart = chart_frame((size[0], size[1] + legend), margins=(48, 16, 16 + legend, 40), x_range=(lo, hi),
                        y_range=(lo, hi))
    ticks = [lo + k * 0.1 for k in range(round((hi - lo) / 0.1) + 1)]
    chart.grid_x(ticks, "{:.1f}".format)
    chart.grid_y(ticks, "{:.1f}".format)
    chart.draw.line([chart.x_px(lo), chart.y_px(lo), chart.x_px(hi), chart.y_px(hi)], fill=INK)
    what = "voxel IoU" if key == "iou" else key
    chart.axis_titles(x=f"{printable(names[0])}: {what} per image", y=f"the others' {what} (above the line: better)")
    colors = [tuple(int(200 * c) for c in rgb) for rgb in part_colors(len(names) - 1).tolist()]
    font = figure_font(11)
    for i, (name, points) in enumerate(pairs.items()):
        for y, x in points:  # the base's value across, its own up
            px, py = chart.x_px(x), chart.y_px(y)
            chart.draw.rectangle([px - 1, py - 1, px + 1, py + 1], fill=colors[i])
        d = paired_difference(evaluations[name], base, key)
        draw_text(chart.draw, (chart.left, 4 + 16 * i), f"{printable(name)}: "
                  f"{d if d is not None else 'fewer than 2 images in common'}", font=font, fill=colors[i])
    return chart.save(path)


#: The steps :func:`trade_plot` may put its grid lines at (data units: voxel IoU): the finest that leaves ten
#: lines or fewer.
TRADE_GRID_STEPS = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)

#: The colour of :func:`trade_plot`'s points (RGB).
TRADE_POINT = (31, 119, 180)


def _grid_around(values: Sequence[float]) -> tuple[float, float, float]:
    """``(low, high, step)``: the grid of :data:`TRADE_GRID_STEPS` around ``values``, one step of margin on
    each side of them, with at most ten steps (the last step's where none fits)."""
    for step in TRADE_GRID_STEPS:
        low, high = (math.floor(min(values) / step) - 1) * step, (math.ceil(max(values) / step) + 1) * step
        if round((high - low) / step) <= 10:
            break
    return low, high, step


def trade_plot(evaluations: Mapping[str, Mapping[str, Any]], path: str | Path,
               size: tuple[int, int] = (620, 460)) -> Path:
    """Each evaluation's mean voxel IoU (across) against its mean Hard Human IoU (up), one labelled point each: the
    trade between fitting each image and parts that hold across poses (``cerberus compare --trade-plot``). Written
    atomically as a PNG.

    Args:
        evaluations: ``{name: results.json dict}``; the means are over each one's images
            (:func:`~cerberus_core.eval.compare.image_mean` of ``iou`` and ``hard_iou``, the columns of
            :func:`~cerberus_core.eval.compare.comparison_rows`); one without Hard Human is left out.
        path: the PNG to write.
        size: ``(width, height)`` of the picture, px.
    Returns:
        ``path``.

    Raises:
        DatasetError: no evaluation has both values; nothing is written then.
    """
    points = {name: (x, y) for name, e in evaluations.items()
              if (x := image_mean(e, "iou")) is not None and (y := image_mean(e, "hard_iou")) is not None}
    if not points:
        raise DatasetError(f"no evaluation ({', '.join(map(printable, evaluations))}) has both a voxel IoU and a "
                           "Hard Human IoU per image ('iou' and 'hard_iou' of its records), so there is no trade to "
                           "draw; Hard Human is scored on data with each subject's canonical pose")
    x0, x1, x_step = _grid_around([x for x, _ in points.values()])
    y0, y1, y_step = _grid_around([y for _, y in points.values()])
    chart = chart_frame(size, margins=(56, 20, 20, 44), x_range=(x0, x1), y_range=(y0, y1))
    chart.grid_x([x0 + k * x_step for k in range(round((x1 - x0) / x_step) + 1)], "{:.2f}".format)
    chart.grid_y([y0 + k * y_step for k in range(round((y1 - y0) / y_step) + 1)], "{:.2f}".format)
    chart.axis_titles(x="voxel IoU (mean over the test images)", y="Hard Human IoU (one set of parts per subject)")
    font = figure_font(10)
    for name, (x, y) in points.items():
        px, py = chart.x_px(x), chart.y_px(y)
        chart.draw.ellipse([px - 4, py - 4, px + 4, py + 4], fill=TRADE_POINT)
        draw_text(chart.draw, (px + 7, py - 6), printable(name), font=font, fill=INK)
    return chart.save(path)
