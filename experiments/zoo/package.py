"""Package a trained run as a shipped pretrained model (cerberus_core/zoo/NAME.{safetensors,json,md}).

Re-exports the run's weights with the dataset's scene set-up in the metadata (so the file alone can
reconstruct images), records its SHA-256, and writes the model card from the run's config and the
results.json of `cerberus eval`. Every figure in the card comes from those files.

    python experiments/zoo/package.py human RUN DATA "one-line summary" --command "..."

The card's training time is RUN/metrics.csv's, summed over the run's sittings (``training_time``);
``--train-seconds`` overrides it (a run whose log is gone, or timed elsewhere).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import yaml

from cerberus_core.datasets.manifest import Manifest
from cerberus_core.eval.compare import load_evaluation
from cerberus_core.plumbing.atomic import atomic_write_text
from cerberus_core.plumbing.metrics_csv import training_time
from cerberus_core.run import Run
from cerberus_core.train.checkpoint import export_weights
from cerberus_core.zoo import ZOO_DIR, sha256_file


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("name")
    ap.add_argument("run", type=Path, help="trained run folder (with eval/results.json from `cerberus eval`)")
    ap.add_argument("data", type=Path, help="the dataset it was evaluated on (its test split; by default also "
                    "the one it was trained on)")
    ap.add_argument("--train-data", type=Path, default=None,
                    help="the dataset it was trained on, when not DATA (e.g. the large human set, scored on the "
                    "small set's test split, which is the same)")
    ap.add_argument("--size", default=None, help="the named `cerberus data generate --size` whose test split DATA "
                    "holds (default: DATA's own preset); the zoo test regenerates that size's test split")
    ap.add_argument("summary")
    ap.add_argument("--train-seconds", type=float, default=None, help="measured wall time of the training "
                    "(default: RUN/metrics.csv's, summed over the run's sittings)")
    ap.add_argument("--command", action="append", default=[], help="a command that made it (repeatable)")
    ap.add_argument("--machine", default="2-core x86 CPU (AVX-512), 24 GiB, no GPU; one thread per training")
    ap.add_argument("--changes", default="", help="what changed against the weights this replaces (the card's "
                    "'What changed' section)")
    ap.add_argument("--eval", type=Path, default=None, help="the `cerberus eval` folder whose results.json the card's "
                    "figures come from (default: RUN/eval); its input look is the card's")
    ap.add_argument("--compare", action="append", default=[], metavar="LABEL=DIR",
                    help="another `cerberus eval` folder of the same model, shown as one more IoU row (repeatable), "
                    "e.g. 'the shaded test=RUN/eval'")
    args = ap.parse_args()

    if args.train_seconds is None:
        trained_for = training_time(args.run / "metrics.csv")
        if trained_for is None:
            ap.error(f"{args.run / 'metrics.csv'} has no training time: give --train-seconds S")
        args.train_seconds = trained_for.seconds
    run = Run.load(args.run)
    model, config = run.model, run.config
    manifest = Manifest.read(args.data)
    trained = Manifest.read(args.train_data) if args.train_data else manifest
    size = args.size or manifest.preset
    train_split = trained.config.splits.get("train")
    counts = ", ".join(f"{getattr(train_split, k):,} {k}" for k in ("pairs", "subjects")
                       if train_split is not None and getattr(train_split, k))
    results = load_evaluation(args.eval or args.run / "eval")
    input_look = results.get("input_look", "shaded")
    compared = []
    for item in args.compare:
        label, _, folder = item.partition("=")
        other = load_evaluation(folder)
        hard = f", Hard Human {other['hard']['mean']:.4f}" if other.get("hard") else ""
        compared.append(f"| voxel IoU, {label} ({other['standard']['count']} images, {other.get('input_look', 'shaded')} "
                        f"input look) | {other['standard']['mean']:.4f}{hard} |")
    config_yaml = yaml.safe_dump(config.to_dict(), sort_keys=False)
    weights = ZOO_DIR / f"{args.name}.safetensors"
    step = config.train.steps
    export_weights(model, weights, config_yaml, step, scene=manifest.scene.to_dict())
    pq = results.get("part_quality") or {}
    figures = {"test_iou": round(results["standard"]["mean"], 4), "test_images": results["standard"]["count"]}
    if results.get("hard"):
        figures["hard_human_iou"] = round(results["hard"]["mean"], 4)
    if pq:
        figures["part_consistency"] = round(pq["consistency"], 3)
    entry = {"name": args.name, "summary": args.summary, "weights": weights.name, "sha256": sha256_file(weights),
             "card": f"{args.name}.md", "results": figures,
             "data": {"dataset": manifest.dataset, "size": size}
             | ({"input_look": input_look} if input_look != "shaded" else {}),
             "part_labels": [p["label"] for p in sorted(pq.get("parts", []), key=lambda p: p["part"])]}
    atomic_write_text(ZOO_DIR / f"{args.name}.json", json.dumps(entry, indent=2) + "\n")
    parts = "\n".join(f"| {p['part']} | {p['label']} | {p['agreement']:.2f} | {p['images']} |" for p in pq.get("parts", []))
    seg = ", ".join(f"{k} {v:.2f}" for k, v in (pq.get("segmentation_iou") or {}).items() if v > 0)
    commands = "\n".join(args.command)
    extras = [name for name, on in (("anti-aliased rendering (visibility gradients)", config.render.antialias),
                                    (f"silhouette term {config.losses.silhouette:g}", config.losses.silhouette > 0),
                                    (f"chamfer term {config.losses.chamfer:g}", config.losses.chamfer > 0),
                                    (f"hidden-part pull {config.losses.hidden:g}", config.losses.hidden > 0),
                                    ("the cross view rendered with each image's own 3D model (losses.cross_view: own, "
                                     f"after {config.losses.cross_view_warmup} steps of the paper's)",
                                     config.losses.cross_view == "own"),
                                    (f"reprojection term {config.losses.reprojection:g}", config.losses.reprojection > 0),
                                    ("the pulls on the cross view too", config.losses.cross_pulls),
                                    (f"bfloat16 network ({config.speed.autocast})", config.speed.autocast),
                                    ("the rotation head's quaternion read as each part's world rotation "
                                     "(model.rotation: world)", config.model.rotation == "world")) if on]
    recipe = "the paper's losses and renderer" if not extras else "the paper's losses plus " + ", ".join(extras)
    scene, supersample = manifest.scene, manifest.config.supersample
    look = (f"{'black' if scene.background == (0.0, 0.0, 0.0) else 'white'} background, "
            f"{supersample}x{supersample} samples per pixel, "
            f"camera distance {scene.distance} at elevation {scene.elevation} degrees")
    labels = {p["label"].split(".")[0] for p in pq.get("parts", []) if p.get("label")}
    gt_kinds = {g.split(".")[0] for g in pq.get("gt_parts", [])}
    missing = [name for name in ("head", "upper_arm", "lower_arm") if name in gt_kinds and name not in labels]
    vis = results.get("part_visibility") or {}
    hidden_row = (f"| parts wholly hidden in their input view in most test images | "
                  f"{vis['parts_hidden_in_most_images']} of {config.model.num_parts} |" if vis else "")
    changes = f"\n## What changed\n\n{args.changes}\n" if args.changes else ""
    kind = ("NMRr (the single-mesh baseline: one deformed sphere, no rotation head, vertex box "
            f"{config.model.vertex_bound})" if config.model.num_parts == 1 else "Cerberus")
    trained_look = config.data.input_look
    limits = (":\nphotographs need the same framing to make sense." if trained_look == "shaded" else
              f", seen in the `{trained_look}` input look: a photo needs a mask of the whole body (`--mask auto` or a "
              "mask file) and the same framing; it reads the silhouette, so what the silhouette does not show (a limb "
              "in front of the body) it guesses.")
    shown = "" if input_look == "shaded" else f", shown in the {input_look} input look"
    seen = ("" if trained_look == "shaded" else
            f"| input look | `{trained_look}`: the network sees each training body "
            + ("as a flat silhouette (its mask filled with one grey level)" if trained_look == "flat"
               else "in a random appearance") + "; the losses compare against the shaded renders "
            "(`data.input_look`, docs/training.md); `cerberus reconstruct` shows it its inputs the same way |\n")
    card = f"""# Model card: `{args.name}`

{args.summary}

| | |
| --- | --- |
| architecture | {kind}, {config.model.num_parts} part{"s" if config.model.num_parts > 1 else ""} of {model.template.vertices.shape[0]}-vertex spheres, ResNet-10 width {config.model.width}, shape latent {config.model.shape_latent_dim} |
| training data | `{trained.dataset}` dataset, size `{args.size or trained.preset}` ({counts}), {trained.image_size} px (generated by the toolkit; no download) |
{seen}| recipe | {config.train.steps} steps, batch {config.train.batch_size} quadruplets, renderer `{config.renderer}`, {recipe} |
| training time | {args.train_seconds / 60:.0f} min on {args.machine} |
| weights | `{weights.name}`, {weights.stat().st_size / 2**20:.1f} MiB, sha256 `{entry['sha256']}` (checked on every load) |

## Results (`cerberus eval`, test split of the same dataset: unseen subjects)

| metric | value |
| --- | --- |
| voxel IoU (kato, 32³), {figures['test_images']} images{shown} | {figures['test_iou']} |
{"| Hard Human voxel IoU | " + str(figures['hard_human_iou']) + " |" if 'hard_human_iou' in figures else ""}
{"| part consistency (mean agreement) | " + str(figures['part_consistency']) + " |" if pq else ""}
{hidden_row}
{chr(10).join(compared)}

Learned parts against the ground-truth semantic parts (majority label, agreement over test images):

| part | label | agreement | images |
| --- | --- | --- | --- |
{parts}

Segmentation IoU of the parts that match a ground-truth part: {seg or 'none'}.
For comparison, the paper reports 0.497 (human) and 0.426 (animal) at 100,000 GPU steps on SMPL/SMAL data;
see `docs/results.md` for how this toolkit's numbers compare and why.

{changes}
## Exact commands

```bash
{commands}
```

## Limits

Trained on the toolkit's synthetic renders (uniform grey albedo, white light following the camera, {look}){limits}
{"No learned part has the " + " or ".join(missing) + " as its label at this budget (see the table above)." if missing else ""}
"""
    lines = card.split("\n")  # a row left empty (no Hard Human, no comparison) must not split its table
    card = "\n".join(line for i, line in enumerate(lines)
                     if not (line == "" and 0 < i < len(lines) - 1 and lines[i - 1].startswith("|")
                             and next((n for n in lines[i + 1:] if n), "").startswith("|")))
    atomic_write_text(ZOO_DIR / f"{args.name}.md", card)
    print(json.dumps(entry, indent=2))


if __name__ == "__main__":
    main()
