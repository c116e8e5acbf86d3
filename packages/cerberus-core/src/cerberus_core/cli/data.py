"""``cerberus data``: generate, check and look at datasets (docs/data_format.md)."""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from cerberus_core.bodies.folder import DEFAULT_UP_AXIS, UP_AXES
from cerberus_core.cli import Terms
from cerberus_core.cli.checks import check_apart, output_file, output_folder, positive_int, resolved
from cerberus_core.datasets.plan import SHORTCUT_FLAGS, GenerationConfig, load_generation_config, sizes
from cerberus_core.errors import ConfigError, DatasetError

_DATASETS = ("human", "animal", "folder", "primitives")  # the order --help lists them
DEFAULT_TEST_FRACTION = 0.3
MAX_SHOW_COUNT, MAX_SHOW_SCALE = 256, 16  # a contact sheet stays a picture (256 rows of 64 px tiles x 16)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("data", help="generate, check and show training/test datasets",
                       description="Render the paper's datasets on this machine (nothing is downloaded): "
                       "quadruplets of one body in 2 poses from 2 viewpoints for training, single views with "
                       "ground-truth meshes and part labels for testing.")
    dsub = p.add_subparsers(dest="data_command", metavar="ACTION")
    dsub.required = True

    g = dsub.add_parser("generate", help="generate (or resume) a dataset",
                        formatter_class=argparse.RawDescriptionHelpFormatter,
                        description="Generate a dataset into --out. Rerunning the same command resumes an interrupted "
                        "run without redoing finished shards; a folder holding anything else is refused unless "
                        "--overwrite.\n\nsizes (bundled presets, cerberus_core/configs/data/<dataset>_<size>.yaml):\n"
                        "  human:      large (the paper's 19,500 train pairs / 5 subjects with small's test split:\n"
                        "              the data of the shipped human model, about half an hour on 2 cores),\n"
                        "              paper (19,500 train pairs / 5 subjects;\n"
                        "              810 test poses x 4 views / 2 subjects),\n"
                        "              small (1,000 pairs; 50 test poses, a few minutes on a CPU), tiny (seconds)\n"
                        "  animal:     paper (41 species x 47 poses x 4 views, 38,540 quadruplets; 984 test views),\n"
                        "              small (12 species), tiny\n"
                        "  primitives: capsule figures with the human presets' structure (paper, small, tiny)\n"
                        "  folder:     pairs (the Human protocol on your meshes), grid (the Animal protocol)\n\n"
                        "--set KEY=VALUE changes any key of the resolved config (values are YAML; see it with\n"
                        "--print-config): seed, image_size, renderer, shard_images, scene.<field>,\n"
                        "splits.<split>.<field>, e.g. --set splits.train.pairs=2000 --set scene.elevation=20")
    g.add_argument("--dataset", choices=_DATASETS, required=True, help="body source")
    g.add_argument("--size", default=None, metavar="NAME",
                   help="size preset (the bundled ones: " + "; ".join(f"{d}: {', '.join(sizes(d))}" for d in _DATASETS)
                   + "); default small (folder: pairs)")
    g.add_argument("--preset", dest="size_alias", default=None, help=argparse.SUPPRESS)  # deprecated: --size
    g.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. --set splits.train.pairs=2000 (repeatable; values are YAML)")
    g.add_argument("--out", type=Path, required=True, help="dataset folder to create or resume")
    g.add_argument("--source", type=Path, help="folder of meshes: SOURCE/<subject>/<pose>.<obj|ply|glb|off|stl> "
                   "(--dataset folder only)")
    g.add_argument("--test-subjects", help="folder: comma-separated test subject names (default: --test-fraction)")
    g.add_argument("--test-fraction", type=float, default=None,
                   help="folder: fraction of subjects (last in sorted order) held out for testing "
                   f"(default {DEFAULT_TEST_FRACTION}; 1: a test-only dataset, to evaluate a trained model on your meshes)")
    g.add_argument("--up-axis", choices=UP_AXES, default=None,
                   help="folder: the meshes' up axis, turned into +Y (default +y, the toolkit's world; Blender, "
                   "anny and many scans are +z); recorded in the manifest")
    g.add_argument("--canonical", metavar="POSE",
                   help="folder: the pose file stem that is each subject's canonical pose, rendered and flagged in "
                   "the test split for the Hard Human test of cerberus eval (default: a pose named 'canonical')")
    g.add_argument("--renderer", default=None,
                   help="renderer backend: warp, torch or auto (default: auto, warp if it works, else torch); "
                   "same as --set renderer=...")
    g.add_argument("--image-size", type=int, default=None,
                   help="image size in pixels (default 64; 128 available); same as --set image_size=...")
    g.add_argument("--seed", type=int, default=None,
                   help="seed of every random choice (default 0); same as --set seed=...")
    g.add_argument("--shard-images", type=int, default=None,
                   help="images per shard (default 1024); same as --set shard_images=...")
    g.add_argument("--batch-size", type=positive_int, default=64, help="views per render call (default 64; no effect on output)")
    g.add_argument("--device", default="cpu", help="torch device for posing and rendering (default cpu)")
    g.add_argument("--overwrite", action="store_true", help="replace a different dataset in --out")
    g.add_argument("--dry-run", action="store_true", help="print the plan (counts per split) and exit")
    g.add_argument("--print-config", action="store_true", help="print the resolved config (YAML) and exit")
    g.add_argument("--quiet", action="store_true", help="no progress bar")
    # The flag of each setting of load_generation_config, validate_generation / generate and the folder source;
    # the config's other keys are said with --set.
    g.set_defaults(func=run_generate, terms=Terms({
        **SHORTCUT_FLAGS, "dataset": "--dataset", "size": "--size", "overrides": "--set", "out": "--out",
        "overwrite": "--overwrite", "batch_size": "--batch-size", "device": "--device", "test_fraction": "--test-fraction",
        "test_subjects": "--test-subjects", "up_axis": "--up-axis", "canonical": "--canonical", "source": "--source"},
        GenerationConfig))

    c = dsub.add_parser("check", help="verify a dataset's checksums and report its contents",
                        description="Verify the manifest (format version, paths), every shard file (size, sha256, "
                        "array shapes) and completeness. Exit status 1 on any problem.")
    c.add_argument("root", type=Path, help="dataset folder")
    c.add_argument("--quick", action="store_true", help="sizes and headers only, no sha256")
    c.set_defaults(func=run_check)

    s = dsub.add_parser("show", help="write a contact sheet PNG of a split",
                        description="Rows of quadruplets (a0 a1 b0 b1) for training splits, or the views of each "
                        "pose for test splits; --parts adds the ground-truth parts in colour.")
    s.add_argument("root", type=Path, help="dataset folder")
    s.add_argument("--split", default="train", help="split to show (default train)")
    s.add_argument("--out", type=Path, help="PNG path (default: ROOT/contact_<split>.png)")
    s.add_argument("--count", type=positive_int, default=8, help=f"rows, 1..{MAX_SHOW_COUNT} (default 8)")
    s.add_argument("--parts", action="store_true", help="add ground-truth part renderings")
    s.add_argument("--scale", type=positive_int, default=2, help=f"tile upscaling, 1..{MAX_SHOW_SCALE} (default 2)")
    s.add_argument("--renderer", default="auto", help="backend for --parts (default auto: warp, else torch)")
    s.set_defaults(func=run_show, terms=Terms({"out": "--out", "split": "--split", "renderer": "--renderer"}))


def _generation_config(args: argparse.Namespace):
    """The resolved config: the size preset, then the shortcut flags, then --set (later wins)."""
    size = args.size
    if args.size_alias is not None:
        print("cerberus data generate: --preset is deprecated here, use --size (a dataset size; training "
              "recipes are `cerberus train --preset`)", file=sys.stderr)
        size = size or args.size_alias
    shortcuts = [f"{key}={value}" for key, flag in SHORTCUT_FLAGS.items()
                 if (value := getattr(args, flag[2:].replace("-", "_"))) is not None]
    return load_generation_config(args.dataset, size, [*shortcuts, *args.overrides])


def _source_options(args: argparse.Namespace) -> dict:
    """The body source's options (stored in the manifest): the folder's root and test split."""
    if (args.dataset == "folder") != (args.source is not None):
        raise ConfigError("--source DIR is required with --dataset folder (and only then)")
    if args.dataset != "folder":
        if args.test_subjects is not None or args.test_fraction is not None:
            raise ConfigError("--test-subjects and --test-fraction choose the test subjects of --dataset folder "
                              "only; the other datasets' splits are set by --size and --set")
        if args.up_axis is not None or args.canonical is not None:
            raise ConfigError("--up-axis and --canonical apply to --dataset folder only; drop them or use --dataset folder")
        return {}
    options = {"root": str(resolved(args.source, "source")),
               "test_fraction": DEFAULT_TEST_FRACTION if args.test_fraction is None else args.test_fraction,
               "up_axis": args.up_axis or DEFAULT_UP_AXIS}
    if args.canonical is not None:
        options["canonical"] = args.canonical
    if args.test_subjects is not None:
        options["test_subjects"] = [s.strip() for s in args.test_subjects.split(",") if s.strip()]
        if not options["test_subjects"]:
            raise ConfigError(f"--test-subjects {args.test_subjects!r}: expected comma-separated subject names")
    return options


def run_generate(args: argparse.Namespace) -> int:
    """Every argument is checked (:func:`validate_generation`) before --dry-run returns and before the
    folder's lock or manifest is written."""
    import yaml

    from cerberus_core.datasets.generate import generate, validate_generation
    from cerberus_core.plumbing.lock import check_unlocked, folder_lock

    options = _source_options(args)
    config = _generation_config(args)
    if args.print_config:
        print(yaml.safe_dump(config.to_dict(), sort_keys=False), end="")
        return 0
    output_folder(args.out, dataset_ok=True)
    if "root" in options:  # the meshes read must not be inside the dataset folder written
        check_apart(args.out, [options["root"]], what="a dataset is written there")
    runtime = {"device": args.device} if args.dataset == "human" else {}  # not stored: no effect on content
    job = validate_generation(config, source_options=options, source_runtime=runtime, device=args.device,
                              batch_size=args.batch_size, out=args.out, overwrite=args.overwrite)
    if args.dataset == "folder" and args.up_axis is None and (hint := job.source.up_axis_warning()):
        warnings.warn(hint, UserWarning, stacklevel=1)  # an explicit --up-axis silences it
    if args.out.is_dir():
        check_unlocked(args.out)  # a live writer: refused before the lock file is even attempted
    if args.dry_run:
        print("\n".join(job.plan_lines()))
        return 0
    with folder_lock(args.out, "cerberus data generate"):  # one writer per dataset folder
        manifest = generate(config, args.out, source=job.source, source_options=options, overwrite=args.overwrite,
                            device=args.device, batch_size=args.batch_size, progress=not args.quiet)
    print(*(f"{split:<6} {info.planned_images:>8} images {info.planned_quadruplets:>8} quadruplets"
            for split, info in manifest.splits.items()), f"dataset written to {args.out}", sep="\n")
    return 0


def run_check(args: argparse.Namespace) -> int:
    """Exit 2 when ROOT is not a readable dataset (bad input), 1 when the dataset has problems."""
    from cerberus_core.datasets.manifest import FORMAT_VERSION
    from cerberus_core.datasets.readers import verify_dataset

    manifest, problems = verify_dataset(args.root, checksums=not args.quick, progress=sys.stderr.isatty())
    if manifest is None:
        raise DatasetError(problems[0])
    print(f"{args.root}: {manifest.dataset}/{manifest.preset}, format v{FORMAT_VERSION}, "
          f"{manifest.image_size}px, {len(manifest.subjects)} subjects, {len(manifest.part_names)} parts")
    for split, info in manifest.splits.items():
        count = info.totals()
        print(f"  {split:<6} {len(info.shards)}/{info.planned_shards} shards, {count['images']} images, "
              f"{count['quadruplets']} quadruplets, {count['meshes']} meshes")
    for p in problems:
        print(f"problem: {p}", file=sys.stderr)
    print("ok" if not problems else f"{len(problems)} problem(s)")
    return 1 if problems else 0


def run_show(args: argparse.Namespace) -> int:
    from cerberus_core.datasets.manifest import Manifest
    from cerberus_core.datasets.show import save_contact_sheet
    from cerberus_core.plugins import RENDERER_GROUP, get_plugin
    from cerberus_core.render.backends import AUTO_RENDERER

    for option, value, most in (("--count", args.count, MAX_SHOW_COUNT), ("--scale", args.scale, MAX_SHOW_SCALE)):
        if value > most:
            raise ConfigError(f"{option} {value}: at most {most}")
    Manifest.read(args.root).split(args.split)
    out = output_file(args.out or args.root / f"contact_{args.split}.png")
    if args.renderer != AUTO_RENDERER:
        get_plugin(RENDERER_GROUP, args.renderer)  # a known backend, even without --parts
    save_contact_sheet(args.root, out, split=args.split, count=args.count, parts=args.parts,
                       renderer=args.renderer, scale=args.scale)
    print(f"contact sheet written to {out}")
    return 0
