"""GLB / OBJ export round trips."""
from __future__ import annotations

import os

import numpy as np
import pytest
import torch
import trimesh

from cerberus_core.eval.export import export_parts, export_reconstruction
from cerberus_core.parts import PartSet
from cerberus_core.viz import part_colors
from tests.support.oracle import body_parts


def test_glb_round_trip_has_named_coloured_parts(tmp_path, primitive_bodies):
    recon = body_parts(primitive_bodies[2])
    paths = export_reconstruction(recon, tmp_path, ["fig"])
    assert tmp_path / "fig.glb" in paths
    scene = trimesh.load(tmp_path / "fig.glb", file_type="glb", process=False)
    names = [f"part_{k:02d}" for k in range(recon.num_parts)]
    assert sorted(scene.graph.nodes_geometry) == names
    posed = recon.posed()[0].numpy()
    colours = np.round(part_colors(recon.num_parts).numpy() * 255)
    for k, name in enumerate(names):
        mesh = scene.geometry[name]
        assert len(mesh.vertices) == recon.num_vertices and len(mesh.faces) == recon.faces.shape[0]
        world = trimesh.transform_points(mesh.vertices, scene.graph.get(name)[0])
        np.testing.assert_allclose(world, posed[k], atol=1e-5)
        np.testing.assert_array_equal(mesh.visual.material.baseColorFactor[:3], colours[k])
    assert len({tuple(c) for c in colours}) == recon.num_parts  # distinct colours


def test_obj_files_per_part_and_combined(tmp_path, primitive_bodies):
    recon = body_parts(primitive_bodies[0])
    export_reconstruction(recon, tmp_path, ["a"], formats=["obj"])
    assert not (tmp_path / "a.glb").exists()
    combined = trimesh.load(tmp_path / "a.obj", process=False, force="mesh")
    assert len(combined.vertices) == recon.num_parts * recon.num_vertices
    text = (tmp_path / "a.obj").read_text()
    for k in range(recon.num_parts):  # every part is its own object and group in the combined file
        assert f"\no part_{k:02d}\ng part_{k:02d}\n" in text
    assert text.count("\nf ") == recon.num_parts * recon.faces.shape[0]
    for k in range(recon.num_parts):
        part = trimesh.load(tmp_path / "a_parts" / f"part_{k:02d}.obj", process=False)
        np.testing.assert_allclose(part.vertices, recon.posed()[0, k].numpy(), atol=1e-6)
        assert part.visual.kind == "vertex"
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def test_export_refuses_broken_input_without_writing(tmp_path):
    verts = np.zeros((2, 3, 3))
    verts[1, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        export_parts(verts, np.array([[0, 1, 2]]), tmp_path, "x")
    with pytest.raises(ValueError, match="unknown format"):
        export_parts(np.zeros((1, 3, 3)), np.array([[0, 1, 2]]), tmp_path, "x", formats=["fbx"])
    with pytest.raises(ValueError, match="names"):
        export_reconstruction(PartSet.from_posed(torch.zeros(2, 3, 3), torch.tensor([[0, 1, 2]])),
                              tmp_path, ["only_one"])
    assert list(tmp_path.iterdir()) == []
