"""``cerberus compare``: several evaluations of one test set side by side, each paired image by image with the
first (:mod:`cerberus_core.eval.compare`)."""
from __future__ import annotations

import argparse
from pathlib import Path

from cerberus_core.cli.flags import FlagNames

EXAMPLES = """examples:
  cerberus compare runs/baseline runs/new                    # two run folders, each evaluated by cerberus eval
  cerberus compare NMRr=eval/nmrr Cerberus=runs/cpu --plot pairs.png
  cerberus compare runs/a/eval/results.json runs/b/eval/results.json
  cerberus compare cpu=runs/parts/cpu mix=runs/parts/mix --columns parts,depth,training --trade-plot trade.png"""


def _column_help() -> str:
    """The epilog's list of the column groups, one line each (:data:`~cerberus_core.eval.compare.COLUMN_GROUPS`)."""
    from cerberus_core.eval.compare import COLUMN_GROUPS

    width = max(len(group.name) for group in COLUMN_GROUPS)
    return "column groups (--columns, comma-separated; added after the paired columns):\n" + "\n".join(
        f"  {group.name:<{width}}  {group.summary}" for group in COLUMN_GROUPS)


def _eval_flags() -> dict[str, str]:
    """``{setting: cerberus eval's flag}`` of each setting that chooses what two evaluations must share
    (:data:`~cerberus_core.eval.compare.MEASUREMENT`, each :attr:`~cerberus_core.eval.compare.Setting.choices`):
    ``{"gt_open_mesh": "--gt-open-mesh", ..., "data": "--data", "split": "--split"}``."""
    from cerberus_core.eval.compare import MEASUREMENT

    return {key: f"--{key.replace('_', '-')}" for setting in MEASUREMENT for key in setting.choices}


def configure(p: argparse.ArgumentParser) -> None:
    """The arguments, description and examples of ``cerberus compare`` (:data:`cerberus_core.cli.COMMANDS`)."""
    p.description = ("Is one model better than another on the same test images? Reads the results.json of each "
        "evaluation (`cerberus eval`) and prints a Markdown table: per evaluation the images it scored, its mean "
        "voxel IoU and, where the evaluations have them, Hard Human and the voxel precision and recall (each the "
        "mean over its images of the per-image value), each beside its paired difference to the first evaluation: "
        "the mean over the images both scored of the per-image difference, its standard error, and how many images "
        "it is better on (`mean ± s.e. (better / images)`). "
        "Pairing removes what the images share (a hard pose is hard for both models), so two models a few "
        "thousandths apart can be told apart. Evaluations of different test sets, or measured under different "
        f"settings (cerberus eval's {', '.join(_eval_flags().values())}), are refused. --columns adds "
        "groups of columns that compare runs beyond the IoU (their parts, depth, training, own training images, "
        "held-out pose families), one row per run as before.")
    p.epilog = f"{_column_help()}\n\n{EXAMPLES}"
    p.add_argument("evaluations", nargs="+", metavar="[NAME=]EVAL",
                   help="an evaluation: a results.json, the folder cerberus eval wrote it to (--out), or a run folder "
                        "evaluated into its eval/; NAME (default: the run's folder name) labels its row. The first "
                        "is the baseline")
    p.add_argument("--plot", type=Path, metavar="PNG",
                   help="also draw each image's voxel IoU under every evaluation against the first's (a point "
                        "above the diagonal: an image it scores better)")
    p.add_argument("--columns", default="", metavar="GROUPS",
                   help="also show these column groups, comma-separated (listed below): what each evaluation's "
                        "results.json measured beyond the IoU, and what its run folder holds")
    p.add_argument("--trade-plot", type=Path, metavar="PNG",
                   help="also draw each evaluation's mean voxel IoU against its Hard Human IoU, one labelled point "
                        "each (the trade between fitting each image and parts that hold across poses)")
    p.set_defaults(func=run, flag_names=FlagNames({"path": "EVAL", "evaluations": "EVAL", "plot": "--plot",
                                                   "columns": "--columns", "trade_plot": "--trade-plot",
                                                   **{key: f"cerberus eval {flag}" for key, flag in
                                                      _eval_flags().items()}}))


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
    from cerberus_core.eval.compare import column_groups, comparison_rows, evaluation_file, load_evaluation, run_folder
    from cerberus_core.eval.markdown import markdown_table
    from cerberus_core.plumbing.outputs import output_file

    if len(args.evaluations) < 2:
        raise ConfigError.about("evaluations", " ".join(args.evaluations),
                                "compare needs two evaluations or more, the baseline first")
    named = _named(args.evaluations)
    groups = column_groups(args.columns)  # checked before anything is read, as the plots' paths
    for key, plot in (("plot", args.plot), ("trade_plot", args.trade_plot)):
        if plot is not None:
            output_file(plot, key, [evaluation_file(p) for p in named.values()])
    evaluations = {name: load_evaluation(path) for name, path in named.items()}
    header, rows = comparison_rows(evaluations, [group.name for group in groups],
                                   {name: run_folder(path) for name, path in named.items()})
    print(markdown_table(header, rows))
    first = next(iter(evaluations))
    pooled = (" (precision and recall too, not the figures pooled over all voxels of its results.md)"
              if "precision" in header or "recall" in header else "")
    print(f"\nEach value: the mean over the evaluation's images of the per-image value{pooled}. Δ: the paired "
          f"difference to {first}, the mean over the images both scored of each image's difference (of the same "
          "images, the difference of the two means), ± its standard error (images where it is higher / images both "
          "scored)" + (f". Then the columns of {', '.join(g.name for g in groups)} (cerberus compare --help)"
                       if groups else ""))
    _plots(args, evaluations)
    return 0


def _plots(args: argparse.Namespace, evaluations: dict) -> None:
    """The figures asked for, each path printed (torch and the renderer are imported only for one)."""
    if args.plot is None and args.trade_plot is None:
        return
    from cerberus_core.eval.figures import paired_plot, trade_plot

    if args.plot is not None:
        print(f"plot: {paired_plot(evaluations, args.plot)}")
    if args.trade_plot is not None:
        print(f"trade plot: {trade_plot(evaluations, args.trade_plot)}")
