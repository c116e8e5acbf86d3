"""Icosphere templates and their connectivity (cerberus_core.render.templates)."""
from __future__ import annotations

import pytest
import torch
import trimesh

from cerberus_core.render.templates import MeshTemplate, icosphere, vertex_normals


def test_level_two_is_the_paper_template() -> None:
    t = icosphere(2)
    assert (t.num_vertices, t.num_faces) == (162, 320)
    assert t.vertices.dtype == torch.float32 and t.faces.dtype == torch.int64
    assert t.edges.shape == (480, 2) and (t.edges[:, 0] < t.edges[:, 1]).all()
    assert len({tuple(e) for e in t.edges.tolist()}) == 480
    assert t.dihedral.shape == (480, 4)  # one quadruple per edge of the closed mesh
    assert t.num_vertices - len(t.edges) + t.num_faces == 2  # Euler characteristic of a sphere
    torch.testing.assert_close(t.vertices.norm(dim=-1), torch.ones(162))


@pytest.mark.parametrize("level", [0, 1, 2, 3])
def test_level_sizes(level: int) -> None:
    t = icosphere(level)
    assert (t.num_vertices, t.num_faces) == (10 * 4**level + 2, 20 * 4**level)


def test_dihedral_quadruples_are_an_edge_and_its_two_opposite_vertices() -> None:
    t = icosphere(2)
    faces = {frozenset(f) for f in t.faces.tolist()}
    edges = {tuple(e) for e in t.edges.tolist()}
    seen = set()
    for a, b, c, d in t.dihedral.tolist():
        assert frozenset((a, b, c)) in faces and frozenset((a, b, d)) in faces and c != d
        seen.add((min(a, b), max(a, b)))
    assert seen == edges


def test_faces_wind_counter_clockwise_from_outside() -> None:
    t = icosphere(2)
    v = t.vertices[t.faces]
    n = torch.linalg.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    assert ((n * v.mean(1)).sum(-1) > 0).all()


def test_neighbours_are_the_edges() -> None:
    t = icosphere(2)
    valence = (t.neighbours >= 0).sum(-1)
    assert set(valence.tolist()) == {5, 6} and (valence == 5).sum() == 12
    pairs = {(i, int(j)) for i, row in enumerate(t.neighbours) for j in row if j >= 0}
    assert pairs == {(a, b) for a, b in t.edges.tolist()} | {(b, a) for a, b in t.edges.tolist()}


def test_radius_and_invalid_levels() -> None:
    torch.testing.assert_close(icosphere(1, radius=0.3).vertices.norm(dim=-1), torch.full((42,), 0.3))
    for bad in (-1, 7, 2.0):
        with pytest.raises(ValueError, match="icosphere level"):
            icosphere(bad)


def test_vertex_normals_point_outward() -> None:
    t = icosphere(2)
    scale = torch.tensor([[0.2, 0.5, 0.1], [1.0, 1.0, 1.0]]).unsqueeze(1)
    verts = t.vertices.unsqueeze(0) * scale + torch.tensor([0.3, -0.2, 0.1])
    n = vertex_normals(verts, t.faces)
    assert n.shape == (2, 162, 3)
    torch.testing.assert_close(n.norm(dim=-1), torch.ones(2, 162))
    assert ((n * t.vertices).sum(-1) > 0).all()  # outward on the ellipsoid too
    assert (n[1] * t.vertices).sum(-1).min() > 0.999  # unit sphere: normal ~ position
    # The normal of an ellipsoid x^2/a^2 + ... is parallel to (x/a^2, y/b^2, z/c^2).
    grad = t.vertices / scale[0]
    cos = (n[0] * torch.nn.functional.normalize(grad, dim=-1)).sum(-1)
    assert cos.min() > 0.97


def test_vertex_normals_are_differentiable() -> None:
    t = icosphere(0)
    v = (t.vertices.double() * torch.tensor([1.0, 0.7, 1.3], dtype=torch.float64)).unsqueeze(0).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda x: vertex_normals(x, t.faces), (v,))


def test_template_from_any_closed_mesh() -> None:
    box = MeshTemplate.from_trimesh(trimesh.creation.box())
    assert (box.num_vertices, box.num_faces, len(box.edges), len(box.dihedral)) == (8, 12, 18, 18)
    with pytest.raises(ValueError, match="at least one face"):
        MeshTemplate.from_trimesh(trimesh.Trimesh(vertices=[[0, 0, 0]], faces=[]))
