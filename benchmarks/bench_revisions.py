"""Training-step speed of two git revisions, side by side: is a change faster on this machine?

Each revision is a source tree: a git revision is checked out into a temporary git worktree, a
folder is taken as it is (a worktree you made, or ``.`` for the working copy with its uncommitted
changes). Each tree's four packages are imported from there (``PYTHONPATH`` ahead of the installed
editable packages; every worker reports the ``cerberus_core`` it imported, printed below) by a worker
process of ``bench_train.py`` that builds the trainer as ``cerberus train`` does (the preset's own
``speed:`` section) on one batch of the same dataset and runs the trainer's own step. The two workers
alternate step by step (A then B, then B then A, ...), so a change of load hits both alike; the
median step (wall clock and the worker's CPU time) of each, the ratios and the first step's loss of
each (the same model and batch: equal up to rounding when the change keeps the maths) are printed.

    python benchmarks/bench_revisions.py 4776951 . --preset cpu --threads 1 --steps 30
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
import bench_train as bt  # noqa: E402 (after its folder is on the path)

PACKAGES = ("cerberus-core", "cerberus-render-torch", "cerberus-render-warp", "cerberus-metrics")


def source_tree(rev: str, where: Path) -> tuple[Path, bool]:
    """``rev`` as a folder: itself if it is one, else a new detached worktree under ``where``
    (returns the folder and whether it was made here)."""
    if Path(rev).is_dir():
        return Path(rev).resolve(), False
    path = where / rev.replace("/", "_")
    subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "--force", str(path), rev], check=True,
                   capture_output=True, text=True)
    return path, True


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("revisions", nargs=2, metavar="REV",
                   help="two git revisions or source folders (A = before, B = after)")
    p.add_argument("--preset", default="cpu", help="training preset (default: cpu)")
    p.add_argument("--renderer", default="warp", help="renderer backend (default: warp)")
    p.add_argument("--data", type=Path, default=None, help="a quadruplet dataset (default: generate primitives)")
    p.add_argument("--threads", type=int, default=1, help="torch threads per worker (default 1)")
    p.add_argument("--steps", type=int, default=30, help="timed steps per revision, alternating (default 30)")
    p.add_argument("--warmup", type=int, default=3, help="untimed steps first (default 3)")
    p.add_argument("--batch-size", type=int, default=None, help="override the preset's batch size")
    args = p.parse_args()
    args.device = "cpu"
    made: list[Path] = []
    with tempfile.TemporaryDirectory() as tmp:
        try:
            specs = []
            root = bt.dataset_for(args, args.preset, Path(tmp))
            for rev in args.revisions:
                tree, new = source_tree(rev, Path(tmp))
                if new:
                    made.append(tree)
                env = {**os.environ, "PYTHONPATH": os.pathsep.join(str(tree / "packages" / pkg / "src")
                                                                   for pkg in PACKAGES)}
                specs.append((rev, bt.base_spec(args, args.preset, args.renderer, root), env))
            workers = bt.start(specs)
            try:
                bt.interleave(workers, args.steps, args.warmup)
            finally:
                for w in workers:
                    w.close()
        finally:
            for tree in made:
                subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(tree)], capture_output=True)
    print()
    print("\n".join(bt.machine_lines()))
    print(bt.load_line(args, f"{args.preset} preset, {args.renderer} renderer, the revisions alternating step by step"))
    for w in workers:
        print(f"{w.label:>24}  {w.wall_s:.4f} s/step  CPU {w.cpu_s:.4f} s  {1 / w.wall_s:6.2f} steps/s  "
              f"first-step loss {w.info['first_loss']:.7f}  ({w.info['optimizer']}; {w.info['note']})")
        print(f"{'':>24}  imported {w.info['core']}")
    a, b = workers
    print(f"{b.label} / {a.label}: {a.wall_s / b.wall_s:.3f}x faster (wall clock), {a.cpu_s / b.cpu_s:.3f}x (CPU time); "
          f"first-step losses differ by {abs(a.info['first_loss'] - b.info['first_loss']):.2e}")


if __name__ == "__main__":
    main()
