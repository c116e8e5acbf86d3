"""Training logs: scalar CSV (always), TensorBoard events (when installed), PNG grids, loss curves.

Files in the run folder::

    RUN/metrics.csv            one row per logged step (step, lr, steps/s, skipped, loss terms; the
                               allocation columns at ``train.allocation_every``)
    RUN/tensorboard/           TensorBoard event files (if the ``tensorboard`` package is importable),
                               with every part's and segment's allocation number under ``allocation/``
    RUN/images/step_XXXXXXX.png  inputs / reconstructions / parts in colour, at ``train.image_every``
    RUN/loss_curves.png        every loss term against the step (log scale), written at the end

``metrics.csv`` is read back, without torch, by :mod:`cerberus_core.plumbing.metrics_csv` (its rows, and the
training time summed over the sittings of a resumed run: ``training_time``).
"""
from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path

import torch

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.eval.allocation import Allocation
from cerberus_core.eval.runner import batch_result, collate
from cerberus_core.eval.standard import GroundTruthMemo
from cerberus_core.plumbing.atomic import atomic_write_text
from cerberus_core.plumbing.metrics_csv import METRICS_CSV, read_rows
from cerberus_core.render.api import render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.train.objective import TERMS
from cerberus_core.viz import atomic_save_png, chart_frame, draw_text, figure_font, image_grid, part_colors

Tensor = torch.Tensor

LOSS_FIELDS = ("total", *TERMS)
ALLOCATION_FIELDS = ("keypoint_spread_max", "keypoint_spread_top4", "segment_to_keypoint_max",
                     "segment_to_keypoint_mean", "low_coverage_parts")
"""The allocation columns of ``metrics.csv`` (:class:`AllocationProbe`): the largest keypoint spread and the
mean of the four largest (px), the largest and the mean over segments of the median distance to the nearest
keypoint (px), and how many parts alone cover at most 2 % of the foreground."""
CSV_FIELDS = ("step", "elapsed_s", "lr", "steps_per_s", "grad_norm", "skipped", *LOSS_FIELDS, *ALLOCATION_FIELDS)


class MetricsLog:
    """Scalar logs of rank 0.

    Args:
        run_dir: the run folder.
        start_step: steps already done. Rows logged after ``start_step`` by an interrupted run are
            dropped, so a resumed run's CSV has no duplicates.
        tensorboard: also write TensorBoard events if the package is importable.
    """

    def __init__(self, run_dir: str | Path, start_step: int = 0, tensorboard: bool = True) -> None:
        self.path = Path(run_dir) / METRICS_CSV
        rows = [r for r in read_rows(self.path) if start_step > 0 and int(r["step"]) <= start_step]
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=CSV_FIELDS)
        writer.writeheader()
        writer.writerows({k: r.get(k, "") for k in CSV_FIELDS} for r in rows)
        atomic_write_text(self.path, buf.getvalue())
        self._file = self.path.open("a", newline="")
        self._csv = csv.DictWriter(self._file, fieldnames=CSV_FIELDS)
        self.tb = None
        if tensorboard:
            try:
                from torch.utils.tensorboard import SummaryWriter
            except ImportError:  # tensorboard not installed: CSV only
                SummaryWriter = None
            if SummaryWriter is not None:
                self.tb = SummaryWriter(str(Path(run_dir) / "tensorboard"), purge_step=start_step + 1)

    def log(self, step: int, values: dict[str, float]) -> None:
        """Append one row (missing fields stay empty) and the same scalars to TensorBoard."""
        row = {k: "" for k in CSV_FIELDS} | {k: v for k, v in values.items() if k in CSV_FIELDS} | {"step": step}
        self._csv.writerow(row)
        self._file.flush()
        if self.tb is not None:
            for k, v in values.items():
                if k != "step":  # a name with its own group ("allocation/...") keeps it
                    self.tb.add_scalar(k if "/" in k else f"{'loss' if k in LOSS_FIELDS else 'train'}/{k}", v, step)

    def close(self) -> None:
        self._file.close()
        if self.tb is not None:
            self.tb.close()


class AllocationProbe:
    """The allocation diagnostics of ``cerberus eval`` (:mod:`cerberus_core.eval.allocation`, the same
    code) on a fixed batch of test views, for the training logs.

    Args:
        views: a :class:`~cerberus_core.datasets.readers.ViewDataset` with ground truth.
        renderer: the backend that renders the parts and the ground truth.
        count: views in the batch, spread evenly over ``views``.
    """

    def __init__(self, views, renderer: Renderer, count: int = 16) -> None:
        self.views, self.renderer = views, renderer
        self.indices = torch.linspace(0, len(views) - 1, min(count, len(views))).round().long().unique().tolist()
        self.batch = collate([views[i] for i in self.indices])
        self.camera = views.cameras(self.batch)
        self.memo = GroundTruthMemo(views.gt_mesh, size=len(self.indices))  # every body kept

    @classmethod
    def for_data(cls, root: str | Path, renderer: Renderer, split: str = "test", count: int = 16) -> AllocationProbe | None:
        """The probe on ``split`` of the dataset at ``root``; ``None`` when there is no such dataset or
        split with views (the diagnostics need each view's ground-truth body)."""
        if not Dataset.is_dataset(root):
            return None
        data = Dataset.open(root)
        record = data.manifest.splits.get(split)
        if record is None or not record.shards:
            return None
        views = data.views(split, allow_partial=True)
        return cls(views, renderer, count) if len(views) else None

    @torch.no_grad()
    def measure(self, model: torch.nn.Module) -> dict[str, float]:
        """Run ``model`` (its ``reconstruct``, in eval mode, restored after) on the batch: the
        :data:`ALLOCATION_FIELDS` and, for TensorBoard, every part's and segment's number under
        ``allocation/``."""
        device = next(model.parameters()).device
        was_training = model.training
        model.eval()
        try:
            camera = self.camera.to(device)
            recon = model.reconstruct(self.batch["images"].to(device), camera).detach().to("cpu")
        finally:
            model.train(was_training)
        allocation = Allocation(self.renderer)
        allocation.update(batch_result(self.views, self.batch, self.indices, recon, camera, self.memo))
        s = allocation.summary()
        spread = sorted(s["keypoint_spread"], reverse=True)
        far = [v for v in s["segment_to_keypoint"].values() if math.isfinite(v)]
        out = {"keypoint_spread_max": spread[0], "keypoint_spread_top4": sum(spread[:4]) / len(spread[:4]),
               "segment_to_keypoint_max": max(far, default=math.nan),
               "segment_to_keypoint_mean": sum(far) / len(far) if far else math.nan,
               "low_coverage_parts": float(len(s["low_coverage_parts"]))}
        out |= {f"allocation/keypoint_spread/part_{p:02d}": v for p, v in enumerate(s["keypoint_spread"])}
        out |= {f"allocation/unique_coverage/part_{p:02d}": v for p, v in enumerate(s["unique_coverage"])}
        out |= {f"allocation/segment_to_keypoint/{k}": v for k, v in s["segment_to_keypoint"].items()}
        return out


@torch.no_grad()
def save_progress_grid(path: str | Path, renderer: Renderer, images: Tensor, renders: Tensor, parts: Tensor,
                       faces: Tensor, camera: Camera, scene: SceneSetup, max_images: int = 8) -> Path:
    """Write a PNG: input images, their reconstructions, and the parts in distinct colours.

    Args:
        images, renders: ``(K, 3, H, W)`` inputs and own-viewpoint renderings.
        parts: ``(K, N, V, 3)`` world-space parts; ``camera``: their ``K`` cameras.
    """
    k = min(max_images, images.shape[0])
    cam = camera.index(slice(0, k))
    colours = part_colors(parts.shape[1]).to(parts.device)
    coloured = render_parts(renderer, parts[:k], faces, cam, scene.light(cam), albedo=colours,
                            background=scene.background).image
    scale = max(1, 128 // images.shape[-1])
    grid = image_grid([images[:k], renders[:k], coloured], row_titles=["input", "recon", "parts"], scale=scale)
    return atomic_save_png(grid, path)


def plot_loss_curves(csv_path: str | Path, png_path: str | Path,
                     terms: Sequence[str] = LOSS_FIELDS,
                     size: tuple[int, int] = (720, 420)) -> Path:
    """Draw every loss term of ``metrics.csv`` against the step, log-scaled, with PIL."""
    rows = read_rows(csv_path)
    series = {}
    for t in terms:
        pts = [(int(r["step"]), float(r[t])) for r in rows if r.get(t) not in (None, "")]
        pts = [(s, v) for s, v in pts if math.isfinite(v) and v > 0]
        if pts:
            series[t] = pts
    margins = (70, 130, 20, 40)  # left, right, top, bottom (px); the legend fills the right margin
    if not series:
        chart = chart_frame(size, margins=margins)
        draw_text(chart.draw, (chart.left + 10, chart.top + 10), "no finite losses logged", font=figure_font(10),
                  fill=(0, 0, 0))
        return chart.save(png_path)
    steps = [s for pts in series.values() for s, _ in pts]
    logs = [math.log10(v) for pts in series.values() for _, v in pts]
    s0, s1 = min(steps), max(max(steps), min(steps) + 1)
    y0, y1 = math.floor(min(logs)), math.ceil(max(logs))
    y1 = max(y1, y0 + 1)
    chart = chart_frame(size, margins=margins, x_range=(s0, s1), y_range=(y0, y1))  # y: log10 of the loss
    chart.grid_y(range(y0, y1 + 1), "1e{}".format, fill=(225, 225, 225))  # decade grid lines
    chart.grid_x([s0 + frac * (s1 - s0) for frac in (0.0, 0.5, 1.0)], lambda s: f"{int(s)}", fill=None)
    chart.axis_titles(x="step")
    colours = (part_colors(len(series)) * 200).to(torch.uint8).tolist()
    for i, (name, pts) in enumerate(series.items()):
        col = tuple(colours[i])
        xy = [(chart.x_px(s), chart.y_px(math.log10(v))) for s, v in pts]
        if len(xy) == 1:
            chart.draw.ellipse([xy[0][0] - 2, xy[0][1] - 2, xy[0][0] + 2, xy[0][1] + 2], fill=col)
        else:
            chart.draw.line(xy, fill=col, width=2)
        ly = chart.top + 12 + 18 * i
        chart.draw.line([chart.right + 10, ly, chart.right + 30, ly], fill=col, width=3)
        chart.draw.text((chart.right + 36, ly - 6), name, fill=(0, 0, 0))
    return chart.save(png_path)
