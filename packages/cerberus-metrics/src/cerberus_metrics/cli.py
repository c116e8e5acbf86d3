"""Command line: ``cerberus-metrics {iou,chamfer,fscore,check,batch,protocols}``.

Exit codes: 0 success; 1 a batch finished but some pairs failed (see the summary);
2 bad input (the message names the file or argument, the problem and the fix).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections.abc import Sequence
from typing import Any

from . import __version__
from .api import METRICS, evaluate_pair, inspect_mesh
from .batch import pairs_from_file, pairs_from_folders, run_batch, write_results
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
"""


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


def _add_voxel_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--protocol", choices=list(PROTOCOLS), default="kato", help="voxel protocol (default: kato)")
    p.add_argument("--resolution", type=int, default=32, help="voxels per grid side (default: 32, the paper's)")


def _add_sampling_options(p: argparse.ArgumentParser, threshold: bool) -> None:
    p.add_argument("--samples", type=int, default=100_000, help="points sampled per surface (default: 100000)")
    p.add_argument("--seed", type=int, default=0, help="sampling seed; the GT uses seed+1 (default: 0)")
    p.add_argument(
        "--normalize", action="store_true", help="scale both shapes by the GT bounding box (longest side 1) first"
    )
    if threshold:
        p.add_argument("--threshold", type=float, default=0.01, help="F-score distance threshold (default: 0.01)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cerberus-metrics", description=_DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    pair_help = "PRED [PRED ...] GT: one or more prediction files (parts, united) then the ground-truth file"
    for name, helptext in (
        ("iou", "voxel IoU of one pair"),
        ("chamfer", "Chamfer-L2 of one pair (mean squared nearest distance, both ways, summed)"),
        ("fscore", "F-score at a distance threshold of one pair"),
    ):
        p = sub.add_parser(name, help=helptext, description=helptext + ". " + pair_help)
        p.add_argument("meshes", nargs="+", metavar="MESH", help=pair_help)
        if name == "iou":
            _add_voxel_options(p)
        else:
            _add_sampling_options(p, threshold=name == "fscore")
        _add_mesh_options(p)
        p.add_argument("--json", action="store_true", help="print the result as JSON")

    p = sub.add_parser("check", help="clean meshes with pymeshlab and report watertightness / manifoldness")
    p.add_argument("meshes", nargs="+", metavar="MESH")
    p.add_argument("--json", action="store_true", help="print the reports as JSON")

    p = sub.add_parser(
        "batch",
        help="evaluate many pairs on all cores",
        description="Evaluate many pairs (from --pairs CSV/JSON, or --pred-dir/--gt-dir matched by file stem) "
        "in parallel. Failing pairs are reported and counted; exit code 1 if any pair failed.",
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--pairs", help="CSV (columns id,pred,gt; parts separated by ';') or JSON list of pairs")
    src.add_argument("--pred-dir", help="folder of predictions (a file, or a sub-folder of parts, per GT stem)")
    p.add_argument("--gt-dir", help="folder of ground truths (with --pred-dir)")
    p.add_argument(
        "--metrics", default="voxel_iou", help=f"comma-separated, from {','.join(METRICS)} (default: voxel_iou)"
    )
    _add_voxel_options(p)
    _add_sampling_options(p, threshold=True)
    _add_mesh_options(p)
    p.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    p.add_argument("--cache-dir", default=None, help="folder for cached ground-truth grids (content-hashed)")
    p.add_argument("--no-cache", action="store_true", help="voxelize every ground truth anew (no grid cache)")
    p.add_argument("--out", default=None, help="write summary and per-pair results as JSON here")
    p.add_argument("--csv", default=None, help="write per-pair results as CSV here")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.add_argument("--json", action="store_true", help="print summary and pairs as JSON on stdout")

    sub.add_parser("protocols", help="list the voxel protocols")
    return parser


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
        kwargs.update(protocol=args.protocol, resolution=args.resolution)
    else:
        kwargs.update(n_samples=args.samples, seed=args.seed, normalize=args.normalize)
        if metric == "fscore":
            kwargs["threshold"] = args.threshold
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeshQualityWarning)
        result = evaluate_pair(pred, gt, [metric], **kwargs)
    notes = sorted({str(w.message) for w in caught})
    for n in notes:
        print(f"warning: {n}", file=sys.stderr)
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
    if args.pairs:
        pairs = pairs_from_file(args.pairs)
    else:
        if not args.gt_dir:
            raise MeshInputError("--pred-dir needs --gt-dir (the folder of ground truths)")
        pairs = pairs_from_folders(args.pred_dir, args.gt_dir)
    if not pairs:
        raise MeshInputError("no pairs found; check the pairs file or the folders (mesh files by suffix)")
    metrics = [m.strip() for m in args.metrics.split(",") if m.strip()]
    result = run_batch(
        pairs,
        metrics,
        jobs=args.jobs,
        cache_dir=args.cache_dir,
        use_cache=not args.no_cache,
        progress=not args.no_progress,
        protocol=args.protocol,
        resolution=args.resolution,
        n_samples=args.samples,
        seed=args.seed,
        threshold=args.threshold,
        normalize=args.normalize,
        **_mesh_kwargs(args),
    )
    write_results(result, args.out, args.csv)
    s = result.summary
    if args.json:
        print(json.dumps({"summary": s, "pairs": result.rows}, indent=2))
    else:
        print(f"pairs: {s['pairs']}  succeeded: {s['succeeded']}  failed: {s['failed']}  "
              f"with warnings: {s['pairs_with_warnings']}")
        for m, st in s["metrics"].items():
            if st["count"]:
                print(f"{m}: mean {st['mean']:.6f}  median {st['median']:.6f}  count {st['count']}")
        for f in s["failures"]:
            print(f"FAILED {f['id']}: {f['error']}", file=sys.stderr)
    return 1 if s["failed"] else 0


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.command == "protocols":
            for p in PROTOCOLS.values():
                print(f"{p.name}: {p.summary}")
            return 0
        if args.command == "check":
            return _run_check(args)
        if args.command == "batch":
            return _run_batch(args)
        return _run_pair(args)
    except MeshInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
