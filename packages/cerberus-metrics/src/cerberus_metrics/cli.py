"""Command line: ``cerberus-metrics {iou,chamfer,fscore,check,batch,protocols}``.

Exit codes: 0 success; 1 a batch finished but some pairs failed (see the summary);
2 bad input (the message names the file or argument, the problem and the fix);
3 internal error. Every error is one line on stderr; outputs are written atomically.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from . import __version__
from .api import METRICS, evaluate_pair, inspect_mesh
from .batch import (
    check_not_input,
    check_output_path,
    check_replaceable,
    pairs_from_file,
    pairs_from_folders,
    run_batch,
    write_results,
)
from .distances import MAX_SAMPLES
from .io import MeshInputError, MeshQualityWarning
from .protocols import PROTOCOLS

_DESCRIPTION = """\
Voxel IoU (Kato et al. / Perspective Transformer Nets 32^3 protocol), Chamfer-L2 and
F-score between a predicted mesh (or the union of its parts) and a ground-truth mesh.
Meshes are read and cleaned with pymeshlab (OBJ, PLY, STL, OFF, GLB/GLTF, ...).

Protocols (--protocol):
""" + "\n".join(f"  {p.name:15s} {p.summary}" for p in PROTOCOLS.values()) + """

Examples:
  cerberus-metrics iou pred.obj gt.obj
  cerberus-metrics iou head.ply torso.ply legs.ply gt.ply --json     (3 parts)
  cerberus-metrics iou pred.obj gt.obj --protocol gt_bbox --resolution 64
  cerberus-metrics fscore pred.obj gt.obj --threshold 0.01 --normalize
  cerberus-metrics batch --pred-dir preds/ --gt-dir gts/ --out results.json --csv results.csv
  cerberus-metrics batch --pairs pairs.csv --metrics voxel_iou,chamfer_l2,fscore
  cerberus-metrics check gt.obj                     (validate and clean; report defects)

Run 'cerberus-metrics COMMAND --help' for a command's description, options and examples.
Exit codes: 0 success, 1 a batch finished with failed pairs, 2 bad input, 3 internal error.
"""


class UsageError(Exception):
    """Bad command-line arguments; the message names the argument and the fix."""


class _Parser(argparse.ArgumentParser):
    """argparse, but an argument error is raised (one line on stderr, exit code 2, from main)."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: {message}; see '{self.prog} --help'")


def _int_in(lo: int, hi: int | None, what: str) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer ({what})") from None
        if value < lo or (hi is not None and value > hi):
            rng = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
            raise argparse.ArgumentTypeError(f"{value} is out of range: {what} must be {rng}")
        return value

    return parse


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text} must be a positive finite number (mesh units)")
    return value


def _add_mesh_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--open-mesh",
        choices=("warn", "close", "error"),
        default="warn",
        help="non-watertight meshes: evaluate as is with a warning (default), close holes with pymeshlab, "
        "or fail",
    )
    p.add_argument(
        "--no-self-intersection-check",
        action="store_true",
        help="skip pymeshlab's self-intersection test (faster; no self-intersection warnings)",
    )


def _add_voxel_options(p: argparse.ArgumentParser, outside: str = "error") -> None:
    p.add_argument("--protocol", choices=list(PROTOCOLS), default="kato", help="voxel protocol (default: kato)")
    p.add_argument(
        "--resolution",
        type=_int_in(2, 1024, "voxels per grid side"),
        default=32,
        help="voxels per grid side, 2..1024 (default: 32, the paper's)",
    )
    other = "error" if outside == "clamp" else "clamp"
    what = {"error": "fail", "clamp": "clamp it to the grid, one rule for faces, edges and corners (its voxels "
            "outside are dropped), and count it"}
    p.add_argument(
        "--outside",
        choices=("error", "clamp"),
        default=outside,
        help=f"kato protocol, a prediction part reaching outside the grid: {what[outside]} (default"
        f"{', as cerberus eval scores' if outside == 'clamp' else ''}), or {what[other]}",
    )


def _add_sampling_options(p: argparse.ArgumentParser, threshold: bool) -> None:
    p.add_argument(
        "--samples",
        type=_int_in(1, MAX_SAMPLES, "points per surface"),
        default=100_000,
        help=f"points sampled per surface, 1..{MAX_SAMPLES} (default: 100000; Chamfer-L2 and the F-score depend on "
        "it: compare numbers measured with the same --samples)",
    )
    p.add_argument("--seed", type=_int_in(0, None, "sampling seed"), default=0,
                   help="sampling seed; the GT uses seed+1 (default: 0)")
    p.add_argument(
        "--normalize", action="store_true", help="scale both shapes by the GT bounding box (longest side 1) first"
    )
    if threshold:
        p.add_argument("--threshold", type=_positive_float, default=0.01,
                       help="F-score distance threshold in mesh units (default: 0.01)")


_PAIR_TEXT = {
    "iou": (
        "voxel IoU of one pair",
        "Voxel IoU |P & G| / |P | G| between a prediction (one mesh, or several files that are the parts of\n"
        "one prediction, united) and a ground truth (the last file). Default: the paper's kato protocol at 32^3\n"
        "(meshes in [-0.5, 0.5]^3); use --protocol gt_bbox for meshes in other coordinates. Prints the IoU.",
        "  cerberus-metrics iou pred.obj gt.obj\n"
        "  cerberus-metrics iou head.ply torso.ply legs.ply gt.ply --json      (3 parts)\n"
        "  cerberus-metrics iou pred.obj gt.obj --protocol gt_bbox --resolution 64",
    ),
    "chamfer": (
        "Chamfer-L2 of one pair",
        "Chamfer-L2 = mean squared nearest distance prediction->GT plus GT->prediction, on points sampled\n"
        "uniformly by area (--samples per surface), in mesh units squared (GT-relative with --normalize).",
        "  cerberus-metrics chamfer pred.obj gt.obj\n"
        "  cerberus-metrics chamfer pred.obj gt.obj --normalize --samples 20000 --json",
    ),
    "fscore": (
        "F-score at a distance threshold of one pair",
        "F-score = 2PR/(P+R): P = share of prediction points within --threshold of the GT points, R the other\n"
        "way (sampled surfaces; threshold in mesh units, or relative to the GT size with --normalize).",
        "  cerberus-metrics fscore pred.obj gt.obj --threshold 0.01 --normalize\n"
        "  cerberus-metrics fscore part1.obj part2.obj gt.obj --json",
    ),
}

_CHECK_DESCRIPTION = """\
Read each mesh with pymeshlab, validate it and clean it (duplicate vertices, duplicate faces,
zero-area faces, unreferenced vertices), then report what cleaning removed and what is still
wrong: watertightness (boundary edges), non-manifold edges and vertices, self-intersecting
faces. A file that cannot be evaluated (unreadable, empty, NaN coordinates, face indices out
of range, all vertices equal) is an error (exit code 2) naming the file and the fix.
A file holding several meshes (e.g. a GLB scene) gives one report per mesh."""

_BATCH_DESCRIPTION = """\
Evaluate many pairs in parallel. Pairs come from --pairs (a CSV with a header pred,gt[,id],
parts of one prediction separated by ';'; or a JSON list of {"id"?, "pred": path | [paths],
"gt": path}); relative paths are relative to the pairs file's folder. Or from --pred-dir and
--gt-dir, matched by file stem (a sub-folder of --pred-dir named like a ground truth holds the
parts of its prediction). A pair that fails is reported and counted, never aborts the batch;
the exit code is then 1. --out and --csv are written only when the batch is complete."""

_BATCH_EXAMPLES = """\
  cerberus-metrics batch --pred-dir preds/ --gt-dir gts/ --out results.json --csv results.csv
  cerberus-metrics batch --pairs pairs.csv --metrics voxel_iou,chamfer_l2,fscore --jobs 4
  cerberus-metrics batch --pairs pairs.json --cache-dir grid-cache/ --json"""


def _sub(sub: Any, name: str, help: str, description: str, examples: str) -> argparse.ArgumentParser:
    return sub.add_parser(
        name,
        help=help,
        description=description,
        epilog="Examples:\n" + examples,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="cerberus-metrics", description=_DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    pair_help = "PRED [PRED ...] GT: one or more prediction files (parts, united) then the ground-truth file"
    for name, (helptext, description, examples) in _PAIR_TEXT.items():
        p = _sub(sub, name, helptext, description + "\n\n" + pair_help + ".", examples)
        p.add_argument("meshes", nargs="+", metavar="MESH", help=pair_help)
        if name == "iou":
            _add_voxel_options(p)
        else:
            _add_sampling_options(p, threshold=name == "fscore")
        _add_mesh_options(p)
        p.add_argument("--json", action="store_true", help="print the result as JSON")

    p = _sub(
        sub,
        "check",
        "validate and clean meshes with pymeshlab; report watertightness, manifoldness, self-intersections",
        _CHECK_DESCRIPTION,
        "  cerberus-metrics check gt.obj\n  cerberus-metrics check preds/*.ply --json",
    )
    p.add_argument("meshes", nargs="+", metavar="MESH", help="mesh files to check")
    p.add_argument("--json", action="store_true", help="print the reports as JSON")

    p = _sub(sub, "batch", "evaluate many pairs on all cores", _BATCH_DESCRIPTION, _BATCH_EXAMPLES)
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--pairs", help="CSV (columns id,pred,gt; parts separated by ';') or JSON list of pairs")
    src.add_argument("--pred-dir", help="folder of predictions (a file, or a sub-folder of parts, per GT stem)")
    p.add_argument("--gt-dir", help="folder of ground truths (with --pred-dir)")
    p.add_argument(
        "--metrics", default="voxel_iou", help=f"comma-separated, from {','.join(METRICS)} (default: voxel_iou)"
    )
    _add_voxel_options(p, outside="clamp")
    _add_sampling_options(p, threshold=True)
    _add_mesh_options(p)
    p.add_argument("--jobs", type=_int_in(1, None, "worker processes"), default=None,
                   help="worker processes, >= 1 (default: all cores)")
    p.add_argument("--cache-dir", default=None, help="folder for cached ground-truth grids (content-hashed)")
    p.add_argument("--no-cache", action="store_true", help="voxelize every ground truth anew (no grid cache)")
    replaced = ("; an existing file is replaced only when it is results batch wrote, anything else is refused "
                "(what --out may replace: docs/outputs.md)")
    p.add_argument("--out", default=None, help="write summary and per-pair results as JSON here" + replaced)
    p.add_argument("--csv", default=None, help="write per-pair results as CSV here" + replaced)
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.add_argument("--json", action="store_true", help="print summary and pairs as JSON on stdout")

    _sub(sub, "protocols", "list the voxel protocols", "List the voxel-IoU protocols and what each does.",
         "  cerberus-metrics protocols")
    return parser


_OPTION = re.compile(r"\b(outside|open_mesh|protocol)='([a-z_]+)'")


def _in_cli_terms(text: str) -> str:
    """A library message with its options said as this command's flags (``outside='clamp'`` -> ``--outside clamp``).

    >>> _in_cli_terms("pass outside='clamp' to clamp it, or use open_mesh='close'")
    'pass --outside clamp to clamp it, or use --open-mesh close'
    """
    return _OPTION.sub(lambda m: f"--{m.group(1).replace('_', '-')} {m.group(2)}", text)


def _split_pair(meshes: Sequence[str]) -> tuple[Any, str]:
    if len(meshes) < 2:
        raise MeshInputError("give at least two meshes: PRED [PRED ...] GT (the last one is the ground truth)")
    pred = list(meshes[:-1])
    return (pred if len(pred) > 1 else pred[0]), meshes[-1]


def _mesh_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    return {"open_mesh": args.open_mesh, "check_self_intersections": not args.no_self_intersection_check}


def _run_pair(args: argparse.Namespace) -> int:
    pred, gt = _split_pair(args.meshes)
    metric = {"iou": "voxel_iou", "chamfer": "chamfer_l2", "fscore": "fscore"}[args.command]
    kwargs: dict[str, Any] = _mesh_kwargs(args)
    if metric == "voxel_iou":
        kwargs.update(protocol=args.protocol, resolution=args.resolution, outside=args.outside)
    else:
        kwargs.update(n_samples=args.samples, seed=args.seed, normalize=args.normalize)
        if metric == "fscore":
            kwargs["threshold"] = args.threshold
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeshQualityWarning)
        result = evaluate_pair(pred, gt, [metric], **kwargs)
    notes = sorted({_in_cli_terms(str(w.message)) for w in caught})
    for n in notes:
        print(f"warning: {n}", file=sys.stderr)
    if result.get("clamped_parts"):
        print(f"warning: {result['clamped_parts']} prediction part(s) reached outside the {args.protocol} grid "
              "and were clamped to it (their voxels outside were dropped)", file=sys.stderr)
    if args.json:
        settings = {k: v for k, v in kwargs.items()}
        print(json.dumps({"pred": args.meshes[:-1], "gt": gt, **result, "settings": settings, "warnings": notes}))
    else:
        print(f"{result[metric]:.6f}")
    return 0


def _run_check(args: argparse.Namespace) -> int:
    reports = []
    for path in args.meshes:
        reports += [r.to_dict() for r in inspect_mesh(path, name="mesh")]
    if args.json:
        print(json.dumps(reports, indent=2))
    else:
        for r in reports:
            state = "watertight" if r["watertight"] else "NOT watertight"
            print(
                f"{r['name']}: {r['vertices']} vertices, {r['faces']} faces, {state}; boundary edges "
                f"{r['boundary_edges']}, non-manifold edges {r['non_manifold_edges']}, non-manifold vertices "
                f"{r['non_manifold_vertices']}, self-intersecting faces {r['self_intersecting_faces']}; removed: "
                f"{r['removed_duplicate_vertices']} duplicate vertices, {r['removed_unreferenced_vertices']} "
                f"unreferenced vertices, {r['removed_null_faces']} zero-area faces, "
                f"{r['removed_duplicate_faces']} duplicate faces"
            )
    return 0


def _run_batch(args: argparse.Namespace) -> int:
    # Everything is made absolute and checked before any work, so nothing (not even a library
    # changing the working directory) can redirect an input or an output, and bad arguments
    # fail before a single pair runs or a file is created.
    metrics = [m.strip() for m in args.metrics.split(",") if m.strip()]
    unknown = sorted(set(metrics) - set(METRICS)) or ([] if metrics else ["(none)"])
    if unknown:
        raise MeshInputError(f"--metrics: unknown metric(s) {unknown}; choose from {','.join(METRICS)}")
    out = check_output_path(args.out, "--out") if args.out else None
    csv_out = check_output_path(args.csv, "--csv") if args.csv else None
    if out and csv_out and out == csv_out:
        raise MeshInputError(f"--out and --csv are the same file '{args.out}'; give them different names")
    cache_dir = None
    if args.cache_dir:
        cache_dir = os.path.abspath(args.cache_dir)
        if os.path.exists(cache_dir) and not os.path.isdir(cache_dir):
            raise MeshInputError(f"--cache-dir '{args.cache_dir}' is a file; pass a folder (it is created if missing)")
    if args.pairs:
        if args.gt_dir:
            raise MeshInputError("--gt-dir goes with --pred-dir, not with --pairs; drop one of them")
        pairs = pairs_from_file(args.pairs)
    else:
        if not args.gt_dir:
            raise MeshInputError("--pred-dir needs --gt-dir (the folder of ground truths)")
        pairs = pairs_from_folders(args.pred_dir, args.gt_dir)
    if not pairs:
        raise MeshInputError("no pairs found; check the pairs file or the folders (mesh files by suffix)")
    check_not_input({"--out": args.out, "--csv": args.csv}, pairs, [args.pairs] if args.pairs else [],
                    folders={"--cache-dir": args.cache_dir})
    check_replaceable({"--out": args.out, "--csv": args.csv})
    result = run_batch(
        pairs,
        metrics,
        jobs=args.jobs,
        cache_dir=cache_dir,
        use_cache=not args.no_cache,
        progress=not args.no_progress,
        protocol=args.protocol,
        resolution=args.resolution,
        outside=args.outside,
        n_samples=args.samples,
        seed=args.seed,
        threshold=args.threshold,
        normalize=args.normalize,
        **_mesh_kwargs(args),
    )
    for row in [*result.rows, *result.summary["failures"]]:  # what a message tells to set is a flag here
        if row.get("error"):
            row["error"] = _in_cli_terms(row["error"])
        if row.get("warnings"):
            row["warnings"] = [_in_cli_terms(w) for w in row["warnings"]]
    write_results(result, out, csv_out)
    s = result.summary
    if args.json:
        print(json.dumps({"summary": s, "pairs": result.rows}, indent=2))
    else:
        _print_summary(s, args.protocol)
    return 1 if s["failed"] else 0


def _print_summary(s: dict[str, Any], protocol: str) -> None:
    """The batch summary (:func:`~cerberus_metrics.batch.summarize`) as lines: each metric's mean over all pairs
    (a failed pair scored 0) beside its mean over the pairs that succeeded, named apart; failures on stderr."""
    print(f"pairs: {s['pairs']}  succeeded: {s['succeeded']}  failed: {s['failed']}  "
          f"with warnings: {s['pairs_with_warnings']}")
    if s["pairs_clamped"]:
        print(f"clamped: {s['pairs_clamped']} pairs ({s['parts_clamped']} prediction parts reached outside the "
              f"{protocol} grid; their voxels outside were dropped)")
    for m, st in s["metrics"].items():
        if st["mean_all_pairs"] is not None:
            all_pairs = f"mean over all {s['pairs']} pairs (failed = 0) {st['mean_all_pairs']:.6f}  "
        else:
            all_pairs = f"no mean over all {s['pairs']} pairs (a failed pair has no {m})  "
        if st["count"]:
            print(f"{m}: {all_pairs}mean over the {st['count']} succeeded {st['mean_succeeded']:.6f}  "
                  f"median {st['median']:.6f}")
        elif st["mean_all_pairs"] is not None:
            print(f"{m}: {all_pairs.rstrip()}")
    for f in s["failures"]:
        print(f"FAILED {f['id']}: {f['error']}", file=sys.stderr)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 a batch had failed pairs, 2 bad input, 3 internal error).

    Every error is one line on stderr. Set ``CERBERUS_METRICS_DEBUG=1`` to get the traceback of
    an internal error instead.
    """
    cwd = os.getcwd()
    for stream in (sys.stdout, sys.stderr):  # a path the stream's encoding cannot say is printed escaped (LANG=C)
        if hasattr(stream, "reconfigure"):
            with contextlib.suppress(ValueError, OSError):
                stream.reconfigure(errors="backslashreplace")
    try:
        args = build_parser().parse_args(argv)
        if args.command == "protocols":
            for p in PROTOCOLS.values():
                print(f"{p.name}: {p.summary}")
            return 0
        if args.command == "check":
            return _run_check(args)
        if args.command == "batch":
            return _run_batch(args)
        return _run_pair(args)
    except UsageError as exc:
        print(f"error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: nothing was written (outputs are written whole, at the end)
        print("interrupted", file=sys.stderr)
        return 130
    except MeshInputError as exc:
        print(f"error: {_in_cli_terms(_one_line(exc))}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = f" '{exc.filename}'" if exc.filename else ""
        print(f"error: cannot access{where} ({_one_line(exc.strerror or exc)}); check the path and its permissions",
              file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - one line instead of a traceback; see CERBERUS_METRICS_DEBUG
        if os.environ.get("CERBERUS_METRICS_DEBUG"):
            raise
        print(f"error: internal error {type(exc).__name__}: {_one_line(exc)}; please report it (rerun with "
              "CERBERUS_METRICS_DEBUG=1 for the traceback)", file=sys.stderr)
        return 3
    finally:
        if os.getcwd() != cwd:
            os.chdir(cwd)


if __name__ == "__main__":
    sys.exit(main())
