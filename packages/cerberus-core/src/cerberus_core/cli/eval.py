"""``cerberus eval``: score a trained run on a test split (voxel IoU, Hard Human, part quality)."""
from __future__ import annotations

import argparse
from pathlib import Path

from cerberus_core.cli.checks import is_dataset, positive_int, result_folder, writing_results
from cerberus_core.devices import check_device
from cerberus_core.errors import CerberusError, ConfigError
from cerberus_core.eval.standard import SCORER_ENTRY_POINT
from cerberus_core.names import printable
from cerberus_core.plugins import get_metric, make_renderer

#: What ``cerberus eval`` wrote before result folders were marked: such a folder is replaced without --overwrite.
EARLIER_RESULTS = frozenset({"results.json", "results.md", "table2.png", "pictures"})
#: Largest voxel grid accepted (memory grows with its cube).
MAX_RESOLUTION = 256


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "eval", help="evaluate a trained run on a test split: voxel IoU, Hard Human, part quality, figure",
        description="Evaluate a trained model (a run folder, model.safetensors or checkpoint .pt) on the test split of "
        "a dataset: 32^3 voxel IoU of the union of parts (metric 'voxel_iou' found through the cerberus.metrics "
        "entry point, 'kato' protocol), per image and per subject; the Hard Human test (parts from each subject's "
        "canonical image, posed by every other image); part quality against the ground-truth semantic parts that "
        "training never saw; how often each learned part is wholly hidden in its input view. Writes results.json, "
        "results.md, a Table-2-like figure (table2.png) and, for the same images, the pictures of the paper's "
        "Figure 1 (pictures/: input, output, parts, new lighting, turntable, new pose), with their meshes (GLB: reconstruction, ground truth, new pose) and pictures/index.html, an "
        "interactive 3D viewer that works offline. Reports the training step of the weights it scores, and warns "
        "when the run has a newer checkpoint than its model.safetensors (a resumed training not finished). "
        "The results replace --out whole, in one step, once they are all written: an error or Ctrl-C leaves it as "
        "it was.")
    p.add_argument("run", help="run folder, model.safetensors or checkpoint .pt, or a shipped model's name "
                   "(`cerberus models`); a bare name that a shipped model has (human) is that model: write a "
                   "folder of that name as ./human")
    p.add_argument("--data", type=Path, help="dataset folder (default: the run's training data root)")
    p.add_argument("--split", default="test", help="split to evaluate (default: test)")
    p.add_argument("--out", type=Path, help="output folder, replaced whole (default: RUN/eval)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace --out even when it holds files that are not earlier results")
    p.add_argument("--protocol", default="kato", help="voxel-IoU protocol (default: kato, the paper's)")
    p.add_argument("--resolution", type=positive_int, default=32,
                   help=f"voxel grid resolution, 1..{MAX_RESOLUTION} (default: 32)")
    p.add_argument("--no-hard", action="store_true", help="skip the Hard Human test")
    p.add_argument("--no-part-quality", action="store_true", help="skip part quality (the slowest part)")
    p.add_argument("--limit", type=positive_int, help="evaluate only the first N >= 1 images (quick look)")
    p.add_argument("--baseline", action="append", default=[], metavar="NAME=RUN",
                   help="another trained run to show beside ours in the figure (repeatable), e.g. NMRr=runs/nmrr")
    p.add_argument("--figure-images", type=positive_int, default=5, help="test images in the figure (default: 5)")
    p.add_argument("--viewer-images", type=int, default=12, metavar="N",
                   help="figure images in the interactive 3D viewer pictures/index.html (default: up to 12; 0: none)")
    p.add_argument("--renderer", help="renderer backend for the figure and the part-visibility render "
                   "(default: the run's)")
    p.add_argument("--device", default="cpu", help="device for the model (default: cpu)")
    p.set_defaults(func=run)


def check_protocol(name: str) -> str:
    """The voxel-IoU protocol must be one the metric knows (checked through its entry point, before
    anything runs)."""
    try:
        get_metric(SCORER_ENTRY_POINT)(protocol=name, resolution=32)
    except (ValueError, KeyError) as exc:
        raise ConfigError(f"--protocol {name!r}: {exc}") from None
    return name


def load_baselines(specs: list[str], device: str) -> dict:
    """``NAME=RUN`` specs → ``{name: model}``, every one loaded before the evaluation starts."""
    from cerberus_core.train.checkpoint import load_model

    out = {}
    for spec in specs:
        name, _, path = spec.partition("=")
        if not name or not path:
            raise ConfigError(f"--baseline takes NAME=RUN (e.g. NMRr=runs/nmrr), got {spec!r}")
        if name in out:
            raise ConfigError(f"--baseline {name!r} is given twice; give each baseline its own name")
        try:
            out[name] = load_model(path, device)[0]
        except CerberusError as exc:
            raise ConfigError(f"--baseline {name}={path}: {exc}") from None
    return out


def run(args: argparse.Namespace) -> int:
    import warnings

    from cerberus_core.datasets.readers import ViewDataset
    from cerberus_core.eval.figures import evaluation_figures
    from cerberus_core.eval.report import markdown_report, md_text, to_jsonable, write_json, write_text
    from cerberus_core.eval.runner import evaluate_dataset
    from cerberus_core.eval.visibility import visibility_line
    from cerberus_core.train.checkpoint import describe_weights, load_model, looks_like_path

    # Every argument is checked, and every model and the dataset opened, before anything is written.
    if args.resolution > MAX_RESOLUTION:
        raise ConfigError(f"--resolution {args.resolution}: at most {MAX_RESOLUTION} (the paper uses 32)")
    check_protocol(args.protocol)
    if args.viewer_images < 0:
        raise ConfigError(f"--viewer-images {args.viewer_images}: must be >= 0 (0: no viewer)")
    check_device(args.device)
    if args.data is not None and not is_dataset(args.data):
        raise ConfigError(f"--data {args.data}: not a Cerberus dataset folder (no manifest.json)")
    get_metric(SCORER_ENTRY_POINT)  # fail early, naming the package, if cerberus-metrics is missing
    weights = describe_weights(args.run)
    model, config = load_model(weights.path, args.device)
    run_path = Path(args.run)
    default_out = (run_path if run_path.is_dir() and looks_like_path(args.run) else run_path.parent) / "eval"
    keep = [run_path] if looks_like_path(args.run) else []
    out = result_folder(args.out or default_out, overwrite=args.overwrite,
                        keep=[*keep, *([args.data] if args.data else [])], earlier=EARLIER_RESULTS)
    baselines = load_baselines(args.baseline, args.device)
    data_root = args.data or Path(config.data.root)
    if args.data is None and not is_dataset(data_root):
        raise ConfigError(f"the run's training data {data_root} is not a dataset folder from here; "
                          "pass --data DATASET")
    dataset = ViewDataset(data_root, args.split)
    dataset.scene  # noqa: B018 - read (and checked) now, not midway through the evaluation
    renderer = make_renderer(args.renderer or config.renderer)
    indices = range(min(args.limit, len(dataset))) if args.limit else None
    stale = weights.stale_warning()
    at_step = "" if weights.step is None else f" at step {weights.step}"
    print(f"evaluating {printable(weights.path)}{at_step}")
    if stale:
        warnings.warn(stale, UserWarning, stacklevel=1)
    shown_run = printable(args.run)
    with writing_results(out, "cerberus eval") as tmp:  # out is replaced only once all is written
        result = evaluate_dataset(dataset, model.reconstruct, protocol=args.protocol, resolution=args.resolution,
                                  hard=not args.no_hard, part_quality=not args.no_part_quality, indices=indices,
                                  renderer=renderer, device=args.device)
        record = to_jsonable(result) | {"model": {"path": str(weights.path), "step": weights.step,
                                                  "newer_checkpoint": None if weights.newer is None else
                                                  {"path": str(weights.newer), "step": weights.newer_step}}}
        write_json(record, tmp / "results.json")
        report = markdown_report(record, title=f"Evaluation of {args.run}{at_step}")
        if stale:
            title, _, rest = report.partition("\n")
            report = f"{title}\n\n> **Warning:** {md_text(stale)}\n{rest}"
        write_text(report, tmp / "results.md")
        evaluation_figures(renderer, dataset, model, tmp, n_images=args.figure_images, baselines=baselines,
                           device=args.device, viewer_images=args.viewer_images,
                           title=f"cerberus eval: {shown_run}{at_step} ({args.split} split)")
    fig = out / "table2.png"
    line = (f"voxel IoU ({args.protocol}, {args.resolution}^3) over {result.standard.count} images: "
            f"{result.standard.mean:.4f}")
    if result.hard is not None:
        line += f"; Hard Human: {result.hard.mean:.4f}"
    elif not args.no_hard:
        line += "; Hard Human: not run (no canonical-pose images in this split"
        if dataset.manifest["config"]["dataset"] == "folder":
            line += "; name each subject's canonical pose with `cerberus data generate --dataset folder --canonical POSE`"
        line += ")"
    print(line)
    if result.part_visibility is not None:
        print(visibility_line(result.part_visibility))
    if stale:  # said again under the scores, where it is read
        print(f"note: these scores are for step {weights.step}; the run has a newer checkpoint "
              f"{printable(weights.newer)} (step {weights.newer_step})")
    print(f"results: {printable(out / 'results.json')}, {printable(out / 'results.md')}; figures: {printable(fig)}, "
          f"{printable(out / 'pictures')}")
    if args.viewer_images > 0:
        print(f"3D viewer: {printable(out / 'pictures' / 'index.html')}")
    return 0
