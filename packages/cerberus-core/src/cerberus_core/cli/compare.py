"""``cerberus compare``: several evaluations of one test set side by side, each paired image by image with the
first (:mod:`cerberus_core.eval.compare`)."""
from __future__ import annotations

import argparse
from pathlib import Path

from cerberus_core.cli.flags import FlagNames

EXAMPLES = """examples:
  cerberus compare runs/baseline runs/new                    # two run folders, each evaluated by cerberus eval
  cerberus compare NMRr=eval/nmrr Cerberus=runs/cpu --plot pairs.png
  cerberus compare runs/a/eval/results.json runs/b/eval/results.json"""


def configure(p: argparse.ArgumentParser) -> None:
    """The arguments, description and examples of ``cerberus compare`` (:data:`cerberus_core.cli.COMMANDS`)."""
    p.description = ("Is one model better than another on the same test images? Reads the results.json of each "
        "evaluation (`cerberus eval`) and prints a Markdown table: per evaluation the images it scored, its mean "
        "voxel IoU and, where the evaluations have them, Hard Human and the voxel precision and recall (each the "
        "mean over its images of the per-image value), each beside its paired difference to the first evaluation: "
        "the mean over the images both scored of the per-image difference, its standard error, and how many images "
        "it is better on (`mean ± s.e. (better / images)`). "
        "Pairing removes what the images share (a hard pose is hard for both models), so two models a few "
        "thousandths apart can be told apart. Evaluations of different test sets are refused.")
    p.epilog = EXAMPLES
    p.add_argument("evaluations", nargs="+", metavar="[NAME=]EVAL",
                   help="an evaluation: a results.json, the folder cerberus eval wrote it to (--out), or a run folder "
                        "evaluated into its eval/; NAME (default: the run's folder name) labels its row. The first "
                        "is the baseline")
    p.add_argument("--plot", type=Path, metavar="PNG",
                   help="also draw each image's voxel IoU under every evaluation against the first's (a point "
                        "above the diagonal: an image it scores better)")
    p.set_defaults(func=run, flag_names=FlagNames({"path": "EVAL", "evaluations": "EVAL", "plot": "--plot"}))


def _named(items: list[str]) -> dict[str, Path]:
    """``[NAME=]PATH`` arguments as ``{name: path}``: a name given before ``=`` (unless the whole argument is an
    existing path), else :func:`~cerberus_core.eval.compare.evaluation_name`."""
    from cerberus_core.errors import ConfigError
    from cerberus_core.eval.compare import evaluation_name

    named: dict[str, Path] = {}
    for item in items:
        name, eq, path = item.partition("=")
        if not eq or not name or Path(item).exists():
            name, path = evaluation_name(item), item
        if name in named:
            raise ConfigError.about("evaluations", item, f"a second evaluation named {name!r}; name each one: "
                                    "NAME=PATH")
        named[name] = Path(path)
    return named


def run(args: argparse.Namespace) -> int:
    from cerberus_core.errors import ConfigError
    from cerberus_core.eval.compare import comparison_rows, evaluation_file, load_evaluation
    from cerberus_core.eval.markdown import markdown_table
    from cerberus_core.plumbing.outputs import output_file

    if len(args.evaluations) < 2:
        raise ConfigError.about("evaluations", " ".join(args.evaluations),
                                "compare needs two evaluations or more, the baseline first")
    named = _named(args.evaluations)
    if args.plot is not None:  # checked before anything is read
        output_file(args.plot, "plot", [evaluation_file(p) for p in named.values()])
    evaluations = {name: load_evaluation(path) for name, path in named.items()}
    header, rows = comparison_rows(evaluations)
    print(markdown_table(header, rows))
    first = next(iter(evaluations))
    pooled = (" (precision and recall too, not the figures pooled over all voxels of its results.md)"
              if "precision" in header or "recall" in header else "")
    print(f"\nEach value: the mean over the evaluation's images of the per-image value{pooled}. Δ: the paired "
          f"difference to {first}, the mean over the images both scored of each image's difference (of the same "
          "images, the difference of the two means), ± its standard error (images where it is higher / images both "
          "scored)")
    if args.plot is not None:
        from cerberus_core.eval.figures import paired_plot  # torch and the renderer: only for a plot

        print(f"plot: {paired_plot(evaluations, args.plot)}")
    return 0
