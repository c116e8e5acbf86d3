"""Contact sheets of a dataset split: quadruplets (training) or the views of each pose (test), with
optionally the ground-truth parts rendered in colour beside them."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from PIL import Image

from cerberus_core.datasets.manifest import Manifest
from cerberus_core.datasets.readers import QuadrupletDataset, ViewDataset
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.errors import DatasetError
from cerberus_core.plumbing.outputs import output_file
from cerberus_core.render.api import render
from cerberus_core.render.backends import make_renderer
from cerberus_core.viz import atomic_save_png, image_grid, part_colors

Tensor = torch.Tensor


def _parts_image(views: ViewDataset, index: int, scene: SceneSetup, renderer) -> Tensor:
    """``(1, 3, H, W)``: the ground-truth body of image ``index`` coloured by part, same camera."""
    body = views.gt_mesh(index)
    rec = views.records[index]
    camera = scene.view_cameras(rec, views.image_size)
    colours = part_colors(max(len(views.part_names), 1))[torch.as_tensor(body.vertex_parts.astype(np.int64))]
    out = render(renderer, torch.as_tensor(body.vertices)[None], torch.as_tensor(body.faces), camera,
                 scene.light(camera), albedo=colours[None], background=scene.background)
    return out.image


def _evenly(n_items: int, count: int) -> list[int]:
    if n_items <= count:
        return list(range(n_items))
    return [int(round(x)) for x in np.linspace(0, n_items - 1, count)]


TITLE_CHARS = 14
"""The longest row title kept whole: 14 characters fit :func:`~cerberus_core.viz.image_grid`'s row-title column
at 11 px; a longer one names the quadruplet instead."""


def contact_sheet(views: ViewDataset, quads: QuadrupletDataset | None = None, *, count: int = 8,
                  parts: bool = False, renderer: str = "auto", scale: int = 2) -> Image.Image:
    """A picture of ``count`` rows of a split (its readers, from
    :meth:`Dataset.views <cerberus_core.datasets.dataset.Dataset.views>` and :meth:`~Dataset.quadruplets`).

    Rows are quadruplets ``a0 a1 b0 b1`` when the split has quadruplets (``quads``), else the views of one pose
    (canonical poses first). With ``parts``, each row ends with the ground-truth parts of its first
    pose (and, for quadruplets, of its second pose) rendered in colour from the same camera.

    Args:
        views, quads: the split's views, and its quadruplets (``None``: a split of single views).
        count: number of rows (spread evenly over the split).
        parts: add ground-truth part renderings (needs the split's meshes, or its body source).
        renderer: backend for the part renderings.
        scale: nearest-neighbour upscaling of every tile.
    """
    scene = views.scene
    rend = make_renderer(renderer) if parts else None
    rows, titles = [], []
    if quads is not None:
        for i in _evenly(len(quads), count):
            item = quads[i]
            row = [item["images"]]
            if parts:
                quad = quads.view_indices(i)
                row += [_parts_image(views, int(quad[0]), scene, rend), _parts_image(views, int(quad[2]), scene, rend)]
            rows.append(torch.cat(row))
            p = item["pose"]
            title = f"s{int(item['subject'])} {int(p[0])}/{int(p[2])}"
            # Motion pairs number their poses with 10-digit ids that do not fit a tile: name the quadruplet.
            titles.append(title if len(title) <= TITLE_CHARS else f"s{int(item['subject'])} quad {i}")
    else:
        rec = views.records
        keys = np.stack([~rec["canonical"], rec["subject"], rec["pose"]], 1)
        _, first = np.unique(keys, axis=0, return_index=True)
        for g in _evenly(len(first), count):
            start = int(first[g])
            sel = np.flatnonzero((rec["subject"] == rec["subject"][start]) & (rec["pose"] == rec["pose"][start]))
            row = [torch.stack([views[int(j)]["images"] for j in sel])]
            if parts:
                row.append(_parts_image(views, int(sel[0]), scene, rend))
            rows.append(torch.cat(row))
            prefix = "c " if rec["canonical"][start] else ""
            titles.append(f"{prefix}s{int(rec['subject'][start])} p{int(rec['pose'][start])}")
    if not rows:
        raise DatasetError(f"{views.root}: split {views.split!r} has no finished shard to show yet; let its "
                           "generation finish a shard first")
    return image_grid(rows, row_titles=titles, scale=scale)


def save_contact_sheet(views: ViewDataset, out: str | Path, manifest: Manifest, **options) -> Path:
    """:func:`contact_sheet` written atomically as a PNG (``out`` may not be a file of the dataset, which
    ``manifest`` lists)."""
    output_file(Path(out), "out", [manifest.path, *(manifest.root / f.path for split in manifest.splits.values()
                                                     for shard in split.shards for f in shard.files.values())])
    atomic_save_png(contact_sheet(views, **options), out)
    return Path(out)
