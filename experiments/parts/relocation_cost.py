"""The cost of ``losses.relocation`` (docs/training.md, "Beyond the paper: parts that move"): CPU seconds of
``relocation_pull`` (forward + backward) on a ``cpu``-preset-sized batch (8 quadruplets, 64 px, 9 parts, three of
them spare), beside ``silhouette_coverage`` of the keypoints (what ``losses.consensus_coverage`` computes) on the
same inputs, one thread.

    python experiments/parts/relocation_cost.py
"""
import time

import torch

from cerberus_core.losses import relocation_pull, silhouette_coverage

BATCH, PARTS, SIZE = 8, 9, 64


def cpu_seconds(run, reps: int = 50) -> float:
    run()
    start = time.process_time()
    for _ in range(reps):
        run()
    return (time.process_time() - start) / reps


def main() -> None:
    torch.set_num_threads(1)
    torch.manual_seed(0)
    fg = torch.zeros(BATCH, 4, SIZE, SIZE)
    fg[..., 8:56, 24:40] = 1  # a trunk
    fg[..., 20:24, 8:56] = 1  # and two arms
    part_id = torch.full((BATCH, 4, SIZE, SIZE), -1)
    part_id[..., 8:56, 24:40] = torch.randint(0, 6, (BATCH, 4, 48, 16))  # six parts share the trunk; three spare
    keypoints = torch.rand(BATCH, 4, PARTS, 2) * 16 + 24

    def relocation() -> None:
        points = keypoints.clone().requires_grad_(True)
        relocation_pull(points, part_id, fg, keypoints).sum().backward()

    def coverage() -> None:
        points = keypoints.flatten(0, 1).clone().requires_grad_(True)
        silhouette_coverage(points, fg.flatten(0, 1)).sum().backward()

    print(f"relocation_pull fwd+bwd: {cpu_seconds(relocation) * 1e3:.1f} ms CPU; "
          f"silhouette_coverage of the keypoints: {cpu_seconds(coverage) * 1e3:.1f} ms CPU")


if __name__ == "__main__":
    main()
