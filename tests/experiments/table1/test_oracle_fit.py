"""experiments/table1/oracle_fit.py: the direct 3D fit of deformed icospheres behind Table 1's oracle row."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

from cerberus_core.eval.standard import VoxelScorer
from cerberus_core.render.templates import icosphere
from tests.support.paths import load_script


@pytest.fixture(scope="module")
def oracle():
    pytest.importorskip("cerberus_metrics")
    return load_script("experiments/table1/oracle_fit.py")


def test_one_part_fits_an_ellipsoid_and_two_parts_two_blobs(oracle):
    """An ellipsoid is what one part can be: the fit scores > 0.9 with the evaluation's IoU; two apart
    blobs get one closed, outward-facing part each."""
    torch.set_num_threads(1)
    scorer = VoxelScorer("kato", 32)
    template = icosphere(2)
    blob = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    ellipsoid = (np.asarray(blob.vertices) * [0.3, 0.15, 0.1], np.asarray(blob.faces))
    verts, log = oracle.fit_body(*ellipsoid, template, 1, 120, samples=600, part_samples=600)
    assert verts.shape == (1, 162, 3)
    assert log["chamfer_end"] < log["chamfer_start"]
    fitted = [(verts[0].numpy().astype(np.float64), template.faces.numpy())]
    assert scorer(fitted, ellipsoid).iou > 0.9

    two = trimesh.util.concatenate([blob.copy().apply_scale(0.12).apply_translation([-0.25, 0, 0]),
                                     blob.copy().apply_scale(0.12).apply_translation([0.25, 0, 0])])
    gt = (np.asarray(two.vertices), np.asarray(two.faces))
    verts, _ = oracle.fit_body(*gt, template, 2, 120, samples=600, part_samples=600)
    checks = oracle.part_checks(verts, template.faces, template.dihedral)
    assert bool((checks["volume"] > 0).all()) and int(checks["folded"].sum()) == 0
    assert sorted(torch.sign(verts.mean(1)[:, 0]).tolist()) == [-1.0, 1.0]  # one part per blob
    parts = [(v.numpy().astype(np.float64), template.faces.numpy()) for v in verts]
    assert scorer(parts, gt).iou > 0.85
