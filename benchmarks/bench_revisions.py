"""Training-step speed of two git revisions, side by side: is a change faster on this machine?

Each revision is checked out into a temporary git worktree; its four packages are imported from
there (``PYTHONPATH``) by a child process that builds the preset's model (seed 0) on one batch of the
same dataset, runs warm-up steps, then times full optimisation steps (objective, backward, Adam;
:func:`bench_train.stepper`). The children alternate, revision A then B, for ``--rounds`` rounds, so
a change of load hits both alike; the median step of every revision and the ratio are printed, with
the first step's loss of each (the same model and batch: equal up to rounding when the change keeps
the maths).

    python benchmarks/bench_revisions.py 55b989e HEAD --preset cpu --data data/human --threads 1
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("cerberus-core", "cerberus-render-torch", "cerberus-render-warp", "cerberus-metrics")

CHILD = """
import json, sys, time
import torch
sys.path.insert(0, {bench!r})
import bench_train as bt
from pathlib import Path
torch.set_num_threads({threads})
cfg, scene, batch, _, renderer = bt.setup({preset!r}, {renderer!r}, Path({data!r}), None)
model, step = bt.stepper(cfg, scene, batch, renderer, cfg.speed)
first = step(0)
for i in range(1, {warmup}):
    step(i)
times = []
for i in range({steps}):
    t0 = time.perf_counter()
    step({warmup} + i)
    times.append(time.perf_counter() - t0)
print(json.dumps({{"times": times, "first_loss": first}}))
"""


def worktree(rev: str, where: Path) -> Path:
    path = where / rev.replace("/", "_")
    subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "--force", str(path), rev], check=True,
                   capture_output=True, text=True)
    return path


def time_revision(tree: Path, args: argparse.Namespace) -> dict:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(str(tree / "packages" / p / "src") for p in PACKAGES),
           "OMP_NUM_THREADS": str(args.threads)}
    code = CHILD.format(bench=str(REPO / "benchmarks"), threads=args.threads, preset=args.preset,
                        renderer=args.renderer, data=str(args.data.resolve()), warmup=args.warmup, steps=args.steps)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=1800)
    if res.returncode != 0:
        sys.exit(f"bench_revisions: the child for {tree.name} failed:\n{res.stderr[-2000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("revisions", nargs=2, metavar="REV", help="two git revisions (A = before, B = after)")
    p.add_argument("--preset", default="cpu", help="training preset (default: cpu)")
    p.add_argument("--renderer", default="warp", help="renderer backend (default: warp)")
    p.add_argument("--data", type=Path, required=True, help="a quadruplet dataset (e.g. data/human)")
    p.add_argument("--threads", type=int, default=1, help="torch threads per child (default 1)")
    p.add_argument("--rounds", type=int, default=3, help="alternations A, B (default 3)")
    p.add_argument("--steps", type=int, default=10, help="timed steps per child (default 10)")
    p.add_argument("--warmup", type=int, default=3, help="untimed steps first (default 3)")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trees = [worktree(rev, Path(tmp)) for rev in args.revisions]
        try:
            times: dict[str, list[float]] = {rev: [] for rev in args.revisions}
            first: dict[str, float] = {}
            for r in range(args.rounds):
                for rev, tree in zip(args.revisions, trees, strict=True):
                    out = time_revision(tree, args)
                    times[rev] += out["times"]
                    first[rev] = out["first_loss"]
                    print(f"  round {r + 1}: {rev} median {statistics.median(out['times']):.3f} s/step", flush=True)
        finally:
            for tree in trees:
                subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(tree)], capture_output=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\n{args.preset} preset, {args.renderer} renderer, {args.threads} thread(s), load average {load:.1f} on "
          f"{os.cpu_count()} CPUs; median of {args.rounds} x {args.steps} steps per revision, alternating")
    a, b = args.revisions
    for rev in args.revisions:
        med = statistics.median(times[rev])
        print(f"{rev:>12}  {med:.3f} s/step  {1 / med:6.2f} steps/s  first-step loss {first[rev]:.7f}")
    print(f"{b} / {a}: {statistics.median(times[a]) / statistics.median(times[b]):.2f}x faster")


if __name__ == "__main__":
    main()
