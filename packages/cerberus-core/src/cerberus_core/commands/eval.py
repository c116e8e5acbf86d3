"""``cerberus eval``: score a trained run on a test split (voxel IoU, Hard Human, part quality)."""
from __future__ import annotations

import argparse
from pathlib import Path

import torch

from cerberus_core.plugins import get_metric, make_renderer


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "eval", help="evaluate a trained run on a test split: voxel IoU, Hard Human, part quality, figure",
        description="Evaluate a trained model (a run folder, model.safetensors or checkpoint .pt) on the test split of "
        "a dataset: 32^3 voxel IoU of the union of parts (metric 'voxel_iou' found through the cerberus.metrics "
        "entry point, 'kato' protocol), per image and per subject; the Hard Human test (parts from each subject's "
        "canonical image, posed by every other image); part quality against the ground-truth semantic parts that "
        "training never saw. Writes results.json, results.md, a Table-2-like figure (table2.png) and, for the same images, the pictures "
        "of the paper's Figure 1 (pictures/: input, output, parts, new lighting, turntable, new pose), with their "
        "meshes (GLB: reconstruction, ground truth, new pose) and pictures/index.html, an interactive 3D viewer.")
    p.add_argument("run", type=Path, help="run folder, model.safetensors or checkpoint .pt")
    p.add_argument("--data", type=Path, help="dataset folder (default: the run's training data root)")
    p.add_argument("--split", default="test", help="split to evaluate (default: test)")
    p.add_argument("--out", type=Path, help="output folder (default: RUN/eval)")
    p.add_argument("--protocol", default="kato", help="voxel-IoU protocol (default: kato, the paper's)")
    p.add_argument("--resolution", type=int, default=32, help="voxel grid resolution (default: 32)")
    p.add_argument("--no-hard", action="store_true", help="skip the Hard Human test")
    p.add_argument("--no-part-quality", action="store_true", help="skip part quality (the slowest part)")
    p.add_argument("--limit", type=int, help="evaluate only the first N images (quick look)")
    p.add_argument("--baseline", action="append", default=[], metavar="NAME=RUN",
                   help="another trained run to show beside ours in the figure (repeatable), e.g. NMRr=runs/nmrr")
    p.add_argument("--figure-images", type=int, default=5, help="test images in the figure (default: 5)")
    p.add_argument("--viewer-images", type=int, default=12, metavar="N",
                   help="figure images in the interactive 3D viewer pictures/index.html (default: up to 12; 0: none)")
    p.add_argument("--renderer", help="renderer backend for the figure (default: the run's)")
    p.add_argument("--device", default="cpu", help="device for the model (default: cpu)")
    p.set_defaults(func=run)


def _figure(args, model, config, dataset, out: Path) -> Path:
    from cerberus_core.eval.figures import comparison_figure, save_image_pictures, save_png
    from cerberus_core.eval.reconstruction import as_part_reconstruction
    from cerberus_core.eval.runner import collate
    from cerberus_core.eval.viewer import write_reconstruction_viewer
    from cerberus_core.train.checkpoint import load_model

    n = min(args.figure_images, len(dataset))
    idx = torch.linspace(0, len(dataset) - 1, n).round().long().unique().tolist()
    batch = collate([dataset[i] for i in idx])
    camera = dataset.cameras(batch)
    images = batch["images"]
    with torch.no_grad():
        ours = as_part_reconstruction(model.reconstruct(images.to(args.device), camera.to(args.device))).to("cpu")
        baselines = {}
        for spec in args.baseline:
            name, _, path = spec.partition("=")
            if not path:
                raise SystemExit(f"cerberus eval: --baseline takes NAME=RUN, got {spec!r}")
            other, _ = load_model(path, args.device)
            baselines[name] = as_part_reconstruction(other.reconstruct(images.to(args.device), camera.to(args.device))).to("cpu")
    renderer = make_renderer(args.renderer or config.renderer)
    background = tuple(dataset.scene["background"])
    fig = comparison_figure(renderer, images, camera, ours, baselines, background=background)
    for k, i in enumerate(idx):  # Figure 1 (b)-(f) per image; the new pose borrows the next image's
        donor = ours.index([(k + 1) % len(idx)]) if len(idx) > 1 else None
        save_image_pictures(renderer, images[k], ours.index([k]), camera.index([k]), out / "pictures",
                            f"test_{i:05d}", pose_donor=donor, background=background)
    write_reconstruction_viewer(out / "pictures", images, ours, camera, [f"test_{i:05d}" for i in idx],
                                bodies=[dataset.gt_mesh(i) for i in idx], limit=args.viewer_images,
                                limit_hint="--viewer-images", background=background,
                                title=f"cerberus eval: {args.run} ({args.split} split)")
    return save_png(fig, out / "table2.png")


def run(args: argparse.Namespace) -> int:
    from cerberus_core.data.dataset import ViewDataset
    from cerberus_core.eval.report import markdown_report, write_json, write_text
    from cerberus_core.eval.runner import evaluate_dataset
    from cerberus_core.train.checkpoint import load_model

    get_metric("voxel_iou")  # fail early, naming the package, if cerberus-metrics is missing
    model, config = load_model(args.run, args.device)
    data_root = args.data or Path(config.data.root)
    dataset = ViewDataset(data_root, args.split)
    out = args.out or ((args.run if args.run.is_dir() else args.run.parent) / "eval")
    out.mkdir(parents=True, exist_ok=True)
    indices = range(min(args.limit, len(dataset))) if args.limit else None
    result = evaluate_dataset(dataset, model.reconstruct, protocol=args.protocol, resolution=args.resolution,
                              hard=not args.no_hard, part_quality=not args.no_part_quality, indices=indices,
                              device=args.device)
    write_json(result, out / "results.json")
    write_text(markdown_report(result, title=f"Evaluation of {args.run}"), out / "results.md")
    fig = _figure(args, model, config, dataset, out)
    line = f"voxel IoU ({args.protocol}, {args.resolution}^3) over {result.standard.count} images: {result.standard.mean:.4f}"
    if result.hard is not None:
        line += f"; Hard Human: {result.hard.mean:.4f}"
    print(line)
    print(f"results: {out / 'results.json'}, {out / 'results.md'}; figures: {fig}, {out / 'pictures'}")
    if args.viewer_images > 0:
        print(f"3D viewer: {out / 'pictures' / 'index.html'}")
    return 0
