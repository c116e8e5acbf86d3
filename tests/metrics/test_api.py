"""The metric functions as entry points (cerberus_metrics.api through ``cerberus.metrics``)."""
from __future__ import annotations

from importlib.metadata import entry_points

import numpy as np
import trimesh


def test_entry_points_discover_metrics(helpers):
    eps = {ep.name: ep for ep in entry_points(group="cerberus.metrics")}
    assert {"voxel_iou", "chamfer_l2", "fscore"} <= set(eps)
    voxel = eps["voxel_iou"].load()
    a = helpers.box((-0.3, -0.3, -0.3), (0.1, 0.1, 0.1))
    parts = [(np.asarray(a.vertices), np.asarray(a.faces)), trimesh.creation.icosphere(radius=0.1)]
    iou = voxel(parts, a, protocol="kato", resolution=32)
    assert isinstance(iou, float) and 0 < iou <= 1
    assert isinstance(eps["fscore"].load()(a, a, n_samples=1000), float)
