"""``cerberus eval``: score a trained run on a test split (voxel IoU and every diagnostic of
:data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS`): :meth:`cerberus_core.run.Run.evaluate`."""
from __future__ import annotations

import argparse
from pathlib import Path

from cerberus_core.cli.checks import OVERWRITE_HELP, positive_int
from cerberus_core.cli.flags import FlagNames
from cerberus_core.datasets.looks import INPUT_LOOKS
from cerberus_core.errors import ConfigError
from cerberus_core.eval.diagnostics import DIAGNOSTICS
from cerberus_core.eval.standard import GT_OPEN_MESH, SCORER_ENTRY_POINT

GT_OPEN_MESH_HELP = (
    "what to do with a ground-truth mesh that is not watertight (a scan with holes): error (the default) stops the "
    "evaluation and names the mesh, since the voxel IoU fills a ground truth's inside and through its holes the fill "
    "would leave a hollow shell, a wrong reference every prediction would be scored against without a word; close "
    "closes its holes with pymeshlab and warns; warn scores it as it is, a hollow shell where the fill leaks in, and "
    "warns. results.json records the choice under 'gt_open_mesh'")


def configure(p: argparse.ArgumentParser) -> None:
    """The arguments, description and examples of ``cerberus eval`` (:data:`cerberus_core.cli.COMMANDS`)."""
    diagnostics = "; ".join(f"{row.about} [{skip_flag(row.name)}]" for row in DIAGNOSTICS)
    p.description = ("Evaluate a trained model (a run folder, model.safetensors or checkpoint .pt) on the test split of "
        "a dataset: 32^3 voxel IoU of the union of parts (scored by the cerberus.metrics entry point "
        f"'{SCORER_ENTRY_POINT}' of cerberus-metrics, 'kato' protocol), per image and per subject; and the "
        f"diagnostics, each skipped by the flag beside it: {diagnostics}. "
        "Writes results.json, "
        "results.md, a Table-2-like figure (table2.png, with the voxels missed and off the body seen from the "
        "front and the side) and, for the same images, the pictures of the paper's "
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
    p.add_argument("--out", type=Path, help=f"output folder, replaced whole (default: RUN/eval); {OVERWRITE_HELP}")
    p.add_argument("--overwrite", action="store_true",
                   help="accepted for older scripts and changes nothing: earlier results of cerberus eval are "
                   "replaced without it, and nothing else ever is (docs/outputs.md)")
    p.add_argument("--protocol", default="kato", help="voxel-IoU protocol (default: kato, the paper's)")
    p.add_argument("--resolution", type=int, default=32,
                   help="voxel grid resolution (default: 32); cerberus-metrics bounds it (2..1024), checked "
                   "before anything runs")
    p.add_argument("--gt-open-mesh", choices=GT_OPEN_MESH, default="error", help=GT_OPEN_MESH_HELP)
    for row in DIAGNOSTICS:  # --no-hard, --no-part-quality, ...: one per diagnostic, from its row
        p.add_argument(skip_flag(row.name), action="store_true", dest=f"no_{row.name}", help=f"skip {row.about}")
    p.add_argument("--limit", type=positive_int, metavar="N",
                   help="evaluate at most N >= 1 images, spread evenly over the split (a quick look that samples every "
                   "part of it): whole poses, as many as N images hold, unless --no-depth (depth compares each pose's "
                   "views); results.json records which under 'data'")
    p.add_argument("--baseline", action="append", default=[], metavar="NAME=RUN",
                   help="another trained run to show beside ours in the figure (repeatable), e.g. NMRr=runs/nmrr")
    p.add_argument("--figure-images", type=positive_int, default=5, help="test images in the figure, spread over the images scored (default: 5)")
    p.add_argument("--viewer-images", type=int, default=12, metavar="N",
                   help="figure images in the interactive 3D viewer pictures/index.html (default: up to 12; 0: none)")
    p.add_argument("--renderer", help="renderer backend of every render in the input views (part visibility, "
                   "depth, body segments, allocation) and of the figures (default: the run's)")
    p.add_argument("--device", default="cpu", help="device for the model (default: cpu)")
    p.add_argument("--input-look", default=None, choices=INPUT_LOOKS,
                   help="show the model the test images in this look: shaded (as stored), flat (each body's mask "
                   "filled with its mean grey: a silhouette) or random (an albedo colour, a texture and a light balance "
                   "drawn per image); the ground truth and every score are as without it (default: the look the model "
                   "learned, data.input_look: shaded for human, flat for human-silhouette)")
    # The flag of each setting of Run.load and Run.evaluate (its EvalSettings fields included).
    p.set_defaults(func=run, flag_names=FlagNames({
        "data": "--data", "split": "--split", "protocol": "--protocol", "resolution": "--resolution",
        "gt_open_mesh": "--gt-open-mesh", "limit": "--limit", "figure_images": "--figure-images",
        "viewer_images": "--viewer-images", "renderer": "--renderer", "out": "--out", "device": "--device",
        "input_look": "--input-look"}))


def skip_flag(name: str) -> str:
    """The flag that skips the diagnostic ``name`` (a row of ``DIAGNOSTICS``): ``part_quality`` → ``--no-part-quality``."""
    return "--no-" + name.replace("_", "-")


def baseline_runs(specs: list[str], device: str) -> dict:
    """``--baseline NAME=RUN`` (repeatable) → ``{name: Run}``, every one loaded before anything runs."""
    from cerberus_core.errors import CerberusError
    from cerberus_core.run import Run

    out = {}
    for spec in specs:
        name, _, path = spec.partition("=")
        if not name or not path:
            raise ConfigError(f"--baseline takes NAME=RUN (e.g. NMRr=runs/nmrr), got {spec!r}", key="baselines", value=spec)
        if name in out:
            raise ConfigError(f"--baseline {name!r} is given twice; give each baseline its own name", key="baselines", value=name)
        try:
            out[name] = Run.load(path, device)
        except CerberusError as exc:
            raise ConfigError(f"--baseline {name}={path}: {exc}", key="baselines", value=name) from None
    return out


def run(args: argparse.Namespace) -> int:
    from cerberus_core.run import EvalSettings, Run

    # Every argument is checked, and every model and the dataset opened, before anything is written.
    settings = EvalSettings(split=args.split, protocol=args.protocol, resolution=args.resolution,
                            gt_open_mesh=args.gt_open_mesh,
                            skip=tuple(row.name for row in DIAGNOSTICS if getattr(args, f"no_{row.name}")),
                            limit=args.limit,
                            figure_images=args.figure_images, viewer_images=args.viewer_images,
                            renderer=args.renderer, input_look=args.input_look)
    run_ = Run.load(args.run, args.device)
    run_.evaluate(args.data, settings, args.out, baselines=baseline_runs(args.baseline, args.device))
    return 0
