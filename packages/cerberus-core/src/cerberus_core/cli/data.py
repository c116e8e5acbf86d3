"""``cerberus data``: generate, check and look at datasets (docs/data_format.md): each sub-command is
its arguments and one call of :class:`~cerberus_core.datasets.dataset.Dataset`; what is left to generate is said
as a command line by :mod:`cerberus_core.cli.datasets`."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cerberus_core.cli.checks import OVERWRITE_HELP, positive_int
from cerberus_core.cli.datasets import CONFIG_FLAGS, finish, source_flags
from cerberus_core.cli.flags import FlagNames

GENERATE_HELP = """Generate a dataset into --out. Rerunning the same command resumes an interrupted run without
redoing finished shards; --overwrite replaces a different dataset that cerberus data generate wrote there. A
folder holding anything else is refused, --overwrite or not (what --out may replace: docs/outputs.md).

--dataset names a body source registered under the cerberus.bodies entry points (docs/bodies.md); the core's:
  human:      large (the paper's 19,500 train pairs / 5 subjects with small's test split:
              the data of the shipped human model, about half an hour on 2 cores),
              paper (19,500 train pairs / 5 subjects; 810 test poses x 4 views / 2 subjects),
              small (1,000 pairs; 50 test poses, a few minutes on a CPU), tiny (seconds),
              heldout_poses (test only: small's 2 test subjects in 36 poses each of six families
              no training generator makes, plus the canonical pose; 296 images)
  animal:     paper (41 species x 47 poses x 4 views, 38,540 quadruplets; 984 test views),
              small (12 species), tiny
  primitives: capsule figures with the human presets' structure (paper, small, tiny)
  folder:     your meshes (--source DIR): pairs (the Human protocol), grid (the Animal protocol)

--set KEY=VALUE changes any key of the resolved config (values are YAML; see it with
--print-config): seed, image_size, renderer, shard_images, scene.<field>,
splits.<split>.<field>, e.g. --set splits.train.pairs=2000 --set scene.elevation=20"""


def configure(p: argparse.ArgumentParser) -> None:
    """The arguments, description and examples of ``cerberus data`` (:data:`cerberus_core.cli.COMMANDS`)."""
    p.description = ("Render the paper's datasets on this machine (nothing is downloaded): "
                       "quadruplets of one body in 2 poses from 2 viewpoints for training, single views with "
                       "ground-truth meshes and part labels for testing.")
    dsub = p.add_subparsers(dest="data_command", metavar="ACTION")
    dsub.required = True
    _add_generate(dsub)
    _add_check(dsub)
    _add_show(dsub)


def _add_generate(dsub: argparse._SubParsersAction) -> None:
    """``cerberus data generate``: what to generate, the config keys with flags of their own, the body source's
    options, then how to run it."""
    from cerberus_core.datasets.settings import GenerationConfig

    g = dsub.add_parser("generate", help="generate (or resume) a dataset", description=GENERATE_HELP)
    _add_what(g)
    options = _add_source_options(g.add_argument_group("body source options", "a source's own flags (the folder "
                                                      "source's); any source's option is --option KEY=VALUE"))
    _add_config_flags(g)
    _add_how(g)
    g.set_defaults(func=run_generate, source_flags=options, flag_names=FlagNames({
        **CONFIG_FLAGS, **{key: flag.flag for key, flag in options.items()}, "dataset": "--dataset", "size": "--size",
        "overrides": "--set", "out": "--out", "overwrite": "--overwrite", "batch_size": "--batch-size",
        "device": "--device"}, GenerationConfig))


def _add_what(g: argparse.ArgumentParser) -> None:
    g.add_argument("--dataset", required=True, metavar="SOURCE", help="body source: human, animal, primitives, "
                   "folder or an installed plugin's")
    g.add_argument("--size", default=None, metavar="NAME",
                   help="size preset: human: heldout_poses, large, paper, small, small128, small_faithful, tiny; animal: paper, "
                   "small, small128, small_faithful, tiny; primitives: paper, small, tiny; folder: pairs, grid; default "
                   "small (folder: pairs)")
    g.add_argument("--preset", dest="size_alias", default=None, help=argparse.SUPPRESS)  # deprecated: --size
    g.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key, e.g. --set splits.train.pairs=2000 (repeatable; values are YAML)")
    g.add_argument("--out", type=Path, required=True, help=f"dataset folder to create or resume; {OVERWRITE_HELP}")


def _add_source_options(g: argparse._ArgumentGroup) -> dict:
    """The flags the installed body sources declare for their options (:func:`~cerberus_core.cli.datasets.source_flags`),
    each stored as ``option:KEY``, and ``--option KEY=VALUE``; returns ``{option: its OptionFlag}``."""
    options = source_flags()
    said = FlagNames({key: flag.flag for key, flag in options.items()})  # `test_fraction` in a help: --test-fraction
    for key, flag in options.items():
        g.add_argument(flag.flag, dest=f"option:{key}", metavar=flag.metavar, help=said.text(flag.help),
                       type=_comma_list if flag.listed else None)
    g.add_argument("--option", dest="options", action="append", default=[], metavar="KEY=VALUE",
                   help="any option of the body source (repeatable; values are YAML)")
    return options


def _comma_list(text: str) -> list[str]:
    return [item.strip() for item in text.split(",") if item.strip()]


def _add_config_flags(g: argparse.ArgumentParser) -> None:
    g.add_argument("--renderer", help="renderer backend: warp, torch or auto (default: auto, warp if it works, else "
                   "torch); same as --set renderer=...")
    g.add_argument("--image-size", type=int, help="image size in pixels (default 64); same as --set image_size=...")
    g.add_argument("--seed", type=int, help="seed of every random choice (default 0); same as --set seed=...")
    g.add_argument("--shard-images", type=int, help="images per shard (default 1024); same as --set shard_images=...")


def _add_how(g: argparse.ArgumentParser) -> None:
    g.add_argument("--batch-size", type=positive_int, default=64, help="views per render call (default 64; no effect on output)")
    g.add_argument("--device", default="cpu", help="torch device for posing and rendering (default cpu)")
    g.add_argument("--overwrite", action="store_true", help="replace a different dataset that cerberus data generate wrote in --out (only its own files)")
    g.add_argument("--dry-run", action="store_true", help="print the plan (counts per split) and exit")
    g.add_argument("--print-config", action="store_true", help="print the resolved config (YAML) and exit")
    g.add_argument("--quiet", action="store_true", help="no progress bar")


def _add_check(dsub: argparse._SubParsersAction) -> None:
    c = dsub.add_parser("check", help="verify a dataset's checksums and report its contents",
                        description="Verify the manifest (format version, paths), every shard file (size, sha256, "
                        "array shapes) and completeness. Exit status 1 on any problem.")
    c.add_argument("root", type=Path, help="dataset folder")
    c.add_argument("--quick", action="store_true", help="sizes and headers only, no sha256")
    c.set_defaults(func=run_check)


def _add_show(dsub: argparse._SubParsersAction) -> None:
    s = dsub.add_parser("show", help="write a contact sheet PNG of a split",
                        description="Rows of quadruplets (a0 a1 b0 b1) for training splits, or the views of each "
                        "pose for test splits; --parts adds the ground-truth parts in colour.")
    s.add_argument("root", type=Path, help="dataset folder")
    s.add_argument("--split", default="train", help="split to show (default train)")
    s.add_argument("--out", type=Path, help="PNG path (default: ROOT/contact_<split>.png)")
    s.add_argument("--count", type=positive_int, default=8, help="rows, 1..256 (default 8)")
    s.add_argument("--parts", action="store_true", help="add ground-truth part renderings")
    s.add_argument("--scale", type=positive_int, default=2, help="tile upscaling, 1..16 (default 2)")
    s.add_argument("--renderer", default="auto", help="backend for --parts (default auto: warp, else torch)")
    s.set_defaults(func=run_show, flag_names=FlagNames({"out": "--out", "split": "--split", "renderer": "--renderer",
                                                        "count": "--count", "scale": "--scale"}))


def generation_request(args: argparse.Namespace):  # noqa: ANN201 - a GenerationRequest (imported lazily)
    """The dataset the flags ask for: --dataset, --size, the config keys (--seed, --image-size, --renderer,
    --shard-images, then --set, which wins) and the body source's options (its flags, then --option KEY=VALUE;
    the source's ``Options`` check them). The inverse of :func:`generate_command`."""
    from cerberus_core.config import flatten, parse_overrides
    from cerberus_core.datasets.plan import SET_EXAMPLE, GenerationRequest

    config = {key: value for key in CONFIG_FLAGS if (value := getattr(args, key)) is not None}
    options = {key: value for key in args.source_flags if (value := getattr(args, f"option:{key}")) is not None}
    size = args.size if args.size is not None else args.size_alias  # --size "" is refused, not the default size
    return GenerationRequest(args.dataset, size,
                             {**config, **flatten(parse_overrides(args.overrides, example=SET_EXAMPLE))},
                             {**options, **parse_overrides(args.options, example="root=DIR")})


def run_generate(args: argparse.Namespace) -> int:
    """Every argument is checked before --dry-run returns and before the folder's lock or manifest is written."""
    import yaml

    from cerberus_core.datasets.dataset import Dataset

    if args.size_alias is not None:
        print("cerberus data generate: --preset is deprecated here, use --size (a dataset size; training "
              "recipes are `cerberus train --preset`)", file=sys.stderr)
    request = generation_request(args)
    if args.print_config:
        print(yaml.safe_dump(request.config().to_dict(), sort_keys=False), end="")
        return 0
    how = dict(overwrite=args.overwrite, device=args.device, batch_size=args.batch_size)
    if args.dry_run:
        print("\n".join(Dataset.plan(request, args.out, **how).plan_lines()))
        return 0
    dataset = Dataset.generate(request, args.out, progress=not args.quiet, **how)
    print(*(f"{split:<6} {info.planned_images:>8} images {info.planned_quadruplets:>8} quadruplets"
            for split, info in dataset.manifest.splits.items()), f"dataset written to {args.out}", sep="\n")
    return 0


def run_check(args: argparse.Namespace) -> int:
    """Exit 2 when ROOT is not a readable dataset (bad input), 1 when the dataset has problems."""
    from cerberus_core.datasets.dataset import Dataset

    dataset = Dataset.open(args.root)
    problems = dataset.verify(checksums=not args.quick, progress=sys.stderr.isatty())
    print("\n".join(dataset.summary()))
    left = set(dataset.incomplete().values())
    for p in problems:
        print(f"problem: {p}" + (f"; {finish(dataset)}" if p in left else ""), file=sys.stderr)
    print("ok" if not problems else f"{len(problems)} problem(s)")
    return 1 if problems else 0


def run_show(args: argparse.Namespace) -> int:
    from cerberus_core.datasets.dataset import Dataset

    out = Dataset.open(args.root).contact_sheet(args.out, split=args.split, count=args.count, parts=args.parts,
                                                renderer=args.renderer, scale=args.scale)
    print(f"contact sheet written to {out}")
    return 0
