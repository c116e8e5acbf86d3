"""experiments/table1/voxel_errors.py: where the wrong voxels lie."""
from __future__ import annotations

import numpy as np

from tests.support.paths import load_script


def test_off_body_counts_measure_distances_both_ways_and_count_the_parts_over_each_voxel():
    module = load_script("experiments/table1/voxel_errors.py")
    body = np.zeros((9, 9, 9), bool)
    body[2:7, 2:7, 2:7] = True
    parts = np.zeros((3, 9, 9, 9), bool)
    parts[0] = body
    parts[0, 2, 2, 2] = False  # a corner missed: one voxel from the outside
    parts[0, 4, 4, 4] = False  # the centre missed by part 0 but covered by part 1
    parts[1, 4, 4, 4] = True
    parts[1, 1, 4, 4] = parts[2, 1, 4, 4] = True  # a shell voxel under two parts
    parts[2, 4, 4, 0] = True  # a stray voxel 2 away from the body
    f = module.off_body_counts(parts, body)
    assert f["counts"].tolist() == [124, 2, 1, 125]
    assert sorted(f["off"].tolist()) == [1.0, 2.0]
    assert sorted(f["cover"].tolist()) == [1, 2]
    assert f["missed"].tolist() == [1.0]
